// CUDA backend: the thread-per-node loop around backends/cuda/lb_device.h (and so around
// lattice/collide.h). Written against gpu_runtime.h, so the same file compiles with hipcc.
//
// Choices ([Geist2010] sec. 3.1, [Steele2009] sec. 5.1, then further):
// - one thread per interior node, x along threadIdx.x: every direction array is read and
//   written coalesced (structure of arrays, x fastest);
// - the 19 values stay in registers; Omega (reduced form) lives in constant memory;
// - no index table: interior nodes push to all 19 neighbours, boundary inflow is written once
//   (and again at each Krylov product, by a launch over the boundary shell only);
// - several systems (colour channels and base solutions) per launch share the density and
//   material loads and the launch overhead; small lattices split them into groups of threads
//   so the GPU fills;
// - convergence sums are reduced on the device in a fixed order (deterministic), and only
//   seven numbers per system come back per check;
// - float16 storage with float32 arithmetic as an option.
#include "backends/cuda/cuda_backend.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <type_traits>
#include <vector>

#include "backends/cuda/gpu_runtime.h"
#include "backends/cuda/gpu_solver.h"
#include "backends/cuda/lb_device.h"
#include "lblight/core/error.h"
#include "lblight/lattice/collision_op.h"

namespace lblight {
namespace gpu {

template <>
struct Storage<gpu_half> {
  __host__ __device__ static float load(gpu_half v) { return __half2float(v); }
  __host__ __device__ static gpu_half store(float v) { return __float2half_rn(v); }
};

// Batch tables in constant memory (one solver owns them at a time; see Solver::bind).
__constant__ CollisionOp<float> c_ops[kMaxChannels][kMaxMaterials];
__constant__ unsigned c_absorb[kMaxChannels];
__constant__ int c_channel[kMaxBatch];
__constant__ float c_boundary[kMaxBatch][19];
__constant__ float c_boundary_total[kMaxBatch];  // boundary_total(), rounded once as the CPU does

struct DeviceTables {
  __device__ int channel(int s) const { return c_channel[s]; }
  __device__ unsigned absorb_bits(int c) const { return c_absorb[c]; }
  __device__ float boundary(int s, int m) const { return c_boundary[s][m]; }
  __device__ const CollisionOp<float>& op(int c, int k) const { return c_ops[c][k]; }
};

// One thread per interior node and run of systems, as step_launch() lays them out (lb_device.h).
template <typename T, bool OneRow, Access A>
__global__ void step_kernel(BatchArgs<T> a, int per_group) {
  int x, y, z, s_begin, s_end;
  if (!step_thread_node<OneRow>(a.d, per_group, a.systems, blockIdx.x, blockIdx.y, blockIdx.z, blockDim.x,
                                blockDim.y, threadIdx.x, threadIdx.y, x, y, z, s_begin, s_end))
    return;
  step_node<A>(a, DeviceTables{}, x, y, z, s_begin, s_end);
}

// The boundary-fed entries of the nodes inflow_launch() gives each thread (lb_device.h).
template <typename T>
__global__ void inflow_kernel(BatchArgs<T> a, InflowLaunch l, T* level, bool zero) {
  inflow_thread_nodes(a.d, l, blockIdx.x, static_cast<int>(threadIdx.x), static_cast<int>(blockDim.x),
                      [&](int x, int y, int z) { inflow_node(a, DeviceTables{}, level, zero, x, y, z); });
}

// y = a x + b y over n elements.
template <typename T>
__global__ void axpby_kernel(float a, const T* x, float b, T* y, long long n) {
  for (long long i = static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x; i < n;
       i += static_cast<long long>(gridDim.x) * blockDim.x)
    y[i] = Storage<T>::store(a * Storage<T>::load(x[i]) + b * Storage<T>::load(y[i]));
}

// Block partial sums of x . y, for finish_dot_kernel.
template <typename T>
__global__ void dot_kernel(const T* x, const T* y, long long n, double* partial) {
  __shared__ double shared[kReduceBlock];
  double sum = 0;
  for (long long i = static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x; i < n;
       i += static_cast<long long>(gridDim.x) * blockDim.x)
    sum += static_cast<double>(Storage<T>::load(x[i])) * static_cast<double>(Storage<T>::load(y[i]));
  shared[threadIdx.x] = sum;
  __syncthreads();
  for (int width = kReduceBlock / 2; width > 0; width /= 2) {
    if (static_cast<int>(threadIdx.x) < width) shared[threadIdx.x] += shared[threadIdx.x + width];
    __syncthreads();
  }
  if (threadIdx.x == 0) partial[blockIdx.x] = shared[0];
}

__global__ void finish_dot_kernel(const double* partial, int blocks, double* out) {
  __shared__ double shared[kReduceBlock];
  double sum = 0;
  for (int b = static_cast<int>(threadIdx.x); b < blocks; b += kReduceBlock) sum += partial[b];
  shared[threadIdx.x] = sum;
  __syncthreads();
  for (int width = kReduceBlock / 2; width > 0; width /= 2) {
    if (static_cast<int>(threadIdx.x) < width) shared[threadIdx.x] += shared[threadIdx.x + width];
    __syncthreads();
  }
  if (threadIdx.x == 0) *out = shared[0];
}

// Totals at t = 0: interior 0, boundary nodes the sum of their fixed values.
__global__ void init_totals_kernel(float* totals, Dims d, int systems) {
  const long long n = static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  const long long count = static_cast<long long>(d.count());
  if (n >= count) return;
  const int x = static_cast<int>(n % d.nx), y = static_cast<int>((n / d.nx) % d.ny),
            z = static_cast<int>(n / (static_cast<long long>(d.nx) * d.ny));
  for (int s = 0; s < systems; ++s) totals[s * count + n] = initial_total(d, x, y, z, c_boundary_total[s]);
}

// Block-level partial sums per system, written to partial[(block * systems + s) * slots].
template <typename T>
__global__ void measure_kernel(BatchArgs<T> a, double* partial) {
  __shared__ double shared[kReduceSlots][kReduceBlock];
  const long long interior = static_cast<long long>(a.d.nx - 2) * (a.d.ny - 2) * (a.d.nz - 2);
  const long long n = static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  for (int s = 0; s < a.systems; ++s) {
    double acc[kReduceSlots] = {0, 0, 0, 0, 0, 0, 0};
    if (n < interior) {
      int x, y, z;
      interior_coords(a.d, n, x, y, z);
      accumulate(acc, measure_node(a, DeviceTables{}, s, x, y, z));
    }
    for (int k = 0; k < kReduceSlots; ++k) shared[k][threadIdx.x] = acc[k];
    __syncthreads();
    for (int width = kReduceBlock / 2; width > 0; width /= 2) {
      if (static_cast<int>(threadIdx.x) < width) {
        double other[kReduceSlots];
        for (int k = 0; k < kReduceSlots; ++k) other[k] = shared[k][threadIdx.x + width];
        double mine[kReduceSlots];
        for (int k = 0; k < kReduceSlots; ++k) mine[k] = shared[k][threadIdx.x];
        combine(mine, other);
        for (int k = 0; k < kReduceSlots; ++k) shared[k][threadIdx.x] = mine[k];
      }
      __syncthreads();
    }
    if (threadIdx.x == 0)
      for (int k = 0; k < kReduceSlots; ++k)
        partial[(static_cast<long long>(blockIdx.x) * a.systems + s) * kReduceSlots + k] = shared[k][0];
    __syncthreads();
  }
}

// One block per system: each thread adds every kReduceBlock-th partial, then a tree over the block.
// A fixed order, so the same sums on every run.
__global__ void finish_reduce_kernel(const double* partial, int blocks, int systems, double* out) {
  __shared__ double shared[kReduceSlots][kReduceBlock];
  const int s = static_cast<int>(blockIdx.x);
  double acc[kReduceSlots] = {0, 0, 0, 0, 0, 0, 0};
  for (int b = static_cast<int>(threadIdx.x); b < blocks; b += kReduceBlock)
    combine(acc, partial + (static_cast<long long>(b) * systems + s) * kReduceSlots);
  for (int k = 0; k < kReduceSlots; ++k) shared[k][threadIdx.x] = acc[k];
  __syncthreads();
  for (int width = kReduceBlock / 2; width > 0; width /= 2) {
    if (static_cast<int>(threadIdx.x) < width) {
      double mine[kReduceSlots], other[kReduceSlots];
      for (int k = 0; k < kReduceSlots; ++k) {
        mine[k] = shared[k][threadIdx.x];
        other[k] = shared[k][threadIdx.x + width];
      }
      combine(mine, other);
      for (int k = 0; k < kReduceSlots; ++k) shared[k][threadIdx.x] = mine[k];
    }
    __syncthreads();
  }
  if (threadIdx.x == 0)
    for (int k = 0; k < kReduceSlots; ++k) out[s * kReduceSlots + k] = shared[k][0];
}

// A device allocation that frees itself.
template <typename T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  explicit DeviceBuffer(std::size_t count) { allocate(count); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  ~DeviceBuffer() { release(); }
  void allocate(std::size_t count) {
    release();
    if (count == 0) return;
    const gpuError_t err = gpuMalloc(reinterpret_cast<void**>(&ptr_), count * sizeof(T));
    if (err != gpuSuccess) ptr_ = nullptr;  // the destructor must not free what was never allocated
    if (err == gpuErrorMemoryAllocation) {
      (void)gpuGetLastError();  // not sticky: clear it, or the next launch check reports it
      std::size_t free_bytes = 0, total = 0;
      (void)gpuMemGetInfo(&free_bytes, &total);
      char buf[160];
      std::snprintf(buf, sizeof buf, "GPU out of memory: allocating %.3f GiB failed with %.3f GiB free",
                    static_cast<double>(count * sizeof(T)) / (1024.0 * 1024.0 * 1024.0),
                    static_cast<double>(free_bytes) / (1024.0 * 1024.0 * 1024.0));
      throw Error(ErrorCategory::Unavailable,
                  std::string(buf) + "; lower the resolution or the systems per batch, or use a GPU with more memory");
    }
    check(err, "gpuMalloc", __FILE__, __LINE__);
    count_ = count;
  }
  void release() {
    if (ptr_) (void)gpuFree(ptr_);  // nothing useful to do with an error in a destructor
    ptr_ = nullptr;
    count_ = 0;
  }
  T* get() const { return ptr_; }
  std::size_t size() const { return count_; }
  std::size_t bytes() const { return count_ * sizeof(T); }

 private:
  T* ptr_ = nullptr;
  std::size_t count_ = 0;
};

// "" when this build has code the current device (`device`) can run and the device answers, else
// why not: the binary holds sm_80/sm_90 machine code and compute_90 PTX, so older GPUs (sm_75,
// ...) have nothing to run, and every launch there would fail with "no kernel image".
std::string kernel_image_problem(int device) {
  gpuFuncAttributes attr{};
  const gpuError_t err = gpuFuncGetAttributes(&attr, reinterpret_cast<const void*>(&finish_dot_kernel));
  if (err == gpuSuccess) return "";
  (void)gpuGetLastError();
  gpuDeviceProp props{};
  std::string name = "GPU " + std::to_string(device);
  if (gpuGetDeviceProperties(&props, device) == gpuSuccess)
    name += " (" + std::string(props.name) + ", compute capability " + std::to_string(props.major) + "." +
            std::to_string(props.minor) + ")";
  (void)gpuGetLastError();
  if (err == gpuErrorNoKernelImage || err == gpuErrorInvalidDeviceFunction)
    return name + " cannot run the GPU code of this build (sm_80, sm_90, compute_90 PTX): " + gpuGetErrorString(err);
  return name + " could not be used: " + gpuGetErrorString(err);  // out of memory, ECC, a lost device, ...
}

// Why the runtime found no usable GPU, with the driver's and this build's runtime versions (a
// driver older than the runtime is the usual cause of "driver version is insufficient").
std::string no_gpu_message(gpuError_t err) {
  int driver = 0, runtime = 0;
  (void)gpuDriverGetVersion(&driver);
  (void)gpuRuntimeGetVersion(&runtime);
  (void)gpuGetLastError();
  const auto version = [](int v) {
    return v > 0 ? std::to_string(v / 1000) + "." + std::to_string(v % 1000 / 10) : std::string("none");
  };
  return std::string("no usable GPU: ") + gpuGetErrorString(err) + " (" +
         (driver > 0 ? "the driver supports up to " + version(driver) : std::string("no GPU driver found")) +
         ", this build's runtime is " + version(runtime) + ")";
}

// Per device (constant memory is per device): the solver whose tables are in its constant memory.
// One thread drives a solver at a time (bake, bench and tests do). A fixed array: no resizing
// while another thread reads it.
const void*& bound_tables_owner(int device) {
  static std::array<const void*, 256> owners{};
  return owners.at(static_cast<std::size_t>(device));
}

// Launches step_kernel over the interior (one step of every system in a).
template <typename T, Access A>
void launch_step(const BatchArgs<T>& a) {
  const StepLaunch l = step_launch(a.d, a.systems);
  if (l.gz == 0) return;
  const dim3 grid(static_cast<unsigned>(l.gx), static_cast<unsigned>(l.gy), static_cast<unsigned>(l.gz));
  const dim3 block(static_cast<unsigned>(l.bx), static_cast<unsigned>(l.by));
  if (l.by == 1) step_kernel<T, true, A><<<grid, block>>>(a, l.per_group);
  else step_kernel<T, false, A><<<grid, block>>>(a, l.per_group);
  GPU_CHECK(gpuGetLastError());
}

// The GPU behind gpu_solver.h: device memory, copies and the kernel launches above.
class CudaDevice {
 public:
  template <typename U>
  using Buffer = DeviceBuffer<U>;

