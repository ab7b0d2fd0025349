// OpenMP backend: the loop around lattice/collide.h. Threads take whole (y, z) rows; each row
// is one SIMD loop along x. Interior nodes push unconditionally (every neighbour of an interior
// node exists); boundary inflow entries are written once per batch (backend/boundary.h).
#include "backends/openmp/openmp_backend.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "lblight/backend/boundary.h"
#include "lblight/core/aligned_buffer.h"
#include "lblight/core/error.h"
#include "lblight/core/system_info.h"
#include "lblight/lattice/collide.h"

namespace lblight {
namespace {

using d3q19::kQ;

// Per-row reduction for measure(): summed serially in row order so results do not depend on
// the thread count.
struct RowSums {
  double diff_sq = 0, total_sq = 0, diff_max = 0, total_max = 0, deficit_sq = 0, deficit_max = 0;
  bool finite = true;
};

template <typename Real>
class CpuLatticeSolver final : public LatticeSolver {
 public:
  CpuLatticeSolver(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels, int capacity,
                   int threads)
      : d_(g.dims), n_(g.dims.count()), capacity_(capacity), threads_(threads) {
    if (d_.nx < 3 || d_.ny < 3 || d_.nz < 3) throw_invalid("lattice must have at least 3 nodes per edge");
    density_ = g.density;
    material_ = g.material;
    material_count_ = g.material_count;
    if (material_count_ < 1 || material_count_ > kMaxMaterials) throw std::logic_error("material count out of range");
    for (const auto& ch : channels) {
      std::array<CollisionOp<Real>, kMaxMaterials> ops{};
      for (int k = 0; k < material_count_; ++k) ops[k] = convert_op<Real>(reduce_omega(ch.omega[k]));
      ops_.push_back(ops);
      unsigned bits = 0;
      for (int k = 0; k < kMaxMaterials; ++k)
        if (ch.absorbs[k]) bits |= 1u << k;
      absorb_bits_.push_back(bits);
    }
    classify_rows();
    stride_ = padded_stride(n_);
    for (int m = 0; m < kQ; ++m)
      push_offset_[m] = static_cast<long long>(m) * static_cast<long long>(stride_) + neighbour_offset(d_, m);
    slots_.resize(static_cast<std::size_t>(capacity_));
  }

  int capacity() const override { return capacity_; }

  void reset(const std::vector<SystemSpec>& batch) override {
    if (static_cast<int>(batch.size()) > capacity_) throw std::logic_error("batch larger than solver capacity");
    active_ = static_cast<int>(batch.size());
    for (int s = 0; s < active_; ++s) {
      Slot& slot = slots_[static_cast<std::size_t>(s)];
      if (batch[s].channel < 0 || batch[s].channel >= static_cast<int>(ops_.size()))
        throw std::logic_error("system channel out of range");
      slot.spec = batch[s];
      slot.stride = stride_;
      if (slot.state.size() == 0) {
        slot.state.allocate(2 * kQ * stride_);
        slot.totals.allocate(n_);
        slot.scratch.allocate(n_);
      }
      fill(slot.state.data(), 2 * kQ * stride_, Real(0));
      double boundary_total = 0;
      for (double v : slot.spec.boundary) boundary_total += v;
      init_totals(slot.totals.data(), static_cast<Real>(boundary_total));
      init_totals(slot.scratch.data(), static_cast<Real>(boundary_total));
      slot.cur = 0;
      // t = 0 has an all-zero interior; what the boundary pushes arrives with the first step.
      apply_inflow(slot.buffer(1), slot.spec.boundary);
      slot.inflow_pending = true;
    }
  }

  void step(int steps) override {
    for (int t = 0; t < steps; ++t)
      for (int s = 0; s < active_; ++s) step_system(slots_[static_cast<std::size_t>(s)]);
  }

