#include "tests/backend/emulated_gpu.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "lblight/backend/node_rules.h"
#include "lblight/core/error.h"
#include "lblight/lattice/collision_op.h"

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
using gpu::Storage;

// The constant-memory tables of cuda_backend.cu (c_ops, c_absorb, c_channel, c_boundary).
struct HostTables {
  std::vector<std::array<CollisionOp<float>, kMaxMaterials>> ops;
  std::vector<unsigned> absorb;
  std::vector<int> channels;
  std::vector<std::array<float, 19>> boundaries;
  int channel(int s) const { return channels[static_cast<std::size_t>(s)]; }
  unsigned absorb_bits(int c) const { return absorb[static_cast<std::size_t>(c)]; }
  float boundary(int s, int m) const { return boundaries[static_cast<std::size_t>(s)][static_cast<std::size_t>(m)]; }
  const CollisionOp<float>& op(int c, int k) const {
    return ops[static_cast<std::size_t>(c)][static_cast<std::size_t>(k)];
  }
};

constexpr int kReduceBlock = 256;  // cuda_backend.cu's measure and dot block size

// cuda_backend.cu's Solver, launch by launch: the same state layout (push form, two levels per
// system), the same order of launches and the same per-thread functions.
template <typename T>
class EmulatedSolver final : public LatticeSolver, public KrylovVectors, public StateAccess {
 public:
  EmulatedSolver(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels, int capacity, long long fill)
      : g_(g), d_(g.dims), capacity_(capacity), fill_(fill) {
    check_geometry(g, "emulated-gpu");
    if (static_cast<int>(channels.size()) > gpu::kMaxChannels) throw std::logic_error("emulated-gpu: too many channels");
    if (capacity_ < 1 || capacity_ > gpu::kMaxBatch) throw std::logic_error("emulated-gpu: capacity out of range");
    for (const ChannelMaterials& ch : channels) {
      std::array<CollisionOp<float>, kMaxMaterials> ops{};
      unsigned bits = 0;
      for (int k = 0; k < kMaxMaterials; ++k) {
        if (k < g.material_count) ops[static_cast<std::size_t>(k)] = convert_op<float>(reduce_omega(ch.omega[k]));
        if (ch.absorbs[static_cast<std::size_t>(k)]) bits |= 1u << k;
      }
      tb_.ops.push_back(ops);
      tb_.absorb.push_back(bits);
    }
    count_ = d_.count();
    stride_ = gpu::gpu_stride(d_);
    state_.assign(static_cast<std::size_t>(capacity_) * 2 * 19 * static_cast<std::size_t>(stride_), T(0.0f));
    totals_.assign(static_cast<std::size_t>(capacity_) * count_, 0.0f);
  }

  int capacity() const override { return capacity_; }

  void reset(const std::vector<SystemSpec>& batch) override {
    if (static_cast<int>(batch.size()) > capacity_) throw std::logic_error("batch larger than solver capacity");
    tb_.channels.clear();
    tb_.boundaries.clear();
    for (const SystemSpec& s : batch) {
      if (s.channel < 0 || s.channel >= static_cast<int>(tb_.ops.size()))
        throw std::logic_error("system channel out of range");
      tb_.channels.push_back(s.channel);
      std::array<float, 19> b{};
      for (int m = 0; m < 19; ++m) b[static_cast<std::size_t>(m)] = static_cast<float>(s.boundary[m]);
      tb_.boundaries.push_back(b);
    }
    batch_ = batch;
    level_ = 0;
    std::fill(state_.begin(), state_.end(), T(0.0f));
    for (std::size_t s = 0; s < batch_.size(); ++s) {  // init_totals_kernel
      const float bt = static_cast<float>(boundary_total(batch_[s].boundary));
      for (int z = 0; z < d_.nz; ++z)
        for (int y = 0; y < d_.ny; ++y)
          for (int x = 0; x < d_.nx; ++x) totals_[s * count_ + d_.index(x, y, z)] = initial_total(d_, x, y, z, bt);
    }
    inflow(level_ptr(0, 1), false);
    inflow_pending_ = true;
  }

  void step(int steps) override {
    for (int t = 0; t < steps; ++t) {
      launch_step(args());
      level_ = 1 - level_;
      if (inflow_pending_) {
        inflow(level_ptr(0, 1 - level_), false);
        inflow_pending_ = false;
      }
    }
  }

