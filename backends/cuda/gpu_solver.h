// The CUDA backend's solver, written once over a Device that supplies memory and launches:
// cuda_backend.cu binds it to a GPU (gpu_runtime.h calls and the kernels around lb_device.h),
// tests/backend/emulated_gpu.cpp to plain memory and loops that run the same per-thread code on
// the CPU. So the host side of the GPU backend (batching, the order of launches, inflow, state
// layout, Krylov vectors) runs in the tests on every machine. Plain C++ (no GPU types): compiles
// with nvcc, hipcc and g++.
//
// A Device provides:
//   template <typename U> using Buffer;   // allocate(count), get(), size(), bytes(); frees itself
//   void use() const;                     // make it the calling thread's device
//   void upload / download / copy(void* dst, const void* src, std::size_t bytes) const;
//   void zero(void* dst, std::size_t bytes) const;
//   void bind(const void* owner, long long generation, const BatchTables&);  // per-batch tables
//   void unbind(const void* owner);
//   template <typename T> void step(const BatchArgs<T>&) const;  // step_node<a.access>, every thread
//   template <typename T> void inflow(const BatchArgs<T>&, T* level, bool zero) const;
//   void init_totals(float* totals, const Dims&, int systems) const;
//   template <typename T> void measure(const BatchArgs<T>&, double* partial, double* reduced,
//                                      double* host) const;  // kReduceSlots per system into host
//   template <typename T> void axpby(float a, const T* x, float b, T* y, long long n) const;
//   template <typename T> double dot(const T* x, const T* y, long long n, double* scratch) const;
#pragma once

#include <cstddef>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "backends/cuda/lb_device.h"
#include "lblight/backend/backend.h"
#include "lblight/backend/node_rules.h"
#include "lblight/core/error.h"
#include "lblight/lattice/collision_op.h"

namespace lblight::gpu {

inline constexpr int kReduceBlock = 256;  // threads per block of the measure and dot reductions
inline constexpr int kVectorBlocks = 1024;  // grid of the vector kernels (grid-stride loops)

// Blocks of measure's first pass over the interior.
inline int reduce_blocks(const Dims& d) {
  return static_cast<int>((static_cast<long long>(d.interior_count()) + kReduceBlock - 1) / kReduceBlock);
}

// Device memory one system needs: its levels of state (two, or one in place), its totals and its
// share of the reductions.
inline std::size_t gpu_bytes_per_system(const Dims& d, Precision p, StateLayout layout = StateLayout::TwoLevels) {
  const std::size_t v = p == Precision::Float16 ? 2 : 4;
  const std::size_t levels = layout == StateLayout::InPlace ? 1 : 2;
  return levels * 19 * static_cast<std::size_t>(gpu_stride(d)) * v + d.count() * sizeof(float) +
         (static_cast<std::size_t>(reduce_blocks(d)) + 1) * kReduceSlots * sizeof(double);
}

template <typename T, typename Device>
class GpuSolver final : public LatticeSolver, public KrylovVectors, public StateAccess {
 public:
  GpuSolver(Device device, const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels, int capacity,
            StateLayout layout, const char* backend)
      : dev_(std::move(device)), d_(g.dims), capacity_(capacity), in_place_(layout == StateLayout::InPlace) {
    check_geometry(g, backend);  // the step kernel picks its operator by the material byte
    if (d_.ny - 2 > 65535 || d_.nz - 2 > 65535) throw_invalid("lattice too large for the GPU launch grid");
    if (static_cast<int>(channels.size()) > kMaxChannels || g.material_count > kMaxMaterials)
      throw std::logic_error(std::string(backend) + " backend: too many channels or materials");
    if (capacity_ < 1 || capacity_ > kMaxBatch)
      throw std::logic_error(std::string(backend) + " backend: batch capacity out of range");
    for (std::size_t c = 0; c < channels.size(); ++c) {
      for (int k = 0; k < g.material_count; ++k)
        tables_.ops[c][k] = convert_op<float>(channel_op(channels[c], k));
      unsigned bits = 0;
      for (int k = 0; k < kMaxMaterials; ++k)
        if (channels[c].absorbs[k]) bits |= 1u << k;
      tables_.absorb[c] = bits;
    }
    channel_count_ = static_cast<int>(channels.size());
    count_ = d_.count();
    stride_ = gpu_stride(d_);
    dev_.use();
    density_.allocate(count_);
    material_.allocate(count_);
    dev_.upload(density_.get(), g.density.data(), count_ * sizeof(float));
    dev_.upload(material_.get(), g.material.data(), count_);
    state_.allocate(static_cast<std::size_t>(capacity_) * levels() * 19 * static_cast<std::size_t>(stride_));
    totals_.allocate(static_cast<std::size_t>(capacity_) * count_);
    partial_.allocate(static_cast<std::size_t>(reduce_blocks(d_)) * capacity_ * kReduceSlots);
    reduced_.allocate(static_cast<std::size_t>(capacity_) * kReduceSlots);
  }