  explicit CudaDevice(int device) : device_(device) {}
  // The runtime's current device is per host thread: a solver created on one thread and driven
  // from another (or after another device's work) must select its own before touching memory.
  void use() const { GPU_CHECK(gpuSetDevice(device_)); }
  void upload(void* dst, const void* src, std::size_t bytes) const {
    GPU_CHECK(gpuMemcpy(dst, src, bytes, gpuMemcpyHostToDevice));
  }
  void download(void* dst, const void* src, std::size_t bytes) const {
    GPU_CHECK(gpuMemcpy(dst, src, bytes, gpuMemcpyDeviceToHost));
  }
  void copy(void* dst, const void* src, std::size_t bytes) const {
    GPU_CHECK(gpuMemcpy(dst, src, bytes, gpuMemcpyDeviceToDevice));
  }
  void zero(void* dst, std::size_t bytes) const { GPU_CHECK(gpuMemset(dst, 0, bytes)); }

  // Puts the tables into constant memory unless this owner's are there already (constant memory
  // is per device, and one solver drives a device at a time: bake, bench and tests do).
  void bind(const void* owner, long long generation, const BatchTables& t) {
    if (bound_tables_owner(device_) == owner && bound_generation_ == generation) return;
    GPU_CHECK(gpuMemcpyToSymbol(c_ops, t.ops, sizeof(t.ops)));
    GPU_CHECK(gpuMemcpyToSymbol(c_absorb, t.absorb, sizeof(t.absorb)));
    GPU_CHECK(gpuMemcpyToSymbol(c_channel, t.channels, sizeof(t.channels)));
    GPU_CHECK(gpuMemcpyToSymbol(c_boundary, t.boundaries, sizeof(t.boundaries)));
    GPU_CHECK(gpuMemcpyToSymbol(c_boundary_total, t.boundary_totals, sizeof(t.boundary_totals)));
    bound_tables_owner(device_) = owner;
    bound_generation_ = generation;
  }
  void unbind(const void* owner) {
    if (bound_tables_owner(device_) == owner) bound_tables_owner(device_) = nullptr;
  }

