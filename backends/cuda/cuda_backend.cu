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
#include "backends/cuda/lb_device.h"
#include "lblight/core/error.h"
#include "lblight/lattice/collision_op.h"

namespace lblight {
namespace gpu {

template <>
struct Storage<gpu_half> {
  __device__ static float load(gpu_half v) { return __half2float(v); }
  __device__ static gpu_half store(float v) { return __float2half_rn(v); }
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

constexpr int kReduceBlock = 256;

// One thread per interior node and run of systems, as step_launch() lays them out (lb_device.h).
template <typename T, bool OneRow>
__global__ void step_kernel(BatchArgs<T> a, int per_group) {
  int x, y, z, s_begin, s_end;
  if (!step_thread_node<OneRow>(a.d, per_group, a.systems, blockIdx.x, blockIdx.y, blockIdx.z, blockDim.x,
                                blockDim.y, threadIdx.x, threadIdx.y, x, y, z, s_begin, s_end))
    return;
  step_node(a, DeviceTables{}, x, y, z, s_begin, s_end);
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

constexpr int kVectorBlocks = 1024;  // grid of the vector kernels (grid-stride loops)

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
template <typename T>
void launch_step(const BatchArgs<T>& a) {
  const StepLaunch l = step_launch(a.d, a.systems);
  if (l.gz == 0) return;
  const dim3 grid(static_cast<unsigned>(l.gx), static_cast<unsigned>(l.gy), static_cast<unsigned>(l.gz));
  const dim3 block(static_cast<unsigned>(l.bx), static_cast<unsigned>(l.by));
  if (l.by == 1) step_kernel<T, true><<<grid, block>>>(a, l.per_group);
  else step_kernel<T, false><<<grid, block>>>(a, l.per_group);
  GPU_CHECK(gpuGetLastError());
}

template <typename T>
class Solver final : public LatticeSolver, public KrylovVectors, public StateAccess {
 public:
  Solver(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels, int capacity)
      : d_(g.dims), capacity_(capacity) {
    check_geometry(g, "cuda");  // the step kernel picks its operator by the material byte
    if (d_.ny - 2 > 65535 || d_.nz - 2 > 65535) throw_invalid("lattice too large for the CUDA launch grid");
    if (static_cast<int>(channels.size()) > kMaxChannels || g.material_count > kMaxMaterials)
      throw std::logic_error("cuda backend: too many channels or materials");
    if (capacity_ < 1 || capacity_ > kMaxBatch) throw std::logic_error("cuda backend: batch capacity out of range");
    for (std::size_t c = 0; c < channels.size(); ++c) {
      for (int k = 0; k < g.material_count; ++k) ops_[c][k] = convert_op<float>(reduce_omega(channels[c].omega[k]));
      unsigned bits = 0;
      for (int k = 0; k < kMaxMaterials; ++k)
        if (channels[c].absorbs[k]) bits |= 1u << k;
      absorb_[c] = bits;
    }
    channel_count_ = static_cast<int>(channels.size());
    GPU_CHECK(gpuGetDevice(&device_));  // the backend's, set by create()
    count_ = d_.count();
    stride_ = gpu_stride(d_);
    density_.allocate(count_);
    material_.allocate(count_);
    GPU_CHECK(gpuMemcpy(density_.get(), g.density.data(), count_ * sizeof(float), gpuMemcpyHostToDevice));
    GPU_CHECK(gpuMemcpy(material_.get(), g.material.data(), count_, gpuMemcpyHostToDevice));
    state_.allocate(static_cast<std::size_t>(capacity_) * 2 * 19 * static_cast<std::size_t>(stride_));
    totals_.allocate(static_cast<std::size_t>(capacity_) * count_);
    const long long interior = static_cast<long long>(d_.interior_count());
    reduce_blocks_ = static_cast<int>((interior + kReduceBlock - 1) / kReduceBlock);
    partial_.allocate(static_cast<std::size_t>(reduce_blocks_) * capacity_ * kReduceSlots);
    reduced_.allocate(static_cast<std::size_t>(capacity_) * kReduceSlots);
  }

  ~Solver() override {
    if (bound_tables_owner(device_) == this) bound_tables_owner(device_) = nullptr;
  }

  int capacity() const override { return capacity_; }

  void reset(const std::vector<SystemSpec>& batch) override {
    if (static_cast<int>(batch.size()) > capacity_) throw std::logic_error("batch larger than solver capacity");
    for (const SystemSpec& s : batch)  // before taking the batch: its channels index constant tables
      if (s.channel < 0 || s.channel >= channel_count_) throw std::logic_error("system channel out of range");
    batch_ = batch;
    ++batch_generation_;  // new tables for bind()
    bind();
    level_ = 0;
    GPU_CHECK(gpuMemset(state_.get(), 0, state_.bytes()));
    const BatchArgs<T> a = args();
    init_totals_kernel<<<static_cast<unsigned>((count_ + kReduceBlock - 1) / kReduceBlock), kReduceBlock>>>(
        totals_.get(), d_, a.systems);
    GPU_CHECK(gpuGetLastError());
    inflow(level_ptr(0, 1), false);  // what the boundary pushes arrives with the first step
    inflow_pending_ = true;
  }

  void step(int steps) override {
    bind();
    for (int t = 0; t < steps; ++t) {
      launch_step(args());
      level_ = 1 - level_;
      if (inflow_pending_) {
        inflow(level_ptr(0, 1 - level_), false);
        inflow_pending_ = false;
      }
    }
  }

  void measure(std::vector<Residual>& out) override {
    out.clear();
    if (batch_.empty()) return;  // a grid of 0 blocks is a launch error
    bind();
    const BatchArgs<T> a = args();
    measure_kernel<T><<<static_cast<unsigned>(reduce_blocks_), kReduceBlock>>>(a, partial_.get());
    GPU_CHECK(gpuGetLastError());
    finish_reduce_kernel<<<static_cast<unsigned>(a.systems), kReduceBlock>>>(partial_.get(), reduce_blocks_,
                                                                            a.systems, reduced_.get());
    GPU_CHECK(gpuGetLastError());
    std::vector<double> host(static_cast<std::size_t>(a.systems) * kReduceSlots);
    GPU_CHECK(gpuMemcpy(host.data(), reduced_.get(), host.size() * sizeof(double), gpuMemcpyDeviceToHost));
    for (int s = 0; s < a.systems; ++s) out.push_back(to_residual(host.data() + static_cast<std::size_t>(s) * kReduceSlots));
  }

  void read_totals(int system, float* out) const override {
    use_device();
    check_system(system);
    GPU_CHECK(gpuMemcpy(out, totals_.get() + static_cast<std::size_t>(system) * count_, count_ * sizeof(float),
                        gpuMemcpyDeviceToHost));
  }

  KrylovVectors* krylov_vectors() override { return this; }
  StateAccess* state_access() override { return this; }

  void read_state(int system, std::vector<double>& f) const override {
    use_device();
    check_system(system);
    std::vector<T> raw(19 * static_cast<std::size_t>(stride_));
    GPU_CHECK(gpuMemcpy(raw.data(), level_ptr(system, level_), raw.size() * sizeof(T), gpuMemcpyDeviceToHost));
    const SystemSpec& spec = batch_.at(static_cast<std::size_t>(system));
    f.assign(19 * count_, 0.0);
    for (int z = 0; z < d_.nz; ++z)
      for (int y = 0; y < d_.ny; ++y)
        for (int x = 0; x < d_.nx; ++x) {
          const std::size_t i = d_.index(x, y, z);
          const bool boundary = d_.is_boundary(x, y, z);
          for (int m = 0; m < 19; ++m)
            f[m * count_ + i] = boundary ? spec.boundary[m] : to_double(raw[m * static_cast<std::size_t>(stride_) + i]);
        }
  }

  void write_state(int system, const std::vector<double>& f) override {
    use_device();
    check_system(system);
    if (f.size() != 19 * count_) throw std::invalid_argument("write_state: wrong state size");
    std::vector<T> raw(19 * static_cast<std::size_t>(stride_));
    // Interior nodes only. Boundary nodes' slots are never read by a step, but a Krylov solve
    // copies the state into its vectors, and the slots no step writes must stay 0 there (else
    // y = A x keeps y's old values in them and A is no longer linear).
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y)
        for (int x = 1; x < d_.nx - 1; ++x) {
          const std::size_t i = d_.index(x, y, z);
          for (int m = 0; m < 19; ++m) raw[m * static_cast<std::size_t>(stride_) + i] = from_double(f[m * count_ + i]);
        }
    GPU_CHECK(gpuMemcpy(level_ptr(system, level_), raw.data(), raw.size() * sizeof(T), gpuMemcpyHostToDevice));
    bind();
    inflow(level_ptr(0, 0), false);
    inflow(level_ptr(0, 1), false);
    inflow_pending_ = false;
  }

  // Krylov vectors, push form: a vector is a full state (f values) of system 0, boundary-fed
  // entries included; A x leaves those entries 0, b = T(0) holds the boundary values there.
  void vectors_reserve(int count) override {
    use_device();
    if (std::is_same_v<T, gpu_half>)
      throw Error(ErrorCategory::Unavailable, "the Krylov solver needs float32 storage (not float16)");
    const std::size_t first = vectors_.size();
    if (static_cast<int>(first) >= count) return;
    vectors_.resize(static_cast<std::size_t>(count));
    for (std::size_t v = first; v < vectors_.size(); ++v) {
      vectors_[v] = std::make_unique<DeviceBuffer<T>>(19 * static_cast<std::size_t>(stride_));
      GPU_CHECK(gpuMemset(vectors_[v]->get(), 0, vectors_[v]->bytes()));
    }
    dot_partial_.allocate(kVectorBlocks + 1);
  }
  void vector_from_state(int v) override {
    use_device();
    GPU_CHECK(gpuMemcpy(vec(v), level_ptr(0, level_), vector_bytes(), gpuMemcpyDeviceToDevice));
  }
  void vector_to_state(int v) override {
    bind();
    GPU_CHECK(gpuMemcpy(level_ptr(0, level_), vec(v), vector_bytes(), gpuMemcpyDeviceToDevice));
    inflow(level_ptr(0, 0), false);
    inflow(level_ptr(0, 1), false);
    inflow_pending_ = false;
  }
  void vector_step_offset(int v) override {
    bind();
    GPU_CHECK(gpuMemset(vec(v), 0, vector_bytes()));
    inflow(vec(v), false, 1);
  }
  void vector_apply(int x, int y) override {
    bind();
    BatchArgs<T> a = args();
    a.systems = 1;
    a.cur = vec(x);
    a.next = vec(y);
    launch_step(a);
    inflow(vec(y), true, 1);
  }
  void vector_axpby(double a, int x, double b, int y) override {
    use_device();
    axpby_kernel<T><<<kVectorBlocks, kReduceBlock>>>(static_cast<float>(a), vec(x), static_cast<float>(b), vec(y),
                                                     19 * stride_);
    GPU_CHECK(gpuGetLastError());
  }
  double vector_dot(int x, int y) override {
    use_device();
    dot_kernel<T><<<kVectorBlocks, kReduceBlock>>>(vec(x), vec(y), 19 * stride_, dot_partial_.get());
    GPU_CHECK(gpuGetLastError());
    finish_dot_kernel<<<1, kReduceBlock>>>(dot_partial_.get(), kVectorBlocks, dot_partial_.get() + kVectorBlocks);
    GPU_CHECK(gpuGetLastError());
    double out = 0;
    GPU_CHECK(gpuMemcpy(&out, dot_partial_.get() + kVectorBlocks, sizeof(double), gpuMemcpyDeviceToHost));
    return out;
  }

  std::size_t bytes_in_use() const override {
    std::size_t bytes = density_.bytes() + material_.bytes() + state_.bytes() + totals_.bytes() + partial_.bytes() +
                        reduced_.bytes() + dot_partial_.bytes();
    for (const auto& v : vectors_) bytes += v->bytes();
    return bytes;
  }

 private:
  static double to_double(float v) { return v; }
  static double to_double(gpu_half v) { return static_cast<double>(__half2float(v)); }
  static T from_double(double v) {
    if constexpr (std::is_same_v<T, float>) return static_cast<float>(v);
    else return __float2half_rn(static_cast<float>(v));
  }

  T* level_ptr(int system, int level) const {
    return state_.get() + static_cast<std::size_t>(system) * 2 * 19 * static_cast<std::size_t>(stride_) +
           static_cast<std::size_t>(level) * 19 * static_cast<std::size_t>(stride_);
  }

  BatchArgs<T> args() const {
    BatchArgs<T> a;
    a.d = d_;
    a.stride = stride_;
    a.system_stride = 2 * 19 * stride_;
    a.systems = static_cast<int>(batch_.size());
    a.density = density_.get();
    a.material = material_.get();
    a.cur = level_ptr(0, level_);
    a.next = level_ptr(0, 1 - level_);
    a.totals = totals_.get();
    return a;
  }

  // Boundary-fed entries of `level` (system 0's layout) for `systems` systems (-1: the batch).
  void inflow(T* level, bool zero, int systems = -1) {
    BatchArgs<T> a = args();
    if (systems >= 0) a.systems = systems;
    const InflowLaunch l = inflow_launch(d_);
    if (l.blocks == 0) return;
    inflow_kernel<T><<<static_cast<unsigned>(l.blocks), kInflowThreads>>>(a, l, level, zero);
    GPU_CHECK(gpuGetLastError());
  }

  // The runtime's current device is per host thread: a solver created on one thread and driven
  // from another (or after another device's work) must select its own before touching memory.
  void use_device() const { GPU_CHECK(gpuSetDevice(device_)); }

  // A system of the current batch: anything else would address device memory past the state.
  void check_system(int system) const {
    if (system < 0 || system >= static_cast<int>(batch_.size()))
      throw std::out_of_range("cuda backend: system " + std::to_string(system) + " is not in the batch");
  }

  T* vec(int v) const { return vectors_.at(static_cast<std::size_t>(v))->get(); }
  std::size_t vector_bytes() const { return 19 * static_cast<std::size_t>(stride_) * sizeof(T); }

  // Puts this solver's tables into constant memory unless they are there already.
  void bind() {
    use_device();
    if (bound_tables_owner(device_) == this && bound_batch_ == batch_generation_) return;
    GPU_CHECK(gpuMemcpyToSymbol(c_ops, ops_, sizeof(ops_)));
    GPU_CHECK(gpuMemcpyToSymbol(c_absorb, absorb_, sizeof(absorb_)));
    int channel[kMaxBatch] = {};
    float boundary[kMaxBatch][19] = {}, total[kMaxBatch] = {};
    for (std::size_t s = 0; s < batch_.size(); ++s) {
      channel[s] = batch_[s].channel;
      for (int m = 0; m < 19; ++m) boundary[s][m] = static_cast<float>(batch_[s].boundary[m]);
      total[s] = static_cast<float>(boundary_total(batch_[s].boundary));
    }
    GPU_CHECK(gpuMemcpyToSymbol(c_channel, channel, sizeof(channel)));
    GPU_CHECK(gpuMemcpyToSymbol(c_boundary, boundary, sizeof(boundary)));
    GPU_CHECK(gpuMemcpyToSymbol(c_boundary_total, total, sizeof(total)));
    bound_tables_owner(device_) = this;
    bound_batch_ = batch_generation_;
  }

  Dims d_;
  int capacity_;
  std::size_t count_ = 0;
  long long stride_ = 0;
  int channel_count_ = 0;
  int device_ = 0;
  CollisionOp<float> ops_[kMaxChannels][kMaxMaterials] = {};
  unsigned absorb_[kMaxChannels] = {};
  DeviceBuffer<float> density_;
  DeviceBuffer<std::uint8_t> material_;
  DeviceBuffer<T> state_;
  DeviceBuffer<float> totals_;
  DeviceBuffer<double> partial_, reduced_, dot_partial_;
  std::vector<std::unique_ptr<DeviceBuffer<T>>> vectors_;
  int reduce_blocks_ = 0;
  std::vector<SystemSpec> batch_;
  int level_ = 0;
  bool inflow_pending_ = false;
  long long batch_generation_ = 0, bound_batch_ = -1;
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
  std::size_t bytes_per_system(const Dims& d, Precision p) const override {
    const std::size_t v = p == Precision::Float16 ? 2 : 4;
    return 2 * 19 * static_cast<std::size_t>(gpu_stride(d)) * v + d.count() * sizeof(float) +
           ((d.interior_count() + kReduceBlock - 1) / kReduceBlock + 1) * kReduceSlots * sizeof(double);
  }
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
      case Precision::Float32: return std::make_unique<Solver<float>>(g, channels, capacity);
      case Precision::Float16: return std::make_unique<Solver<gpu_half>>(g, channels, capacity);
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