  ~GpuSolver() override { dev_.unbind(this); }

  int capacity() const override { return capacity_; }

  void reset(const std::vector<SystemSpec>& batch) override {
    if (static_cast<int>(batch.size()) > capacity_) throw std::logic_error("batch larger than solver capacity");
    for (const SystemSpec& s : batch)  // before taking the batch: its channels index constant tables
      if (s.channel < 0 || s.channel >= channel_count_) throw std::logic_error("system channel out of range");
    batch_ = batch;
    for (std::size_t s = 0; s < batch_.size(); ++s) {
      tables_.channels[s] = batch_[s].channel;
      for (int m = 0; m < 19; ++m) tables_.boundaries[s][m] = static_cast<float>(batch_[s].boundary[m]);
      tables_.boundary_totals[s] = static_cast<float>(boundary_total(batch_[s].boundary));
    }
    ++batch_generation_;  // new tables for bind()
    bind();
    level_ = 0;
    swapped_ = false;
    dev_.zero(state_.get(), state_.bytes());
    dev_.init_totals(totals_.get(), d_, static_cast<int>(batch_.size()));
    // What the boundary pushes arrives with the first step: into the other level, or in place into
    // the swapped layout's slots now and the natural layout's (which the first step reads as 0) after it.
    if (in_place_) inflow(with_access(args(), Access::SwapIn), level_ptr(0, 0), false);
    else inflow(args(), level_ptr(0, 1), false);
    inflow_pending_ = true;
  }

  void step(int steps) override {
    bind();
    for (int t = 0; t < steps; ++t) {
      dev_.step(args());
      if (in_place_) swapped_ = !swapped_;
      else level_ = 1 - level_;
      if (inflow_pending_) {
        if (in_place_) inflow(with_access(args(), Access::Push), level_ptr(0, 0), false);
        else inflow(args(), level_ptr(0, 1 - level_), false);
        inflow_pending_ = false;
      }
    }
  }

  void measure(std::vector<Residual>& out) override {
    out.clear();
    if (batch_.empty()) return;  // a grid of 0 blocks is a launch error
    bind();
    std::vector<double> host(batch_.size() * kReduceSlots);
    dev_.measure(args(), partial_.get(), reduced_.get(), host.data());
    for (std::size_t s = 0; s < batch_.size(); ++s) out.push_back(to_residual(host.data() + s * kReduceSlots));
  }

  void read_totals(int system, float* out) const override {
    dev_.use();
    check_system(system);
    dev_.download(out, totals_.get() + static_cast<std::size_t>(system) * count_, count_ * sizeof(float));
  }

  std::size_t bytes_in_use() const override {
    std::size_t bytes = density_.bytes() + material_.bytes() + state_.bytes() + totals_.bytes() + partial_.bytes() +
                        reduced_.bytes() + dot_partial_.bytes();
    for (const auto& v : vectors_) bytes += v->bytes();
    return bytes;
  }

  KrylovVectors* krylov_vectors() override { return this; }
  StateAccess* state_access() override { return this; }

  void read_state(int system, std::vector<double>& f) const override {
    dev_.use();
    check_system(system);
    std::vector<T> raw;
    download_natural(system, raw);
    const SystemSpec& spec = batch_.at(static_cast<std::size_t>(system));
    f.assign(19 * count_, 0.0);
    for (int z = 0; z < d_.nz; ++z)
      for (int y = 0; y < d_.ny; ++y)
        for (int x = 0; x < d_.nx; ++x) {
          const std::size_t i = d_.index(x, y, z);
          const bool boundary = d_.is_boundary(x, y, z);
          for (int m = 0; m < 19; ++m)
            f[m * count_ + i] = boundary ? spec.boundary[m]
                                         : static_cast<double>(Storage<T>::load(raw[m * static_cast<std::size_t>(stride_) + i]));
        }
  }