  template <typename T>
  void step(const BatchArgs<T>& a) const {
    switch (a.access) {
      case Access::Push: launch_step<T, Access::Push>(a); break;
      case Access::SwapOut: launch_step<T, Access::SwapOut>(a); break;
      case Access::SwapIn: launch_step<T, Access::SwapIn>(a); break;
    }
  }
  template <typename T>
  void inflow(const BatchArgs<T>& a, T* level, bool zero) const {
    const InflowLaunch l = inflow_launch(a.d);
    if (l.blocks == 0) return;
    inflow_kernel<T><<<static_cast<unsigned>(l.blocks), kInflowThreads>>>(a, l, level, zero);
    GPU_CHECK(gpuGetLastError());
  }
  void init_totals(float* totals, const Dims& d, int systems) const {
    init_totals_kernel<<<static_cast<unsigned>((d.count() + kReduceBlock - 1) / kReduceBlock), kReduceBlock>>>(
        totals, d, systems);
    GPU_CHECK(gpuGetLastError());
  }
  template <typename T>
  void measure(const BatchArgs<T>& a, double* partial, double* reduced, double* host) const {
    const int blocks = reduce_blocks(a.d);
    measure_kernel<T><<<static_cast<unsigned>(blocks), kReduceBlock>>>(a, partial);
    GPU_CHECK(gpuGetLastError());
    finish_reduce_kernel<<<static_cast<unsigned>(a.systems), kReduceBlock>>>(partial, blocks, a.systems, reduced);
    GPU_CHECK(gpuGetLastError());
    download(host, reduced, static_cast<std::size_t>(a.systems) * kReduceSlots * sizeof(double));
  }
  template <typename T>
  void axpby(float a, const T* x, float b, T* y, long long n) const {
    axpby_kernel<T><<<kVectorBlocks, kReduceBlock>>>(a, x, b, y, n);
    GPU_CHECK(gpuGetLastError());
  }
  template <typename T>
  double dot(const T* x, const T* y, long long n, double* scratch) const {
    dot_kernel<T><<<kVectorBlocks, kReduceBlock>>>(x, y, n, scratch);
    GPU_CHECK(gpuGetLastError());
    finish_dot_kernel<<<1, kReduceBlock>>>(scratch, kVectorBlocks, scratch + kVectorBlocks);
    GPU_CHECK(gpuGetLastError());
    double out = 0;
    download(&out, scratch + kVectorBlocks, sizeof(double));
    return out;
  }

