#include "tests/backend/emulated_gpu.h"

#include <algorithm>
#include <cstring>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "backends/cuda/gpu_solver.h"
#include "lblight/backend/node_rules.h"
#include "lblight/core/error.h"

// The GPU's float16 storage mode on the CPU: GCC's _Float16 converts with round-to-nearest-even,
// as __float2half_rn does on the device, and the arithmetic stays float, so the emulation rounds
// exactly where the GPU does (one conversion per stored value).
#if defined(__FLT16_MAX__)
#define LBL_TEST_HAVE_FLOAT16 1
namespace lblight::gpu {
template <>
struct Storage<_Float16> {
  static float load(_Float16 v) { return static_cast<float>(v); }
  static _Float16 store(float v) { return static_cast<_Float16>(v); }
};
}  // namespace lblight::gpu
#else
#define LBL_TEST_HAVE_FLOAT16 0
#endif

namespace lblight::test {
namespace {

using gpu::BatchArgs;
using gpu::BatchTables;
using gpu::Storage;

// Host memory in the place of device memory.
template <typename U>
class HostBuffer {
 public:
  void allocate(std::size_t count) { v_.assign(count, U(0.0f)); }
  U* get() const { return const_cast<U*>(v_.data()); }
  std::size_t size() const { return v_.size(); }
  std::size_t bytes() const { return v_.size() * sizeof(U); }

 private:
  std::vector<U> v_;
};

// cuda_backend.cu's CudaDevice, with loops over the emulated launch grids standing in for the
// kernels: each loop body is the kernel's, so each thread runs the same lb_device.h function.
class EmulatedDevice {
 public:
  template <typename U>
  using Buffer = HostBuffer<U>;

  explicit EmulatedDevice(long long fill) : fill_(fill) {}
  void use() const {}
  void upload(void* dst, const void* src, std::size_t bytes) const { std::memcpy(dst, src, bytes); }
  void download(void* dst, const void* src, std::size_t bytes) const { std::memcpy(dst, src, bytes); }
  void copy(void* dst, const void* src, std::size_t bytes) const { std::memmove(dst, src, bytes); }
  void zero(void* dst, std::size_t bytes) const { std::memset(dst, 0, bytes); }  // 0.0 in float and half
  void bind(const void*, long long, const BatchTables& t) { tables_ = &t; }
  void unbind(const void*) {}

  template <typename T>
  void step(const BatchArgs<T>& a) const {  // launch_step and step_kernel
    switch (a.access) {
      case gpu::Access::Push: step_as<gpu::Access::Push>(a); break;
      case gpu::Access::SwapOut: step_as<gpu::Access::SwapOut>(a); break;
      case gpu::Access::SwapIn: step_as<gpu::Access::SwapIn>(a); break;
    }
  }
  template <gpu::Access A, typename T>
  void step_as(const BatchArgs<T>& a) const {
    for_each_step_thread(a.d, a.systems, fill_,
                         [&](int x, int y, int z, int s0, int s1) { gpu::step_node<A>(a, *tables_, x, y, z, s0, s1); });
  }
  template <typename T>
  void inflow(const BatchArgs<T>& a, T* level, bool zero) const {  // inflow_kernel
    for_each_inflow_node(a.d, [&](int x, int y, int z) { gpu::inflow_node(a, *tables_, level, zero, x, y, z); });
  }
  void init_totals(float* totals, const Dims& d, int systems) const {  // init_totals_kernel
    for (int s = 0; s < systems; ++s)
      for (int z = 0; z < d.nz; ++z)
        for (int y = 0; y < d.ny; ++y)
          for (int x = 0; x < d.nx; ++x)
            totals[static_cast<std::size_t>(s) * d.count() + d.index(x, y, z)] =
                initial_total(d, x, y, z, tables_->boundary_totals[s]);
  }
  // measure_kernel + finish_reduce_kernel: partial sums per block of kReduceBlock interior nodes,
  // combined in block order.
  template <typename T>
  void measure(const BatchArgs<T>& a, double*, double*, double* host) const {
    const long long interior = static_cast<long long>(a.d.interior_count());
    for (int s = 0; s < a.systems; ++s) {
      double total[kReduceSlots] = {};
      for (long long b0 = 0; b0 < interior; b0 += gpu::kReduceBlock) {
        double block[kReduceSlots] = {};
        for (long long n = b0; n < std::min(interior, b0 + gpu::kReduceBlock); ++n) {
          int x, y, z;
          gpu::interior_coords(a.d, n, x, y, z);
          accumulate(block, gpu::measure_node(a, *tables_, s, x, y, z));
        }
        combine(total, block);
      }
      std::copy(total, total + kReduceSlots, host + static_cast<std::size_t>(s) * kReduceSlots);
    }
  }
  template <typename T>
  void axpby(float a, const T* x, float b, T* y, long long n) const {  // axpby_kernel
    for (long long i = 0; i < n; ++i) y[i] = Storage<T>::store(a * Storage<T>::load(x[i]) + b * Storage<T>::load(y[i]));
  }
  template <typename T>
  double dot(const T* x, const T* y, long long n, double*) const {
    double sum = 0;
    for (long long i = 0; i < n; ++i)
      sum += static_cast<double>(Storage<T>::load(x[i])) * static_cast<double>(Storage<T>::load(y[i]));
    return sum;
  }