  void write_state(int system, const std::vector<double>& f) override {
    dev_.use();
    check_system(system);
    if (f.size() != 19 * count_) throw std::invalid_argument("write_state: wrong state size");
    make_natural();  // the other systems of the batch keep the layout of this one
    std::vector<T> raw(19 * static_cast<std::size_t>(stride_), Storage<T>::store(0.0f));
    // Interior nodes only. Boundary nodes' slots are never read by a step, but a Krylov solve
    // copies the state into its vectors, and the slots no step writes must stay 0 there (else
    // y = A x keeps y's old values in them and A is no longer linear).
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y)
        for (int x = 1; x < d_.nx - 1; ++x) {
          const std::size_t i = d_.index(x, y, z);
          for (int m = 0; m < 19; ++m)
            raw[m * static_cast<std::size_t>(stride_) + i] = Storage<T>::store(static_cast<float>(f[m * count_ + i]));
        }
    dev_.upload(level_ptr(system, level_), raw.data(), raw.size() * sizeof(T));
    refill_inflow();
  }

  // Krylov vectors, push form: a vector is a full state (f values) of system 0, boundary-fed
  // entries included; A x leaves those entries 0, b = T(0) holds the boundary values there.
  void vectors_reserve(int count) override {
    dev_.use();
    if (!std::is_same_v<T, float>)
      throw Error(ErrorCategory::Unavailable, "the Krylov solver needs float32 storage (not float16)");
    const std::size_t first = vectors_.size();
    if (static_cast<int>(first) >= count) return;
    vectors_.resize(static_cast<std::size_t>(count));
    for (std::size_t v = first; v < vectors_.size(); ++v) {
      vectors_[v] = std::make_unique<Buffer<T>>();
      vectors_[v]->allocate(19 * static_cast<std::size_t>(stride_));
      dev_.zero(vectors_[v]->get(), vectors_[v]->bytes());
    }
    dot_partial_.allocate(kVectorBlocks + 1);
  }
  void vector_from_state(int v) override {
    make_natural();
    dev_.copy(vec(v), level_ptr(0, level_), vector_bytes());
    clear_outflow(v);
  }
  void vector_to_state(int v) override {
    make_natural();
    dev_.copy(level_ptr(0, level_), vec(v), vector_bytes());
    refill_inflow();
  }
  void vector_step_offset(int v) override {
    bind();
    dev_.zero(vec(v), vector_bytes());
    inflow(vector_args(v, v), vec(v), false);
  }
  void vector_apply(int x, int y) override {
    bind();
    dev_.step(vector_args(x, y));
    inflow(vector_args(x, y), vec(y), true);
  }
  void vector_axpby(double a, int x, double b, int y) override {
    dev_.use();
    dev_.axpby(static_cast<float>(a), vec(x), static_cast<float>(b), vec(y), 19 * stride_);
  }
  double vector_dot(int x, int y) override {
    dev_.use();
    return dev_.dot(vec(x), vec(y), 19 * stride_, dot_partial_.get());
  }

 private:
  template <typename U>
  using Buffer = typename Device::template Buffer<U>;

  std::size_t levels() const { return in_place_ ? 1 : 2; }

  T* level_ptr(int system, int level) const {
    return state_.get() + static_cast<std::size_t>(system) * levels() * 19 * static_cast<std::size_t>(stride_) +
           static_cast<std::size_t>(level) * 19 * static_cast<std::size_t>(stride_);
  }

  // The batch's state: cur the level a step reads; in place next == cur and access alternates.
  BatchArgs<T> args() const {
    BatchArgs<T> a;
    a.d = d_;
    a.stride = stride_;
    a.system_stride = static_cast<long long>(levels()) * 19 * stride_;
    a.systems = static_cast<int>(batch_.size());
    a.density = density_.get();
    a.material = material_.get();
    a.cur = level_ptr(0, level_);
    a.next = in_place_ ? a.cur : level_ptr(0, 1 - level_);
    a.totals = totals_.get();
    a.access = !in_place_ ? Access::Push : (swapped_ ? Access::SwapIn : Access::SwapOut);
    return a;
  }

  static BatchArgs<T> with_access(BatchArgs<T> a, Access access) {
    a.access = access;
    return a;
  }