 private:
  int device_;
  long long bound_generation_ = -1;
};

class CudaBackend final : public Backend {
 public:
  explicit CudaBackend(int device) : device_(device) {
    int count = 0;
    const gpuError_t err = gpuGetDeviceCount(&count);
    if (err != gpuSuccess) throw Error(ErrorCategory::Unavailable, no_gpu_message(err));
    if (device < 0 || device >= count)
      throw Error(ErrorCategory::Unavailable,
                  "GPU " + std::to_string(device) + " does not exist (" + std::to_string(count) + " present)");
    GPU_CHECK(gpuSetDevice(device));
    GPU_CHECK(gpuGetDeviceProperties(&props_, device));
    const std::string no_code = kernel_image_problem(device);
    if (!no_code.empty()) throw Error(ErrorCategory::Unavailable, no_code);
  }
  std::string name() const override { return "cuda"; }
  std::string description() const override {
    char buf[256];
    std::snprintf(buf, sizeof buf, "%s %s, device %d (%d SMs, %.1f GiB)",
#if defined(__HIPCC__)
                  "HIP",
#else
                  "CUDA",
#endif
                  props_.name, device_, props_.multiProcessorCount,
                  static_cast<double>(props_.totalGlobalMem) / (1024.0 * 1024.0 * 1024.0));
    return buf;
  }
  bool supports(Precision p) const override { return p != Precision::Float64; }
  bool occupies_host_cores() const override { return false; }
  std::size_t bytes_per_system(const Dims& d, Precision p) const override { return gpu_bytes_per_system(d, p); }
  std::size_t bytes_per_system_in_place(const Dims& d, Precision p) const override {
    return gpu_bytes_per_system(d, p, StateLayout::InPlace);
  }
  // Measured on an H200 (docs/performance.md, "Solver throughput, GPU"): in place ran 10-44% faster
  // than two levels at every size, precision and batch, with the same bits. A solve that rewrites
  // the state between steps keeps two levels: in place turns the layout back through the host.
  bool prefers_in_place(const LatticeGeometry&, Precision, bool rewrites_state) const override { return !rewrites_state; }
  std::size_t bytes_per_lattice(const Dims& d) const override { return d.count() * (sizeof(float) + 1); }
  std::size_t available_bytes() const override {
    std::size_t free_bytes = 0, total = 0;
    GPU_CHECK(gpuSetDevice(device_));
    GPU_CHECK(gpuMemGetInfo(&free_bytes, &total));
    return free_bytes;
  }
  int preferred_batch(const Dims& d, Precision, int total_systems) const override {
    return systems_to_fill(d, total_systems);
  }
  std::size_t cache_bytes() const override { return static_cast<std::size_t>(std::max(props_.l2CacheSize, 0)); }
  std::unique_ptr<LatticeSolver> create(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels,
                                        const SolverOptions& options) const override {
    GPU_CHECK(gpuSetDevice(device_));
    // Asking for more than one launch holds is an error here, not a silent clamp: callers that
    // fill batches of max_systems (bench --systems) would otherwise fail in reset() with a
    // logic_error about the solver's capacity.
    if (options.max_systems > kMaxBatch)
      throw Error(ErrorCategory::InvalidInput, "the cuda backend runs at most " + std::to_string(kMaxBatch) +
                                                   " systems per batch, not " + std::to_string(options.max_systems));
    const int capacity = options.max_systems > 0 ? options.max_systems : 1;
    switch (options.precision) {
      case Precision::Float32:
        return std::make_unique<GpuSolver<float, CudaDevice>>(CudaDevice(device_), g, channels, capacity,
                                                              options.layout, "cuda");
      case Precision::Float16:
        return std::make_unique<GpuSolver<gpu_half, CudaDevice>>(CudaDevice(device_), g, channels, capacity,
                                                                 options.layout, "cuda");
      default:
        throw Error(ErrorCategory::Unavailable, "the cuda backend stores float32 or float16, not float64");
    }
  }
  double measure_copy_bandwidth(std::size_t bytes) const override {
    GPU_CHECK(gpuSetDevice(device_));
    DeviceBuffer<char> a(bytes), b(bytes);
    GPU_CHECK(gpuMemset(a.get(), 1, bytes));
    gpuEvent_t start, stop;
    GPU_CHECK(gpuEventCreate(&start));
    GPU_CHECK(gpuEventCreate(&stop));
    double best = 0;
    for (int rep = 0; rep < 6; ++rep) {
      GPU_CHECK(gpuEventRecord(start, 0));
      GPU_CHECK(gpuMemcpy(b.get(), a.get(), bytes, gpuMemcpyDeviceToDevice));
      GPU_CHECK(gpuEventRecord(stop, 0));
      GPU_CHECK(gpuEventSynchronize(stop));
      float ms = 0;
      GPU_CHECK(gpuEventElapsedTime(&ms, start, stop));
      if (rep > 0) best = std::max(best, 2.0 * static_cast<double>(bytes) / (ms * 1e-3));
    }
    (void)gpuEventDestroy(start);
    (void)gpuEventDestroy(stop);
    return best;
  }

 private:
  int device_;
  gpuDeviceProp props_{};
};

}  // namespace gpu

std::string cuda_unavailable_reason() {
  int count = 0;
  const gpuError_t err = gpuGetDeviceCount(&count);
  if (err != gpuSuccess) return gpu::no_gpu_message(err);
  if (count == 0) return "no GPU found";
  int device = 0;
  if (gpuGetDevice(&device) != gpuSuccess) {
    (void)gpuGetLastError();
    device = 0;
  }
  return gpu::kernel_image_problem(device);
}

std::unique_ptr<Backend> make_cuda_backend(int device) { return std::make_unique<gpu::CudaBackend>(device); }

}  // namespace lblight