  // measure_kernel + finish_reduce_kernel: block partial sums of kReduceBlock interior nodes,
  // combined in block order.
  void measure(std::vector<Residual>& out) override {
    out.clear();
    const BatchArgs<T> a = args();
    const long long interior = static_cast<long long>(d_.interior_count());
    for (int s = 0; s < a.systems; ++s) {
      double total[kReduceSlots] = {};
      for (long long b0 = 0; b0 < interior; b0 += kReduceBlock) {
        double block[kReduceSlots] = {};
        for (long long n = b0; n < std::min(interior, b0 + kReduceBlock); ++n) {
          int x, y, z;
          gpu::interior_coords(d_, n, x, y, z);
          accumulate(block, gpu::measure_node(a, tb_, s, x, y, z));
        }
        combine(total, block);
      }
      out.push_back(to_residual(total));
    }
  }

  void read_totals(int system, float* out) const override {
    check_system(system);
    std::copy_n(totals_.begin() + static_cast<long long>(system) * static_cast<long long>(count_), count_, out);
  }

  std::size_t bytes_in_use() const override {
    std::size_t bytes = g_.density.size() * sizeof(float) + g_.material.size() + state_.size() * sizeof(T) +
                        totals_.size() * sizeof(float);
    for (const auto& v : vectors_) bytes += v.size() * sizeof(T);
    return bytes;
  }

  KrylovVectors* krylov_vectors() override { return this; }
  StateAccess* state_access() override { return this; }

  void read_state(int system, std::vector<double>& f) const override {
    check_system(system);
    const T* raw = level_ptr(system, level_);
    const SystemSpec& spec = batch_.at(static_cast<std::size_t>(system));
    f.assign(19 * count_, 0.0);
    for (int z = 0; z < d_.nz; ++z)
      for (int y = 0; y < d_.ny; ++y)
        for (int x = 0; x < d_.nx; ++x) {
          const std::size_t i = d_.index(x, y, z);
          const bool boundary = d_.is_boundary(x, y, z);
          for (int m = 0; m < 19; ++m)
            f[m * count_ + i] =
                boundary ? spec.boundary[m] : static_cast<double>(Storage<T>::load(raw[m * static_cast<std::size_t>(stride_) + i]));
        }
  }