  void measure(std::vector<Residual>& out) override {
    out.assign(static_cast<std::size_t>(active_), Residual{});
    const int rows_y = d_.ny - 2, rows_z = d_.nz - 2;
    std::vector<RowSums> rows(static_cast<std::size_t>(rows_y) * rows_z);
    for (int s = 0; s < active_; ++s) {
      Slot& slot = slots_[static_cast<std::size_t>(s)];
      const Real* f = slot.buffer(slot.cur);
      const Real* prev = slot.totals.data();
      Real* next = slot.scratch.data();
      const auto& ops = ops_[static_cast<std::size_t>(slot.spec.channel)];
      const unsigned absorb_bits = absorb_bits_[static_cast<std::size_t>(slot.spec.channel)];
      const std::size_t n = stride_;
      const int nx = d_.nx;
#pragma omp parallel for collapse(2) schedule(static) num_threads(threads_)
      for (int z = 1; z < d_.nz - 1; ++z)
        for (int y = 1; y < d_.ny - 1; ++y) {
          const std::size_t base = d_.index(0, y, z);
          RowSums r;
          for (int x = 1; x < nx - 1; ++x) {
            const std::size_t i = base + static_cast<std::size_t>(x);
            Real fi[kQ];
            Real t = 0;
            for (int m = 0; m < kQ; ++m) {
              fi[m] = f[static_cast<std::size_t>(m) * n + i];
              t += fi[m];
            }
            next[i] = t;
            const double td = static_cast<double>(t);
            const double dd = td - static_cast<double>(prev[i]);
            r.diff_sq += dd * dd;
            r.total_sq += td * td;
            r.diff_max = std::max(r.diff_max, std::fabs(dd));
            r.total_max = std::max(r.total_max, std::fabs(td));
            if (!std::isfinite(td)) r.finite = false;
            const unsigned k = material_[i];
            if (density_[i] > 0.0f && !((absorb_bits >> k) & 1u)) {
              const double deficit = static_cast<double>(f0_deficit(ops[k], fi));
              r.deficit_sq += deficit * deficit;
              r.deficit_max = std::max(r.deficit_max, std::fabs(deficit));
            }
          }
          rows[static_cast<std::size_t>(z - 1) * rows_y + static_cast<std::size_t>(y - 1)] = r;
        }
      Residual res;
      for (const RowSums& r : rows) {
        res.diff_sq += r.diff_sq;
        res.total_sq += r.total_sq;
        res.diff_max = std::max(res.diff_max, r.diff_max);
        res.total_max = std::max(res.total_max, r.total_max);
        res.deficit_sq += r.deficit_sq;
        res.deficit_max = std::max(res.deficit_max, r.deficit_max);
        res.finite = res.finite && r.finite;
      }
      std::swap(slot.totals, slot.scratch);
      out[static_cast<std::size_t>(s)] = res;
    }
  }

  void read_totals(int system, float* out) const override {
    const Slot& slot = slots_.at(static_cast<std::size_t>(system));
    for (std::size_t i = 0; i < n_; ++i) out[i] = static_cast<float>(slot.totals[i]);
  }

  void read_state(int system, std::vector<double>& f) const override {
    const Slot& slot = slots_.at(static_cast<std::size_t>(system));
    f.assign(kQ * n_, 0.0);
    const Real* src = slot.buffer(slot.cur);
    for (int z = 0; z < d_.nz; ++z)
      for (int y = 0; y < d_.ny; ++y)
        for (int x = 0; x < d_.nx; ++x) {
          const std::size_t i = d_.index(x, y, z);
          const bool boundary = d_.is_boundary(x, y, z);
          for (int m = 0; m < kQ; ++m)
            f[static_cast<std::size_t>(m) * n_ + i] =
                boundary ? slot.spec.boundary[m] : static_cast<double>(src[static_cast<std::size_t>(m) * stride_ + i]);
        }
  }

  void write_state(int system, const std::vector<double>& f) override {
    Slot& slot = slots_.at(static_cast<std::size_t>(system));
    if (f.size() != kQ * n_) throw std::invalid_argument("write_state: wrong state size");
    Real* dst = slot.buffer(slot.cur);
    for (int m = 0; m < kQ; ++m)
      for (std::size_t i = 0; i < n_; ++i) dst[static_cast<std::size_t>(m) * stride_ + i] = static_cast<Real>(f[m * n_ + i]);
    apply_inflow(slot.buffer(0), slot.spec.boundary);
    apply_inflow(slot.buffer(1), slot.spec.boundary);
    slot.inflow_pending = false;
  }

