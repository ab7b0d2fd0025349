// A heap array aligned for SIMD, uninitialised on allocation (lattices are large and every
// backend initialises them itself, in parallel).
#pragma once

#include <cstddef>
#include <cstdlib>
#include <new>
#include <utility>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace lblight {

template <typename T>
class AlignedBuffer {
 public:
  static constexpr std::size_t kAlignment = 64;
  static constexpr std::size_t kHugePage = std::size_t(2) << 20;
  static constexpr std::size_t kHugeFrom = std::size_t(8) << 20;

  AlignedBuffer() = default;
  explicit AlignedBuffer(std::size_t count) { allocate(count); }
  AlignedBuffer(const AlignedBuffer&) = delete;
  AlignedBuffer& operator=(const AlignedBuffer&) = delete;
  AlignedBuffer(AlignedBuffer&& o) noexcept : data_(std::exchange(o.data_, nullptr)), size_(std::exchange(o.size_, 0)) {}
  AlignedBuffer& operator=(AlignedBuffer&& o) noexcept {
    if (this != &o) {
      release();
      data_ = std::exchange(o.data_, nullptr);
      size_ = std::exchange(o.size_, 0);
    }
    return *this;
  }
  ~AlignedBuffer() { release(); }

  void allocate(std::size_t count) {
    release();
    if (count == 0) return;
    const std::size_t raw = count * sizeof(T);
    // Large arrays start on a huge page and ask for huge pages: a lattice row reads 19 and
    // writes 19 direction arrays megabytes apart, and with 4 KiB pages (transparent huge pages
    // in "madvise" mode, as many kernels and VMs run them) the address translations, not the
    // bytes, bound the sweep (docs/performance.md).
    const std::size_t align = raw >= kHugeFrom ? kHugePage : kAlignment;
    const std::size_t bytes = ((raw + align - 1) / align) * align;
    data_ = static_cast<T*>(std::aligned_alloc(align, bytes));
    if (!data_) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (align == kHugePage) madvise(data_, bytes, MADV_HUGEPAGE);  // advice only: failure is harmless
#endif
    size_ = count;
  }
  void release() {
    std::free(data_);
    data_ = nullptr;
    size_ = 0;
  }

  T* data() { return data_; }
  const T* data() const { return data_; }
  std::size_t size() const { return size_; }
  T& operator[](std::size_t i) { return data_[i]; }
  const T& operator[](std::size_t i) const { return data_[i]; }

 private:
  T* data_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace lblight