  // A Krylov product y = A x between vectors: system 0's channel, two levels, whatever the state.
  BatchArgs<T> vector_args(int x, int y) const {
    BatchArgs<T> a = with_access(args(), Access::Push);
    a.systems = 1;
    a.cur = vec(x);
    a.next = vec(y);
    return a;
  }

  // Boundary-fed entries of `level` (laid out as a.cur) for a's systems, where a's access reads them.
  void inflow(const BatchArgs<T>& a, T* level, bool zero) { dev_.inflow(a, level, zero); }

  // Zeroes vector v's boundary-node slots that pushes write (light leaving the lattice), which the
  // swapped layout uses for its inflow: so a vector taken from the state is the same whatever the
  // state's layout. (A x fills them again, with what leaves: extra entries of the vectors that
  // converge with the rest, as they always have on the GPU.)
  void clear_outflow(int v) {
    bind();
    inflow(with_access(vector_args(v, v), Access::SwapIn), vec(v), true);
  }

  // After the state was written from the host or a vector: the inflow of every level (in place,
  // of both layouts) again.
  void refill_inflow() {
    bind();
    inflow(with_access(args(), Access::Push), level_ptr(0, 0), false);
    inflow(in_place_ ? with_access(args(), Access::SwapIn) : args(), level_ptr(0, in_place_ ? 0 : 1), false);
    inflow_pending_ = false;
  }

  // System `system`'s current level, in the natural layout (direction m of node i at
  // m * stride + i) at the interior nodes.
  void download_natural(int system, std::vector<T>& raw) const {
    const std::size_t n = 19 * static_cast<std::size_t>(stride_);
    raw.resize(n);
    dev_.download(raw.data(), level_ptr(system, level_), n * sizeof(T));
    if (!swapped_) return;
    std::vector<T> swapped(raw);
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y)
        for (int x = 1; x < d_.nx - 1; ++x) {
          const long long i = static_cast<long long>(d_.index(x, y, z));
          for (int m = 0; m < 19; ++m)
            raw[static_cast<std::size_t>(m * stride_ + i)] =
                swapped[static_cast<std::size_t>(i + read_offset<Access::SwapIn>(d_, stride_, m))];
        }
  }

  // Returns a swapped in-place state to the natural layout (through the host: only what a step
  // does not do needs it, a Krylov solve's start and end and writes from the host). The inflow
  // stays in place: the natural layout's comes from the swapped one's, which the upload keeps.
  void make_natural() {
    dev_.use();
    if (!swapped_) return;
    std::vector<T> raw;
    for (int s = 0; s < static_cast<int>(batch_.size()); ++s) {
      download_natural(s, raw);
      dev_.upload(level_ptr(s, level_), raw.data(), raw.size() * sizeof(T));
    }
    swapped_ = false;
  }

  // A system of the current batch: anything else would address device memory past the state.
  void check_system(int system) const {
    if (system < 0 || system >= static_cast<int>(batch_.size()))
      throw std::out_of_range("GPU solver: system " + std::to_string(system) + " is not in the batch");
  }

  T* vec(int v) const { return vectors_.at(static_cast<std::size_t>(v))->get(); }
  std::size_t vector_bytes() const { return 19 * static_cast<std::size_t>(stride_) * sizeof(T); }

  // Selects the device and puts this solver's tables in place unless they are there already.
  void bind() {
    dev_.use();
    dev_.bind(this, batch_generation_, tables_);
  }

  Device dev_;
  Dims d_;
  int capacity_;
  std::size_t count_ = 0;
  long long stride_ = 0;
  int channel_count_ = 0;
  BatchTables tables_{};
  Buffer<float> density_;
  Buffer<std::uint8_t> material_;
  Buffer<T> state_;
  Buffer<float> totals_;
  Buffer<double> partial_, reduced_, dot_partial_;
  std::vector<std::unique_ptr<Buffer<T>>> vectors_;
  std::vector<SystemSpec> batch_;
  int level_ = 0;             // two levels: the one steps read
  bool in_place_ = false;     // one level, AA pattern (Access::SwapOut / SwapIn)
  bool swapped_ = false;      // in place: an odd number of steps since the natural layout
  bool inflow_pending_ = false;
  long long batch_generation_ = 0;
};

}  // namespace lblight::gpu