  std::size_t bytes_in_use() const override {
    std::size_t bytes = density_.size() * sizeof(float) + material_.size();
    for (const Slot& s : slots_) bytes += (s.state.size() + s.totals.size() + s.scratch.size()) * sizeof(Real);
    return bytes;
  }

 private:
  struct Slot {
    SystemSpec spec;
    AlignedBuffer<Real> state;  // both time levels: 2 x 19 direction arrays, stride_ apart
    AlignedBuffer<Real> totals, scratch;
    int cur = 0;
    bool inflow_pending = false;
    std::size_t stride = 0;
    Real* buffer(int which) { return state.data() + static_cast<std::size_t>(which) * kQ * stride; }
    const Real* buffer(int which) const { return state.data() + static_cast<std::size_t>(which) * kQ * stride; }
  };

  // Direction arrays a multiple of 4 KiB apart alias in the CPU's store-to-load checks and
  // stall every load behind every store (a 4x slowdown measured at 128^3); spreading the 38
  // arrays over distinct 64-byte slots modulo 4 KiB avoids that.
  static std::size_t padded_stride(std::size_t count) {
    constexpr std::size_t kLine = 64 / sizeof(Real);
    std::size_t s = (count + kLine - 1) / kLine * kLine;
    while ((s * sizeof(Real)) % 4096 != 320) s += kLine;
    return s;
  }

  // Which materials each interior row holds; rows of one material run the plain collision,
  // rows of several run it once per material with the density masked, and rows with no medium
  // only stream.
  void classify_rows() {
    const int rows_y = d_.ny - 2, rows_z = d_.nz - 2;
    row_mask_.assign(static_cast<std::size_t>(rows_y) * rows_z, 0);
    row_empty_.assign(row_mask_.size(), 1);
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y) {
        const std::size_t r = static_cast<std::size_t>(z - 1) * rows_y + static_cast<std::size_t>(y - 1);
        for (int x = 1; x < d_.nx - 1; ++x) {
          const std::size_t i = d_.index(x, y, z);
          if (material_[i] >= kMaxMaterials) throw std::logic_error("material index out of range");
          row_mask_[r] |= static_cast<std::uint8_t>(1u << material_[i]);
          if (density_[i] != 0.0f) row_empty_[r] = 0;
        }
      }
  }

  void fill(Real* p, std::size_t count, Real v) const {
#pragma omp parallel for schedule(static) num_threads(threads_)
    for (std::size_t i = 0; i < count; ++i) p[i] = v;
  }

  void init_totals(Real* t, Real boundary_total) const {
    for (int z = 0; z < d_.nz; ++z)
      for (int y = 0; y < d_.ny; ++y)
        for (int x = 0; x < d_.nx; ++x) t[d_.index(x, y, z)] = d_.is_boundary(x, y, z) ? boundary_total : Real(0);
  }

  void apply_inflow(Real* f, const std::array<double, 19>& boundary) const {
#pragma omp parallel for collapse(2) schedule(static) num_threads(threads_)
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y)
        for (int x = 1; x < d_.nx - 1; ++x) {
          if (!d_.is_boundary(x - 1, y - 1, z - 1) && !d_.is_boundary(x + 1, y + 1, z + 1)) continue;
          const std::size_t i = d_.index(x, y, z);
          for (int m = 1; m < kQ; ++m)
            if (fed_by_boundary(d_, x, y, z, m)) f[static_cast<std::size_t>(m) * stride_ + i] = static_cast<Real>(boundary[m]);
        }
  }