 private:
  long long fill_;
  const BatchTables* tables_ = nullptr;
};

class EmulatedGpuBackend final : public Backend {
 public:
  explicit EmulatedGpuBackend(long long fill) : fill_(fill) {}
  std::string name() const override { return "emulated-gpu"; }
  std::string description() const override {
    return "the CUDA backend's kernels emulated on the CPU (fill " + std::to_string(fill_) + " threads)";
  }
  bool supports(Precision p) const override {
    return p == Precision::Float32 || (p == Precision::Float16 && LBL_TEST_HAVE_FLOAT16);
  }
  bool occupies_host_cores() const override { return false; }  // as the CUDA backend: output on its own thread
  std::size_t bytes_per_system(const Dims& d, Precision p) const override { return gpu::gpu_bytes_per_system(d, p); }
  std::size_t bytes_per_system_in_place(const Dims& d, Precision p) const override {
    return gpu::gpu_bytes_per_system(d, p, StateLayout::InPlace);
  }
  std::size_t bytes_per_lattice(const Dims& d) const override { return d.count() * (sizeof(float) + 1); }
  std::size_t available_bytes() const override { return 0; }  // unknown: no memory limit applied
  int preferred_batch(const Dims& d, Precision, int total) const override { return gpu::systems_to_fill(d, total); }
  std::unique_ptr<LatticeSolver> create(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels,
                                        const SolverOptions& o) const override {
    const int capacity = o.max_systems > 0 ? o.max_systems : 1;
    switch (o.precision) {
      case Precision::Float32:
        return std::make_unique<gpu::GpuSolver<float, EmulatedDevice>>(EmulatedDevice(fill_), g, channels, capacity,
                                                                        o.layout, "emulated-gpu");
#if LBL_TEST_HAVE_FLOAT16
      case Precision::Float16:
        return std::make_unique<gpu::GpuSolver<_Float16, EmulatedDevice>>(EmulatedDevice(fill_), g, channels, capacity,
                                                                           o.layout, "emulated-gpu");
#endif
      default:
        throw Error(ErrorCategory::Unavailable, std::string("the emulated GPU does not store ") + to_string(o.precision));
    }
  }
  double measure_copy_bandwidth(std::size_t) const override { return 0; }

 private:
  long long fill_;
};

}  // namespace

std::unique_ptr<Backend> make_emulated_gpu_backend(long long fill) { return std::make_unique<EmulatedGpuBackend>(fill); }

}  // namespace lblight::test