  void write_state(int system, const std::vector<double>& f) override {
    check_system(system);
    if (f.size() != 19 * count_) throw std::invalid_argument("write_state: wrong state size");
    T* raw = level_ptr(system, level_);
    std::fill(raw, raw + 19 * static_cast<std::size_t>(stride_), T(0.0f));
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y)
        for (int x = 1; x < d_.nx - 1; ++x) {
          const std::size_t i = d_.index(x, y, z);
          for (int m = 0; m < 19; ++m)
            raw[m * static_cast<std::size_t>(stride_) + i] = Storage<T>::store(static_cast<float>(f[m * count_ + i]));
        }
    inflow(level_ptr(0, 0), false);
    inflow(level_ptr(0, 1), false);
    inflow_pending_ = false;
  }

  // Krylov vectors, push form, as cuda_backend.cu has them.
  void vectors_reserve(int count) override {
    if (std::is_same_v<T, float> == false)
      throw Error(ErrorCategory::Unavailable, "the Krylov solver needs float32 storage (not float16)");
    while (static_cast<int>(vectors_.size()) < count) vectors_.emplace_back(19 * static_cast<std::size_t>(stride_), T(0.0f));
  }
  void vector_from_state(int v) override { std::copy_n(level_ptr(0, level_), vector_size(), vec(v)); }
  void vector_to_state(int v) override {
    std::copy_n(vec(v), vector_size(), level_ptr(0, level_));
    inflow(level_ptr(0, 0), false);
    inflow(level_ptr(0, 1), false);
    inflow_pending_ = false;
  }
  void vector_step_offset(int v) override {
    std::fill(vec(v), vec(v) + vector_size(), T(0.0f));
    inflow(vec(v), false, 1);
  }
  void vector_apply(int x, int y) override {
    BatchArgs<T> a = args();
    a.systems = 1;
    a.cur = vec(x);
    a.next = vec(y);
    launch_step(a);
    inflow(vec(y), true, 1);
  }
  void vector_axpby(double a, int x, double b, int y) override {
    const float fa = static_cast<float>(a), fb = static_cast<float>(b);
    const T* px = vec(x);
    T* py = vec(y);
    for (std::size_t i = 0; i < vector_size(); ++i)
      py[i] = Storage<T>::store(fa * Storage<T>::load(px[i]) + fb * Storage<T>::load(py[i]));
  }
  double vector_dot(int x, int y) override {
    const T* px = vec(x);
    const T* py = vec(y);
    double sum = 0;
    for (std::size_t i = 0; i < vector_size(); ++i)
      sum += static_cast<double>(Storage<T>::load(px[i])) * static_cast<double>(Storage<T>::load(py[i]));
    return sum;
  }

 private:
  T* level_ptr(int system, int level) {
    return state_.data() + static_cast<std::size_t>(system) * 2 * 19 * static_cast<std::size_t>(stride_) +
           static_cast<std::size_t>(level) * 19 * static_cast<std::size_t>(stride_);
  }
  const T* level_ptr(int system, int level) const { return const_cast<EmulatedSolver*>(this)->level_ptr(system, level); }

  BatchArgs<T> args() {
    BatchArgs<T> a;
    a.d = d_;
    a.stride = stride_;
    a.system_stride = 2 * 19 * stride_;
    a.systems = static_cast<int>(batch_.size());
    a.density = g_.density.data();
    a.material = g_.material.data();
    a.cur = level_ptr(0, level_);
    a.next = level_ptr(0, 1 - level_);
    a.totals = totals_.data();
    return a;
  }

  // step_kernel over the launch step_launch() lays out, block by block and thread by thread.
  void launch_step(const BatchArgs<T>& a) const {
    for_each_step_thread(a.d, a.systems, fill_,
                         [&](int x, int y, int z, int s0, int s1) { gpu::step_node(a, tb_, x, y, z, s0, s1); });
  }

  // inflow_kernel over the boundary shell, for `systems` systems (-1: the batch).
  void inflow(T* level, bool zero, int systems = -1) {
    BatchArgs<T> a = args();
    if (systems >= 0) a.systems = systems;
    for_each_inflow_node(d_, [&](int x, int y, int z) { gpu::inflow_node(a, tb_, level, zero, x, y, z); });
  }

  void check_system(int system) const {
    if (system < 0 || system >= static_cast<int>(batch_.size()))
      throw std::out_of_range("emulated-gpu: system " + std::to_string(system) + " is not in the batch");
  }
  T* vec(int v) { return vectors_.at(static_cast<std::size_t>(v)).data(); }
  std::size_t vector_size() const { return 19 * static_cast<std::size_t>(stride_); }

  LatticeGeometry g_;
  Dims d_;
  int capacity_;
  long long fill_;
  std::size_t count_ = 0;
  long long stride_ = 0;
  HostTables tb_;
  std::vector<SystemSpec> batch_;
  std::vector<T> state_;
  std::vector<float> totals_;
  std::vector<std::vector<T>> vectors_;
  int level_ = 0;
  bool inflow_pending_ = false;
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
  std::size_t bytes_per_system(const Dims& d, Precision p) const override {
    return 2 * 19 * static_cast<std::size_t>(gpu::gpu_stride(d)) * (p == Precision::Float16 ? 2 : 4) +
           d.count() * sizeof(float);
  }
  std::size_t bytes_per_lattice(const Dims& d) const override { return d.count() * (sizeof(float) + 1); }
  std::size_t available_bytes() const override { return 0; }  // unknown: no memory limit applied
  int preferred_batch(const Dims& d, Precision, int total) const override { return gpu::systems_to_fill(d, total); }
  std::unique_ptr<LatticeSolver> create(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels,
                                        const SolverOptions& o) const override {
    const int capacity = o.max_systems > 0 ? o.max_systems : 1;
    switch (o.precision) {
      case Precision::Float32: return std::make_unique<EmulatedSolver<float>>(g, channels, capacity, fill_);
#if LBL_TEST_HAVE_FLOAT16
      case Precision::Float16: return std::make_unique<EmulatedSolver<_Float16>>(g, channels, capacity, fill_);
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