  void step_system(Slot& slot) {
    const Real* __restrict src = slot.buffer(slot.cur);
    Real* __restrict dst = slot.buffer(1 - slot.cur);
    const auto& ops = ops_[static_cast<std::size_t>(slot.spec.channel)];
    const unsigned absorb_bits = absorb_bits_[static_cast<std::size_t>(slot.spec.channel)];
    const int rows_y = d_.ny - 2;
#pragma omp parallel for collapse(2) schedule(static) num_threads(threads_)
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y) {
        const std::size_t r = static_cast<std::size_t>(z - 1) * rows_y + static_cast<std::size_t>(y - 1);
        const std::size_t base = d_.index(0, y, z);
        const unsigned mask = row_mask_[r];
        if ((mask & (mask - 1)) == 0) {
          const int k = __builtin_ctz(mask);
          const bool absorbs = (absorb_bits >> k) & 1u;
          if (row_empty_[r]) stream_row(src, dst, base, absorbs);
          else uniform_row(src, dst, base, ops[k], absorbs);
        } else {
          mixed_row(src, dst, base, ops, absorb_bits);
        }
      }
    slot.cur = 1 - slot.cur;
    if (slot.inflow_pending) {  // the buffer written next step has not seen the boundary yet
      apply_inflow(slot.buffer(1 - slot.cur), slot.spec.boundary);
      slot.inflow_pending = false;
    }
  }

  // Row with no medium: collision is the identity, only streaming remains.
  void stream_row(const Real* __restrict src, Real* __restrict dst, std::size_t base, bool absorbs) const {
    const std::size_t n = stride_;
    const int nx = d_.nx;
    for (int m = 0; m < kQ; ++m) {
      const Real* __restrict in = src + static_cast<std::size_t>(m) * n + base;
      Real* __restrict out = dst + push_offset_[m] + static_cast<long long>(base);
      if (m == 0 && absorbs) {
        for (int x = 1; x < nx - 1; ++x) out[x] = Real(0);
      } else {
#pragma omp simd
        for (int x = 1; x < nx - 1; ++x) out[x] = in[x];
      }
    }
  }

  void uniform_row(const Real* __restrict src, Real* __restrict dst, std::size_t base, const CollisionOp<Real>& op,
                   bool absorbs) const {
    const int nx = d_.nx;
    const float* __restrict rho = density_.data() + base;
    const long long n = static_cast<long long>(stride_), sy = nx, sz = static_cast<long long>(nx) * d_.ny;
    const Real* __restrict in = src + base;
    Real* __restrict out = dst + base;
    const Real f0_keep = absorbs ? Real(0) : Real(1);
    for_each_chunk(nx, [&](int x) __attribute__((always_inline)) {
      Real f[kQ];
      LBL_UNROLL
      for (int m = 0; m < kQ; ++m) f[m] = in[m * n + x];
      collide_node(op, f0_keep, static_cast<Real>(rho[x]), f, [&](int m, Real v) {
        out[m * n + d3q19::cx(m) + d3q19::cy(m) * sy + d3q19::cz(m) * sz + x] = v;
      });
    });
  }

  // Runs node(x) for x = 1 .. nx-2 as SIMD loops of a fixed width. The last chunk is shifted
  // back to end at nx-2 and recomputes a few nodes (same inputs, same outputs) instead of
  // leaving a scalar remainder, which would cost more than the rest of the row.
  template <typename Node>
  static LBL_FORCEINLINE void for_each_chunk(int nx, Node&& node) {
    constexpr int kChunk = 16;
    if (nx - 2 < kChunk) {
#pragma omp simd
      for (int x = 1; x < nx - 1; ++x) node(x);
      return;
    }
    for (int x0 = 1; x0 < nx - 1; x0 += kChunk) {
      const int xs = x0 + kChunk > nx - 1 ? nx - 1 - kChunk : x0;
#pragma omp simd
      for (int x = xs; x < xs + kChunk; ++x) node(x);
    }
  }

  using Ops = std::array<CollisionOp<Real>, kMaxMaterials>;

  void mixed_row(const Real* __restrict src, Real* __restrict dst, std::size_t base, const Ops& ops,
                 unsigned absorb_bits) const {
    if (material_count_ <= 2) mixed_row_k<2>(src, dst, base, ops, absorb_bits);
    else mixed_row_k<kMaxMaterials>(src, dst, base, ops, absorb_bits);
  }

  template <int K>
  void mixed_row_k(const Real* __restrict src, Real* __restrict dst, std::size_t base, const Ops& ops,
                   unsigned absorb_bits) const {
    const int nx = d_.nx;
    const float* __restrict density = density_.data() + base;
    const std::uint8_t* __restrict mat = material_.data() + base;
    const long long n = static_cast<long long>(stride_), sy = nx, sz = static_cast<long long>(nx) * d_.ny;
    const Real* __restrict in = src + base;
    Real* __restrict out = dst + base;
    const CollisionOp<Real>* om[K];
    for (int k = 0; k < K; ++k) om[k] = &ops[static_cast<std::size_t>(k)];
    for_each_chunk(nx, [&](int x) __attribute__((always_inline)) {
      Real f[kQ];
      LBL_UNROLL
      for (int m = 0; m < kQ; ++m) f[m] = in[m * n + x];
      const unsigned k_node = mat[x];
      Real rho[K];
      for (int k = 0; k < K; ++k) rho[k] = static_cast<unsigned>(k) == k_node ? static_cast<Real>(density[x]) : Real(0);
      const Real f0_keep = static_cast<Real>(((absorb_bits >> k_node) & 1u) ^ 1u);
      collide_node_multi<K>(om, rho, f0_keep, f, [&](int m, Real v) {
        out[m * n + d3q19::cx(m) + d3q19::cy(m) * sy + d3q19::cz(m) * sz + x] = v;
      });
    });
  }

  Dims d_;
  std::size_t n_;
  int capacity_;
  int threads_;
  std::vector<float> density_;
  std::vector<std::uint8_t> material_;
  int material_count_ = 1;
  std::vector<std::array<CollisionOp<Real>, kMaxMaterials>> ops_;  // per channel and material
  std::vector<unsigned> absorb_bits_;     // per channel: bit k set when material k absorbs
  std::vector<std::uint8_t> row_mask_, row_empty_;
  std::size_t stride_ = 0;                // elements between direction arrays (>= count)
  long long push_offset_[kQ]{};           // m * stride + offset of p + c_m
  std::vector<Slot> slots_;
  int active_ = 0;
};

class OpenMpBackend final : public Backend {
 public:
  explicit OpenMpBackend(int threads) {
    threads_ = threads > 0 ? threads : omp_get_max_threads();
  }
  std::string name() const override { return "cpu"; }
  std::string description() const override {
    return "OpenMP, " + std::to_string(threads_) + " thread" + (threads_ == 1 ? "" : "s") + ", " + host_cpu_model();
  }
  bool supports(Precision p) const override { return p != Precision::Float16; }
  std::size_t bytes_per_system(const Dims& d, Precision p) const override {
    const std::size_t v = p == Precision::Float64 ? 8 : 4;
    return (2 * kQ + 2) * d.count() * v;
  }
  std::size_t bytes_per_lattice(const Dims& d) const override { return d.count() * (sizeof(float) + 1); }
  std::size_t available_bytes() const override { return host_available_memory_bytes(); }
  int preferred_batch(const Dims&, Precision, int total_systems) const override { return std::min(total_systems, 3); }

  std::unique_ptr<LatticeSolver> create(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels,
                                        const SolverOptions& options) const override {
    int capacity = options.max_systems > 0 ? options.max_systems : 3;
    switch (options.precision) {
      case Precision::Float32: return std::make_unique<CpuLatticeSolver<float>>(g, channels, capacity, threads_);
      case Precision::Float64: return std::make_unique<CpuLatticeSolver<double>>(g, channels, capacity, threads_);
      default:
        throw Error(ErrorCategory::Unavailable, "the cpu backend stores float32 or float64, not " +
                                                    std::string(to_string(options.precision)));
    }
  }

  double measure_copy_bandwidth(std::size_t bytes) const override {
    const std::size_t n = std::max<std::size_t>(bytes / sizeof(float), 1 << 20);
    AlignedBuffer<float> a(n), b(n);
#pragma omp parallel for schedule(static) num_threads(threads_)
    for (std::size_t i = 0; i < n; ++i) {
      a[i] = 1.0f;
      b[i] = 0.0f;
    }
    double best = 0;
    for (int rep = 0; rep < 5; ++rep) {
      const auto t0 = std::chrono::steady_clock::now();
      float* __restrict dst = b.data();
      const float* __restrict src = a.data();
#pragma omp parallel for schedule(static) num_threads(threads_)
      for (std::size_t i = 0; i < n; ++i) dst[i] = src[i];
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      best = std::max(best, 2.0 * static_cast<double>(n * sizeof(float)) / s);
    }
    if (b[n / 2] != 1.0f) throw std::logic_error("bandwidth probe failed");
    return best;
  }

 private:
  int threads_ = 1;
};

}  // namespace

std::unique_ptr<Backend> make_openmp_backend(int threads) { return std::make_unique<OpenMpBackend>(threads); }

}  // namespace lblight
