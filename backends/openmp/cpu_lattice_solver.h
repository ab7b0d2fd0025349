// The CPU sweep (backends/openmp): the loop around lattice/collide.h. Threads take whole (y, z) rows; each row is
// processed in SIMD chunks of one cache line along x.
//
// The CPU runs the update in "pull" form: the state holds post-collision values g at their own
// node, and a step gathers f_m(q) = g_m(q - c_m), collides at q and stores g(q) back at q. That
// is the update rule of docs/model.md sec. 3 (f(t+1) = S g(t), g = C f) with the same fixed point, the same
// trajectory and the same totals; it is chosen because every store then lands on its own node:
// rows are padded so interior chunks start on a cache line, and full chunks leave through
// non-temporal stores, which skip the read-for-ownership a push scheme pays on every store
// (a third of its memory traffic). Boundary nodes (density 0, margin >= 1) hold their fixed
// values permanently, so there is no inflow bookkeeping and no branch in the inner loop.
//
// With StateLayout::InPlace one copy of the state is updated in place by the AA pattern
// (docs/performance.md, "In-place streaming"): steps alternate between a "swap-out" step (node q
// gathers as above, then stores g_m(q) into slot opposite(m) of q + c_m: exactly the entries it
// read) and a "swap-in" step (node q reads f_m(q) from its own slot opposite(m) and stores g_m(q)
// into its own slot m: the natural layout again). Each entry has one reader and writer per step,
// so rows still run in parallel, and every node sees the same arithmetic on the same inputs: the
// same bits as two levels. Two surface passes keep the fixed boundary exact (edges_in_, edges_out_).
//
// On a sparse lattice (fewer than 3/4 of its chunks hold medium, as a plant's) the two-level state
// streams by position instead (shift_offsets): values move with the array offsets, only the
// chunks with medium are touched, and the first operation that needs the natural layout (a
// written state, the Krylov vectors) rotates it back (unshift). Rows the light has not reached
// yet are skipped in the two-level pull (lit_spans.h).
#pragma once

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "backends/openmp/chunks.h"
#include "backends/openmp/lit_spans.h"
#include "backends/openmp/openmp_backend.h"
#include "backends/openmp/simd.h"
#include "lblight/backend/node_rules.h"
#include "lblight/core/aligned_buffer.h"
#include "lblight/core/error.h"
#include "lblight/core/system_info.h"
#include "lblight/lattice/collide.h"

namespace lblight::openmp {

using d3q19::kQ;

// Real: the arithmetic; Store: the state's storage (Real, or _Float16 rounded to nearest even as
// the GPU's float16 mode stores, arithmetic still in float).
template <typename Real, typename Store = Real>
class CpuLatticeSolver final : public LatticeSolver, public KrylovVectors, public StateAccess, public SlabHalo {
  // One SIMD chunk = one cache line of one direction array.
  static constexpr int kLine = 64 / static_cast<int>(sizeof(Store));
  // Non-temporal stores write whole lines of the arithmetic type: only when it is the storage's.
  static constexpr bool kCanStream = std::is_same_v<Real, Store>;
  // A row reads 19 shifted streams (and writes 19 more): more than the hardware prefetchers
  // follow, so each chunk asks for the lines this many chunks ahead (measured: 2 lines gain
  // 15-25% on a 2-core AMD EPYC, docs/performance.md).
  static constexpr int kPrefetchChunks = 2;
  // Streaming by position asks for the chunk this many busy chunks ahead (prefetch_shifted;
  // measured on plant-128: 1 or 2 gain 20%, 4 less).
  static constexpr int kAheadChunks = 2;

 public:
  CpuLatticeSolver(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels, int capacity,
                   int threads, const SolverOptions& options)
      : d_(g.dims),
        n_(g.dims.count()),
        capacity_(capacity),
        threads_(threads),
        stores_(options.stores),
        flush_denormals_(options.flush_denormals),
        time_block_option_(options.time_block),
        skip_dark_(options.skip_dark),
        in_place_(options.layout == StateLayout::InPlace),
        shift_option_(options.shift_streaming) {
    check_geometry(g, "cpu");
    density_ = g.density;
    material_ = g.material;
    material_count_ = g.material_count;
    wood_.resize(n_);
    for (std::size_t i = 0; i < n_; ++i) wood_[i] = material_[i] == kMaterialWood ? 1.0f : 0.0f;
    for (const auto& ch : channels) {
      std::array<CollisionOp<Real>, kMaxMaterials> ops{};
      for (int k = 0; k < material_count_; ++k) {
        ops[k] = convert_op<Real>(channel_op(ch, k));
        if (!options.symmetric_collision) ops[k].is_cubic = 0;
      }
      ops_.push_back(ops);
      unsigned bits = 0;
      for (int k = 0; k < kMaxMaterials; ++k)
        if (ch.absorbs[k]) bits |= 1u << k;
      absorb_bits_.push_back(bits);
      bool plain = true;  // totals are plain sums (no gains): measure_row's shorter loop
      for (int k = 0; k < kMaxMaterials; ++k)
        for (int p = 0; p < kPairs; ++p) plain = plain && ops[k].total_gain[p] == Real(0);
      plain_totals_.push_back(plain);
    }
    // Padded layout: node x of a row sits at row * pitch_ + x + (kLine - 1), so x = 1 (the first
    // interior node) starts a cache line.
    pitch_ = (d_.nx + kLine - 1 + kLine - 1) / kLine * kLine;
    plane_ = pitch_ * d_.ny;
    stride_ = padded_stride(static_cast<std::size_t>(plane_ * d_.nz));
    classify_rows();  // after the layout: ahead_ holds state indices
    slots_.resize(static_cast<std::size_t>(capacity_));
    if (in_place_) list_edges();
    if (shift_option_ && sparse_ && !in_place_) list_shift_edges();
  }

  int capacity() const override { return capacity_; }
  int steps_per_pass() const override { return time_block_; }
  bool streams_by_position() const override { return shifted_; }
  double swept_fraction() const override {
    if (!shifted_) return 1.0;
    return std::min(1.0, static_cast<double>(busy_chunks_) * kLine / static_cast<double>(d_.interior_count()));
  }

  void reset(const std::vector<SystemSpec>& batch) override {
    if (static_cast<int>(batch.size()) > capacity_) throw std::logic_error("batch larger than solver capacity");
    active_ = static_cast<int>(batch.size());
    shifted_ = !shift_edges_.empty() && time_block_option_ <= 1;
    // streaming by position keeps the state in level 0; level 1 is set up when it ends (unshift)
    const int live_levels = shifted_ ? 1 : levels();
    for (int s = 0; s < active_; ++s) {
      Slot& slot = slots_[static_cast<std::size_t>(s)];
      if (batch[s].channel < 0 || batch[s].channel >= static_cast<int>(ops_.size()))
        throw std::logic_error("system channel out of range");
      slot.spec = batch[s];
      slot.vacuum_f0_written = false;
      slot.stride = stride_;
      if (slot.state.size() == 0) {
        slot.state.allocate(levels() * kQ * stride_);
        slot.totals.allocate(n_);
        slot.scratch.allocate(n_);
      }
      fill(slot.state.data(), live_levels * kQ * stride_, Store(0));
      for (int level = 0; level < live_levels; ++level) set_boundary(slot, level);
      if (skip_dark_ && !in_place_) slot.lit.reset(d_, slot.spec.boundary);
      else slot.lit.light_all();
      const Real total = static_cast<Real>(boundary_total(slot.spec.boundary));
      init_totals(slot.totals.data(), total);
      init_totals(slot.scratch.data(), total);
    }
    now_ = 0;
    cur_ = 0;
    swapped_ = false;
    const double state_bytes = static_cast<double>(active_) * levels() * kQ * stride_ * sizeof(Store);
    const double cache = static_cast<double>(host_last_level_cache_bytes());
    stream_ = kCanStream && !in_place_ &&
              (stores_ == StoreMode::Streaming || (stores_ == StoreMode::Auto && state_bytes > 2.0 * cache));
    if (shifted_) {
      stream_ = false;
      time_block_ = 1;
      inject(0, true);
      return;
    }
    time_block_ = in_place_ ? 1
                  : time_block_option_ > 0 ? time_block_option_
                                           : auto_time_block(state_bytes / std::max(active_, 1), cache);
  }

  void step(int steps) override {
    if (shifted_) {
      for (int k = 0; k < steps; ++k) {
        if (now_ == 0) {
          inject(0, false);
        } else {
          shift_offsets(now_);
          drop_vacuum_f0();
          step_shifted();
        }
        ++now_;
        inject(now_, true);
      }
      return;
    }
    int done = 0;
    if (now_ == 0 && steps > 0) {
      // g(0) = C f(0) = 0 on the interior, which is what both levels already hold: the first
      // step only advances the clock.
      now_ = 1;
      done = 1;
    }
    if (in_place_) {
      for (; done < steps; ++done, ++now_) {
        for (int s = 0; s < active_; ++s) step_in_place(slots_[static_cast<std::size_t>(s)]);
        swapped_ = !swapped_;
      }
      return;
    }
    while (done < steps) {
      const int depth = std::min(time_block_, steps - done);
      for (int s = 0; s < active_; ++s) {
        Slot& slot = slots_[static_cast<std::size_t>(s)];
        if (depth == 1) step_system(slot);
        else wavefront(slot, depth);
      }
      if (depth % 2 == 1) cur_ = 1 - cur_;
      now_ += depth;
      done += depth;
    }
  }

  // Per row, the node rules' sums (backend/node_rules.h), then the rows added in row order: the
  // result does not depend on the thread count.
  void measure(std::vector<Residual>& out) override {
    begin_measure(out);
    for (int s = 0; s < active_; ++s) {
      const Slot& slot = slots_[static_cast<std::size_t>(s)];
#pragma omp parallel for collapse(2) schedule(dynamic, 8) num_threads(threads_)
      for (int z = 1; z < d_.nz - 1; ++z)
        for (int y = 1; y < d_.ny - 1; ++y) measure_row(slot, slot.buffer(cur_), y, z);
      out[static_cast<std::size_t>(s)] = finish_measure(s);
    }
  }

  // step(steps) then measure(out), the measurement riding along the last pass over the lattice
  // as one more wavefront stage (two layers behind the last step): the same sums in the same
  // order, without a pass of its own.
  void step_and_measure(int steps, std::vector<Residual>& out) override {
    if (time_block_ < 2 || steps < 2 || now_ == 0) {
      step(steps);
      measure(out);
      return;
    }
    const int last = std::min(time_block_, steps);
    step(steps - last);
    begin_measure(out);
    for (int s = 0; s < active_; ++s) {
      wavefront(slots_[static_cast<std::size_t>(s)], last, true);
      out[static_cast<std::size_t>(s)] = finish_measure(s);
    }
    if (last % 2 == 1) cur_ = 1 - cur_;
    now_ += last;
  }

  void read_totals(int system, float* out) const override {
    const Slot& slot = slots_.at(static_cast<std::size_t>(system));
    for (std::size_t i = 0; i < n_; ++i) out[i] = static_cast<float>(slot.totals[i]);
  }

  KrylovVectors* krylov_vectors() override { return this; }
  StateAccess* state_access() override { return this; }

  // Row by row per direction: f_m of row (y, z) is the row of g_m shifted by -c_m, a contiguous
  // copy (a warm start reads and writes a whole state per system and frame, docs/fluid.md). Each
  // value has one writer: any thread count gives the same state.
  void read_state(int system, std::vector<double>& f) const override {
    const Slot& slot = slots_.at(static_cast<std::size_t>(system));
    f.assign(kQ * n_, 0.0);
    const Store* g = slot.buffer(cur_);
    const int nx = d_.nx;
#pragma omp parallel for collapse(2) schedule(static) num_threads(threads_)
    for (int m = 0; m < kQ; ++m)
      for (int z = 0; z < d_.nz; ++z) {
        const double b = slot.spec.boundary[m];
        // swapped (in place, after a swap-out step): f_m(q) is q's own slot opposite(m)
        const int from = swapped_ ? d3q19::opposite(m) : m;
        const long long shift = swapped_ ? 0 : d3q19::cx(m) + d3q19::cy(m) * pitch_ + d3q19::cz(m) * plane_;
        for (int y = 0; y < d_.ny; ++y) {
          double* out = f.data() + static_cast<std::size_t>(m) * n_ + d_.index(0, y, z);
          if (z == 0 || z == d_.nz - 1 || y == 0 || y == d_.ny - 1) {
            std::fill(out, out + nx, b);
            continue;
          }
          out[0] = out[nx - 1] = b;
          if (now_ == 0) continue;  // the interior is 0 before the first step
          if (shifted_) {
            for (int x = 1; x < nx - 1; ++x) out[x] = static_cast<double>(g[shifted_at(m, state_index(x, y, z))]);
            continue;
          }
          const Store* src = g + static_cast<std::size_t>(from) * stride_ + (state_index(0, y, z) - shift);
          for (int x = 1; x < nx - 1; ++x) out[x] = static_cast<double>(src[x]);
        }
      }
  }

  // Stores f as the current state: g_m(q - c_m) = f_m(q) wherever q - c_m is interior. Entries
  // fed by the boundary keep the boundary values.
  void write_state(int system, const std::vector<double>& f) override {
    Slot& slot = slots_.at(static_cast<std::size_t>(system));
    if (f.size() != kQ * n_) throw std::invalid_argument("write_state: wrong state size");
    unswap();
    if (shifted_) {
      write_shifted_state(system, f);
      return;
    }
    slot.lit.light_all();
    if (now_ == 0) now_ = 1;  // a state with f(q) = S g: the first step must do real work
    Store* g = slot.buffer(cur_);
#pragma omp parallel for collapse(2) schedule(static) num_threads(threads_)
    for (int m = 0; m < kQ; ++m)
      for (int z = 1; z < d_.nz - 1; ++z) {
        const int cx = d3q19::cx(m), cy = d3q19::cy(m), cz = d3q19::cz(m);
        if (z - cz < 1 || z - cz > d_.nz - 2) continue;  // the source row is the boundary's
        // x whose source x - cx is interior
        const int x0 = std::max(1, 1 + cx), x1 = std::min(d_.nx - 2, d_.nx - 2 + cx);
        for (int y = 1; y < d_.ny - 1; ++y) {
          if (y - cy < 1 || y - cy > d_.ny - 2) continue;
          const double* in = f.data() + static_cast<std::size_t>(m) * n_ + d_.index(0, y, z);
          Store* dst = g + static_cast<std::size_t>(m) * stride_ + state_index(-cx, y - cy, z - cz);
          for (int x = x0; x <= x1; ++x) dst[x] = static_cast<Store>(in[x]);
        }
      }
  }

  // write_state while streaming by position, which it keeps (a warm start on a sparse lattice
  // runs at the by-position rate): f_m(q) goes where node q's value sits at the clock's time,
  // the boundary-fed entries are set again. A state written before the first step first takes
  // that step, which only advances the clock (as now_ = 1 does for two levels).
  void write_shifted_state(int system, const std::vector<double>& f) {
    if (now_ == 0) step(1);
    Store* g = slots_.at(static_cast<std::size_t>(system)).buffer(0);
#pragma omp parallel for collapse(2) schedule(static) num_threads(threads_)
    for (int m = 0; m < kQ; ++m)
      for (int z = 1; z < d_.nz - 1; ++z)
        for (int y = 1; y < d_.ny - 1; ++y) {
          const double* in = f.data() + static_cast<std::size_t>(m) * n_ + d_.index(0, y, z);
          for (int x = 1; x < d_.nx - 1; ++x) g[shifted_at(m, state_index(x, y, z))] = static_cast<Store>(in[x]);
        }
    inject(now_, true);
    slots_.at(static_cast<std::size_t>(system)).vacuum_f0_written = true;
  }
  // A written state may hold f_0 on nodes of density 0 (the previous frame's smoke was there).
  // The pull's next step drops it where the material absorbs (f_0 times f0_keep, plus rho times
  // the rest: 0); streaming by position does not visit empty rows and chunks, so it drops them
  // here, before that step. Nodes it does visit get the same bits either way.
  void drop_vacuum_f0() {
    for (int s = 0; s < active_; ++s) {
      Slot& slot = slots_[static_cast<std::size_t>(s)];
      if (!slot.vacuum_f0_written) continue;
      slot.vacuum_f0_written = false;
      const unsigned absorb_bits = absorb_bits_[static_cast<std::size_t>(slot.spec.channel)];
      Store* g = slot.buffer(0);
#pragma omp parallel for collapse(2) schedule(static) num_threads(threads_)
      for (int z = 1; z < d_.nz - 1; ++z)
        for (int y = 1; y < d_.ny - 1; ++y)
          for (int x = 1; x < d_.nx - 1; ++x) {
            const std::size_t i = d_.index(x, y, z);
            if (density_[i] == 0.0f && f0_keep<Real>(absorb_bits, material_[i]) == Real(0))
              g[shifted_at(0, state_index(x, y, z))] = Store(0);
          }
    }
  }

  const double* layer_sums(int system) const override {
    return layer_sums_.data() + static_cast<std::size_t>(system) * (d_.nz - 2) * kReduceSlots;
  }

  void step_layers(int z_lo, int z_hi) override {
    require_two_levels("the slab halo");
    unshift();
    for (Slot& slot : slots_) slot.lit.light_all();  // the ghost layers come from other ranks
    if (now_ > 0)
      for (int s = 0; s < active_; ++s) step_system(slots_[static_cast<std::size_t>(s)], z_lo, z_hi);
  }
  void end_step() override {
    if (now_ > 0) cur_ = 1 - cur_;
    ++now_;
  }

  // In place, the slab halo would have to follow the swapped layout: the mpi backend keeps two levels.
  void read_layer(int system, int z, int sign, double* out) const override {
    require_two_levels("the slab halo");
    if (shifted_) throw std::logic_error("the slab halo needs SolverOptions::shift_streaming off");
    const Store* g = slots_.at(static_cast<std::size_t>(system)).buffer(cur_);
    for_layer(z, sign, [&](std::size_t k, std::size_t at) { out[k] = static_cast<double>(g[at]); });
  }
  void write_layer(int system, int z, int sign, const double* in) override {
    require_two_levels("the slab halo");
    unshift();
    Slot& slot = slots_.at(static_cast<std::size_t>(system));
    slot.lit.light_all();
    Store* g = slot.buffer(cur_);
    for_layer(z, sign, [&](std::size_t k, std::size_t at) { g[at] = static_cast<Store>(in[k]); });
  }

  // In place: f_m(q) is g_m(q - c_m), and each (m, q) owns its entry, so rows run in parallel.
  void add_mode(int system, const std::vector<double>& phi, const ModeShapes& shape,
                const std::vector<std::uint8_t>& /*material: the solver's own*/) override {
    Slot& slot = slots_.at(static_cast<std::size_t>(system));
    if (phi.size() != n_) throw std::invalid_argument("add_mode: wrong size");
    unswap();
    unshift();
    slot.lit.light_all();
    if (now_ == 0) now_ = 1;  // as write_state
    Store* g = slot.buffer(cur_);
#pragma omp parallel for collapse(2) schedule(static) num_threads(threads_)
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y)
        for (int x = 1; x < d_.nx - 1; ++x) {
          const std::size_t i = d_.index(x, y, z);
          const double v = phi[i];
          if (v == 0.0) continue;
          const auto& sh = shape[material_[i]];
          for (int m = 0; m < kQ; ++m) {
            const int px = x - d3q19::cx(m), py = y - d3q19::cy(m), pz = z - d3q19::cz(m);
            if (d_.is_boundary(px, py, pz)) continue;
            Store& e = g[static_cast<std::size_t>(m) * stride_ + static_cast<std::size_t>(state_index(px, py, pz))];
            e = static_cast<Store>(static_cast<double>(e) + sh[m] * v);
          }
        }
  }

  std::size_t bytes_in_use() const override {
    std::size_t bytes = density_.size() * sizeof(float) + material_.size() + wood_.size() * sizeof(float);
    for (const Slot& s : slots_) bytes += s.state.size() * sizeof(Store) + (s.totals.size() + s.scratch.size()) * sizeof(Real);
    for (const auto& v : vectors_) bytes += v.size() * sizeof(Store);
    bytes += (edges_in_.size() + edges_out_.size()) * sizeof(Edge);
    return bytes;
  }

  // Krylov vectors: one time level in the padded state layout (post-collision values g), with
  // the boundary positions held at 0.
  void vectors_reserve(int count) override {
    if (static_cast<int>(vectors_.size()) >= count) return;
    const std::size_t first = vectors_.size();
    vectors_.resize(static_cast<std::size_t>(count));
    for (std::size_t v = first; v < vectors_.size(); ++v) {
      vectors_[v].allocate(kQ * stride_);
      fill(vectors_[v].data(), kQ * stride_, Store(0));
    }
  }

  void vector_from_state(int v) override {
    unswap();
    unshift();
    Slot& slot = slots_.front();
    copy(slot.buffer(cur_), vec(v));
    zero_boundary(vec(v));
  }

  void vector_to_state(int v) override {
    unswap();
    unshift();
    Slot& slot = slots_.front();
    slot.lit.light_all();
    copy(vec(v), slot.buffer(cur_));
    set_boundary(slot, cur_);
    if (now_ == 0) now_ = 1;  // the state is now an arbitrary g, not the t = 0 special case
  }

  void vector_step_offset(int v) override {
    // b = T(0): one step from a zero interior with the real boundary values, built in the
    // free time level.
    // (in place there is no free level: a temporary one)
    unshift();
    Slot& slot = slots_.front();
    AlignedBuffer<Store> spare;
    if (in_place_) spare.allocate(kQ * stride_);
    Store* zero = in_place_ ? spare.data() : slot.buffer(1 - cur_);
    fill(zero, kQ * stride_, Store(0));
    set_boundary(slot, zero);
    fill(vec(v), kQ * stride_, Store(0));
    sweep_system(slot, zero, vec(v));
  }

  void vector_apply(int x, int y) override { sweep_system(slots_.front(), vec(x), vec(y)); }

  void vector_axpby(double a, int x, double b, int y) override {
    const Store* __restrict px = vec(x);
    Store* __restrict py = vec(y);
    const Real ra = static_cast<Real>(a), rb = static_cast<Real>(b);
    const std::size_t n = kQ * stride_;
#pragma omp parallel for simd schedule(static) num_threads(threads_)
    for (std::size_t i = 0; i < n; ++i) py[i] = static_cast<Store>(ra * static_cast<Real>(px[i]) + rb * static_cast<Real>(py[i]));
  }

  double vector_dot(int x, int y) override {
    double xy = 0, unused = 0;
    dots(vec(x), vec(y), nullptr, nullptr, xy, unused);
    return xy;
  }

  void vector_dots(int x, int y, int u, int w, double& xy, double& uw) override {
    dots(vec(x), vec(y), vec(u), vec(w), xy, uw);
  }

  // The sweep, then each row's y = x - A x while the row is still in the cache.
  void vector_apply_minus(int x, int y) override {
    const Slot& slot = slots_.front();
    const Store* __restrict src = vec(x);
    Store* __restrict dst = vec(y);
    const int nx = d_.nx;
    sweep<false>(src, dst, ops_[static_cast<std::size_t>(slot.spec.channel)],
                 absorb_bits_[static_cast<std::size_t>(slot.spec.channel)], 1, d_.nz - 2, WholeRows{}, [&](int yy, int z) {
                   const long long row = state_index(0, yy, z);
                   for (int m = 0; m < kQ; ++m) {
                     const Store* __restrict in = src + static_cast<long long>(m) * static_cast<long long>(stride_) + row;
                     Store* __restrict out = dst + static_cast<long long>(m) * static_cast<long long>(stride_) + row;
#pragma omp simd
                     for (int i = 1; i < nx - 1; ++i)
                       out[i] = static_cast<Store>(static_cast<Real>(in[i]) - static_cast<Real>(out[i]));
                   }
                 });
  }

  void vector_combine(double a, int x, double b, int y, double c, int z) override {
    const Store* __restrict px = vec(x);
    const Store* __restrict py = vec(y);
    Store* __restrict pz = vec(z);
    const Real ra = static_cast<Real>(a), rb = static_cast<Real>(b), rc = static_cast<Real>(c);
    const std::size_t n = kQ * stride_;
    if (c == 0.0) {  // z is not read: one vector less to load
#pragma omp parallel for simd schedule(static) num_threads(threads_)
      for (std::size_t i = 0; i < n; ++i)
        pz[i] = static_cast<Store>(ra * static_cast<Real>(px[i]) + rb * static_cast<Real>(py[i]));
    } else {
#pragma omp parallel for simd schedule(static) num_threads(threads_)
      for (std::size_t i = 0; i < n; ++i)
        pz[i] = static_cast<Store>(ra * static_cast<Real>(px[i]) + rb * static_cast<Real>(py[i]) +
                                   rc * static_cast<Real>(pz[i]));
    }
  }

 private:
  std::vector<double> layer_sums_;  // the last measure(): per system and interior layer, kReduceSlots sums
  struct RowSums {
    double v[kReduceSlots];
  };
  std::vector<RowSums> rows_;  // measure(): per interior row

  struct Slot {
    SystemSpec spec;
    AlignedBuffer<Store> state;  // both time levels: 2 x 19 direction arrays, stride apart
    AlignedBuffer<Real> totals, scratch;
    std::size_t stride = 0;
    LitSpans lit;  // where each level can be nonzero (lit_spans.h)
    bool vacuum_f0_written = false;  // write_state while streaming by position: see drop_vacuum_f0
    Store* buffer(int level) { return state.data() + static_cast<std::size_t>(level) * kQ * stride; }
    const Store* buffer(int level) const { return state.data() + static_cast<std::size_t>(level) * kQ * stride; }
  };

  // Direction arrays a multiple of 4 KiB apart alias in the CPU's store-to-load checks and
  // stall every load behind every store (a 4x slowdown measured at 128^3); spreading the 38
  // arrays over distinct 64-byte slots modulo 4 KiB avoids that.
  static std::size_t padded_stride(std::size_t count) {
    std::size_t s = (count + kLine - 1) / kLine * kLine;
    while ((s * sizeof(Store)) % 4096 != 320) s += kLine;
    return s;
  }

  long long state_index(int x, int y, int z) const {
    return (static_cast<long long>(z) * d_.ny + y) * pitch_ + x + (kLine - 1);
  }

  // visit(k, state offset) over SlabHalo's layer order.
  template <typename Visit>
  void for_layer(int z, int sign, Visit&& visit) const {
    std::size_t k = 0;
    for (int m = 1; m < kQ; ++m) {
      if (d3q19::cz(m) != sign) continue;
      for (int y = 1; y < d_.ny - 1; ++y)
        for (int x = 1; x < d_.nx - 1; ++x)
          visit(k++, static_cast<std::size_t>(m) * stride_ + static_cast<std::size_t>(state_index(x, y, z)));
    }
  }

  // x.y and (where u is given) u.w in one pass: fixed blocks added in order, so the sums do not
  // depend on the thread count.
  void dots(const Store* px, const Store* py, const Store* pu, const Store* pw, double& xy, double& uw) const {
    const std::size_t n = kQ * stride_;
    constexpr std::size_t kBlock = 1 << 14;
    const std::size_t blocks = (n + kBlock - 1) / kBlock;
    std::vector<double> partial(2 * blocks, 0.0);
#pragma omp parallel for schedule(static) num_threads(threads_)
    for (std::size_t b = 0; b < blocks; ++b) {
      double s1 = 0, s2 = 0;
      const std::size_t end = std::min(n, (b + 1) * kBlock);
      if (pu)
        for (std::size_t i = b * kBlock; i < end; ++i) {
          s1 += static_cast<double>(px[i]) * static_cast<double>(py[i]);
          s2 += static_cast<double>(pu[i]) * static_cast<double>(pw[i]);
        }
      else
        for (std::size_t i = b * kBlock; i < end; ++i) s1 += static_cast<double>(px[i]) * static_cast<double>(py[i]);
      partial[2 * b] = s1;
      partial[2 * b + 1] = s2;
    }
    xy = uw = 0;
    for (std::size_t b = 0; b < blocks; ++b) {
      xy += partial[2 * b];
      uw += partial[2 * b + 1];
    }
  }

  // Where f_m(q), node q's pre-collision value in direction m, is stored in the state: g_m(q - c_m)
  // pulled, q's own slot opposite(m) swapped, the direction array's moving position by position.
  long long pre_collision_at(int m, long long q) const {
    if (shifted_) return shifted_at(m, q);
    const long long L = static_cast<long long>(stride_);
    if (swapped_) return static_cast<long long>(d3q19::opposite(m)) * L + q;
    return static_cast<long long>(m) * L + q - d3q19::cx(m) - d3q19::cy(m) * pitch_ - d3q19::cz(m) * plane_;
  }
  void gather(const Store* g, long long q, Real (&f)[kQ]) const {
    for (int m = 0; m < kQ; ++m) f[m] = static_cast<Real>(g[pre_collision_at(m, q)]);
  }

  // Which materials each interior row holds; rows of one material run the plain collision,
  // rows of several run it once per material with the density masked, and rows with no medium
  // only stream. Within a row, chunks with no medium only stream and chunks without wood run
  // the medium's collision alone (mixed_row).
  void classify_rows() {
    const int rows_y = d_.ny - 2, rows_z = d_.nz - 2;
    row_mask_.assign(static_cast<std::size_t>(rows_y) * rows_z, 0);
    row_empty_.assign(row_mask_.size(), 1);
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y) {
        const std::size_t r = static_cast<std::size_t>(z - 1) * rows_y + static_cast<std::size_t>(y - 1);
        for (int x = 1; x < d_.nx - 1; ++x) {
          const std::size_t i = d_.index(x, y, z);
          row_mask_[r] |= static_cast<std::uint8_t>(1u << material_[i]);
          if (density_[i] != 0.0f) row_empty_[r] = 0;
        }
      }
    // Chunks as run_row and run_row_in_place cut a row (chunk_nodes).
    chunks_per_row_ = (d_.nx - 2 + kLine - 1) / kLine;
    chunk_class_.assign(row_mask_.size() * static_cast<std::size_t>(chunks_per_row_), kEmptyChunk);
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y)
        for (int c = 0; c < chunks_per_row_; ++c) {
          const auto [lo, hi] = chunk_nodes(c, d_.nx, kLine);
          std::uint8_t k = kEmptyChunk;
          for (int x = lo; x <= hi; ++x) {
            const std::size_t i = d_.index(x, y, z);
            if (wood_[i] != 0.0f) k = kWoodChunk;
            else if (density_[i] != 0.0f && k == kEmptyChunk) k = kPlainChunk;
          }
          chunk_class_[(static_cast<std::size_t>(z - 1) * rows_y + static_cast<std::size_t>(y - 1)) * chunks_per_row_ +
                       static_cast<std::size_t>(c)] = k;
        }
    const auto busy = chunk_class_.size() - static_cast<std::size_t>(std::count(chunk_class_.begin(), chunk_class_.end(), kEmptyChunk));
    sparse_ = mostly_idle(busy, chunk_class_.size());
    busy_chunks_ = busy;
    // ahead_[c]: the state index of the first node of the busy chunk kAheadChunks busy chunks
    // after busy chunk c in row order (-1: none)
    ahead_.assign(chunk_class_.size(), -1);
    std::vector<std::size_t> order;
    for (std::size_t c = 0; c < chunk_class_.size(); ++c)
      if (chunk_class_[c] != kEmptyChunk) order.push_back(c);
    const auto first_node = [&](std::size_t chunk) {
      const int r = static_cast<int>(chunk / static_cast<std::size_t>(chunks_per_row_)),
                c = static_cast<int>(chunk % static_cast<std::size_t>(chunks_per_row_));
      return state_index(1 + c * kLine, 1 + r % rows_y, 1 + r / rows_y);
    };
    for (std::size_t k = 0; k + kAheadChunks < order.size(); ++k) ahead_[order[k]] = first_node(order[k + kAheadChunks]);
  }

  // What a chunk of a row holds: no medium and no wood, medium but no wood, wood.
  static constexpr std::uint8_t kEmptyChunk = 0, kPlainChunk = 1, kWoodChunk = 2;
  const std::uint8_t* chunk_classes(int y, int z) const {
    return chunk_class_.data() +
           (static_cast<std::size_t>(z - 1) * (d_.ny - 2) + static_cast<std::size_t>(y - 1)) * chunks_per_row_;
  }

  template <typename T>
  void fill(T* p, std::size_t count, T v) const {
#pragma omp parallel for schedule(static) num_threads(threads_)
    for (std::size_t i = 0; i < count; ++i) p[i] = v;
  }

  void set_boundary(const Slot& slot, int level) const { set_boundary(slot, const_cast<Store*>(slot.buffer(level))); }
  void set_boundary(const Slot& slot, Store* g) const {
    for (int z = 0; z < d_.nz; ++z)
      for (int y = 0; y < d_.ny; ++y)
        for (int x = 0; x < d_.nx; ++x)
          if (d_.is_boundary(x, y, z))
            for (int m = 0; m < kQ; ++m)
              g[static_cast<std::size_t>(m) * stride_ + static_cast<std::size_t>(state_index(x, y, z))] =
                  static_cast<Store>(slot.spec.boundary[m]);
  }

  void init_totals(Real* t, Real boundary_total) const {
    for (int z = 0; z < d_.nz; ++z)
      for (int y = 0; y < d_.ny; ++y)
        for (int x = 0; x < d_.nx; ++x) t[d_.index(x, y, z)] = initial_total(d_, x, y, z, boundary_total);
  }

  int levels() const { return in_place_ ? 1 : 2; }

  // Streaming by position, for sparse lattices (docs/performance.md). f_m(q, t) is kept in
  // level 0 at position (q - t s_m) mod L of direction array m (s_m: c_m's offset in the state
  // index, L = stride_). Then the value a node stores at step t is where node q + c_m reads it at
  // t + 1: streaming moves nothing, and a step is the in-place collision of the chunks that hold
  // medium plus writing the boundary-fed entries (f_m(q) with q - c_m on the boundary), which
  // the moving positions leave stale. Each node computes what the pull computes: the same bits.
  // offset_[m] = t s_m mod L for the time of the state at hand.
  void shift_offsets(long long t) {
    const long long L = static_cast<long long>(stride_);
    for (int m = 0; m < kQ; ++m) {
      long long o = ((t % L) * (shift(m) % L)) % L;
      if (o < 0) o += L;
      offset_[m] = o;
    }
  }
  // Where f_m(q) sits within direction m's array while streaming by position, and in the state.
  long long shifted_position(int m, long long q) const {
    const long long p = q - offset_[m];
    return p < 0 ? p + static_cast<long long>(stride_) : p;
  }
  long long shifted_at(int m, long long q) const {
    return static_cast<long long>(m) * static_cast<long long>(stride_) + shifted_position(m, q);
  }
  // f(t)'s boundary-fed entries set to the boundary values (or to 0: the first step, which only
  // advances the clock, must not stream f(0)'s); offset_ is left at t.
  void inject(long long t, bool set) {
    shift_offsets(t);
    for (int s = 0; s < active_; ++s) {
      Slot& slot = slots_[static_cast<std::size_t>(s)];
      Store* g = slot.buffer(0);
      const std::size_t n = shift_edges_.size();
      const long long L = static_cast<long long>(stride_);
#pragma omp parallel for schedule(static) num_threads(threads_)
      for (std::size_t k = 0; k < n; ++k) {
        const EdgeRun& e = shift_edges_[k];
        const Store v = set ? static_cast<Store>(slot.spec.boundary[e.m]) : Store(0);
        Store* a = g + static_cast<long long>(e.m) * L;
        long long p = e.q - offset_[e.m];
        if (p < 0) p += L;
        const long long head = std::min<long long>(e.length, L - p);  // up to the array's end
        std::fill(a + p, a + p + head, v);
        std::fill(a, a + (e.length - head), v);
      }
    }
  }
  // The boundary-fed entries f_m(q) (q - c_m on the boundary) as runs of consecutive q per
  // direction, so that inject writes the face rows as stretches, not value by value.
  void list_shift_edges() {
    std::vector<std::pair<int, long long>> entries;
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y)
        for (int x = 1; x < d_.nx - 1; ++x) {
          if (x > 1 && x < d_.nx - 2 && y > 1 && y < d_.ny - 2 && z > 1 && z < d_.nz - 2) continue;
          for (int m = 1; m < kQ; ++m)
            if (d_.is_boundary(x - d3q19::cx(m), y - d3q19::cy(m), z - d3q19::cz(m)))
              entries.emplace_back(m, state_index(x, y, z));
        }
    std::sort(entries.begin(), entries.end());
    for (const auto& [m, q] : entries) {
      if (!shift_edges_.empty()) {
        EdgeRun& last = shift_edges_.back();
        if (last.m == m && last.q + last.length == q) {
          ++last.length;
          continue;
        }
      }
      shift_edges_.push_back({m, q, 1});
    }
  }
  // One collision of every chunk with medium, in place at f(now_)'s positions.
  void step_shifted() {
    for (int s = 0; s < active_; ++s) {
      Slot& slot = slots_[static_cast<std::size_t>(s)];
      const auto& ops = ops_[static_cast<std::size_t>(slot.spec.channel)];
      const unsigned absorb_bits = absorb_bits_[static_cast<std::size_t>(slot.spec.channel)];
      Store* g = slot.buffer(0);
#pragma omp parallel num_threads(threads_)
      {
        const ScopedFlushDenormals ftz(flush_denormals_);
#pragma omp for collapse(2) schedule(dynamic, 8)
        for (int z = 1; z < d_.nz - 1; ++z)
          for (int y = 1; y < d_.ny - 1; ++y) {
            const std::size_t r = static_cast<std::size_t>(z - 1) * (d_.ny - 2) + static_cast<std::size_t>(y - 1);
            if (row_empty_[r]) continue;
            sweep_row<false, Access::Shifted>(g, g, ops, absorb_bits, y, z, WholeRows{}(y, z));
          }
      }
    }
  }

  void require_two_levels(const char* what) const {
    if (in_place_) throw std::logic_error(std::string(what) + " needs the cpu solver's two-level state layout");
  }

  // The boundary entries the in-place steps must set, as state offsets: edges_in_ before a
  // swap-out step, the entries f_m(q) fed by a boundary node (q - c_m on the boundary, stored
  // swapped in q's slot opposite(m), which no interior node writes that step: boundary value m,
  // the opposite of the entry's direction array); edges_out_ after a swap-in step, the boundary
  // node entries a swap-out step overwrote with outgoing values (slot opposite(m) of q + c_m on
  // the boundary), back to their fixed value (that of the entry's direction array).
  using Edge = std::size_t;
  void list_edges() {
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y)
        for (int x = 1; x < d_.nx - 1; ++x) {
          if (x > 1 && x < d_.nx - 2 && y > 1 && y < d_.ny - 2 && z > 1 && z < d_.nz - 2) continue;
          const long long q = state_index(x, y, z);
          for (int m = 1; m < kQ; ++m) {
            const int cx = d3q19::cx(m), cy = d3q19::cy(m), cz = d3q19::cz(m);
            const std::size_t opp = static_cast<std::size_t>(d3q19::opposite(m)) * stride_;
            if (d_.is_boundary(x - cx, y - cy, z - cz)) edges_in_.push_back(opp + static_cast<std::size_t>(q));
            if (d_.is_boundary(x + cx, y + cy, z + cz)) edges_out_.push_back(opp + static_cast<std::size_t>(q + shift(m)));
          }
        }
  }

  // One in-place step of one system: a swap-out step from the natural layout, a swap-in step
  // back to it.
  void step_in_place(Slot& slot) {
    const auto& ops = ops_[static_cast<std::size_t>(slot.spec.channel)];
    const unsigned absorb_bits = absorb_bits_[static_cast<std::size_t>(slot.spec.channel)];
    Store* g = slot.buffer(0);
    const auto& b = slot.spec.boundary;
    if (!swapped_) {
      for (const Edge e : edges_in_) g[e] = static_cast<Store>(b[static_cast<std::size_t>(d3q19::opposite(static_cast<int>(e / stride_)))]);
      sweep<false, Access::SwapOut>(g, g, ops, absorb_bits, 1, d_.nz - 2, WholeRows{});
    } else {
      sweep<false, Access::SwapIn>(g, g, ops, absorb_bits, 1, d_.nz - 2, WholeRows{});
      for (const Edge e : edges_out_) g[e] = static_cast<Store>(b[e / stride_]);
    }
  }

  // Back to the natural layout after a swap-out step, for the operations that address the state
  // as two levels do (write_state, add_mode, the Krylov vectors): per pair of opposite
  // directions, g_m(q) is the swapped entry at slot opposite(m) of q + c_m. One direction array
  // of temporary memory; the same values as the swap-in step's inputs, so the bits are kept.
  void unswap() {
    if (!swapped_) return;
    AlignedBuffer<Store> tmp(stride_);
    for (int s = 0; s < active_; ++s) {
      Slot& slot = slots_[static_cast<std::size_t>(s)];
      Store* g = slot.buffer(0);
      for (int m = 1; m < kQ; m += 2) {
        const int o = d3q19::opposite(m);
        Store* gm = g + static_cast<std::size_t>(m) * stride_;
        Store* go = g + static_cast<std::size_t>(o) * stride_;
        std::copy_n(gm, stride_, tmp.data());
        const long long sm = shift(m);
        const Store* was_m = tmp.data();
        for (int pass = 0; pass < 2; ++pass)  // gm first (it reads go), then go from the copy of gm
#pragma omp parallel for collapse(2) schedule(static) num_threads(threads_)
          for (int z = 1; z < d_.nz - 1; ++z)
            for (int y = 1; y < d_.ny - 1; ++y)
              for (int x = 1; x < d_.nx - 1; ++x) {
                const long long q = state_index(x, y, z);
                if (pass == 0) gm[q] = go[q + sm];  // g_m(q): slot opposite(m) of q + c_m
                else go[q] = was_m[q - sm];         // g_o(q): slot m of q + c_o = q - c_m
              }
      }
      set_boundary(slot, 0);
    }
    swapped_ = false;
  }

  // One step of the system's state, rows the light has not reached skipped (lit_spans.h).
  // Leaves streaming by position for the natural two-level layout, until the next reset: each
  // direction array rotated so that g(now - 1) sits at its nodes in level 0, the boundary values
  // restored (the other level still holds them from the reset).
  void unshift() {
    if (!shifted_) return;
    shifted_ = false;
    for (Slot& slot : slots_) slot.vacuum_f0_written = false;  // the pull's steps drop it themselves
    const long long L = static_cast<long long>(stride_);
    if (now_ > 0) shift_offsets(now_ - 1);
    for (int s = 0; s < active_; ++s) {
      Slot& slot = slots_[static_cast<std::size_t>(s)];
      Store* g = slot.buffer(0);
      slot.lit.light_all();
      if (now_ == 0) {
        fill(g, kQ * stride_, Store(0));
      } else {
        for (int m = 1; m < kQ; ++m) {
          Store* a = g + static_cast<std::size_t>(m) * stride_;
          std::rotate(a, a + (L - offset_[m]) % L, a + L);
        }
      }
      set_boundary(slot, 0);
      fill(slot.buffer(1), kQ * stride_, Store(0));  // left untouched by reset
      set_boundary(slot, 1);
    }
    cur_ = 0;
  }

  void step_system(Slot& slot, int z_lo = 1, int z_hi = -1) {
    const int from = cur_;
    sweep_system(slot, slot.buffer(cur_), slot.buffer(1 - cur_), z_lo, z_hi,
                 [&](int y, int z) LBL_INLINE_LAMBDA { return slot.lit.advance(from, y, z); });
  }

  // One pull step from level src to level dst with the materials of slot's channel, over the
  // layers z_lo..z_hi (-1: the last interior one); span(y, z): the nodes of row (y, z) to sweep.
  template <typename RowSpan = WholeRows>
  void sweep_system(const Slot& slot, const Store* src, Store* dst, int z_lo = 1, int z_hi = -1,
                    RowSpan&& span = WholeRows{}) const {
    const auto& ops = ops_[static_cast<std::size_t>(slot.spec.channel)];
    const unsigned absorb_bits = absorb_bits_[static_cast<std::size_t>(slot.spec.channel)];
    if (z_hi < 0) z_hi = d_.nz - 2;
    if (stream_) sweep<true>(src, dst, ops, absorb_bits, z_lo, z_hi, span);
    else sweep<false>(src, dst, ops, absorb_bits, z_lo, z_hi, span);
  }


  Store* vec(int v) { return vectors_.at(static_cast<std::size_t>(v)).data(); }

  void copy(const Store* src, Store* dst) const {
    const std::size_t n = kQ * stride_;
#pragma omp parallel for simd schedule(static) num_threads(threads_)
    for (std::size_t i = 0; i < n; ++i) dst[i] = src[i];
  }

  void zero_boundary(Store* g) const {
    for (int z = 0; z < d_.nz; ++z)
      for (int y = 0; y < d_.ny; ++y)
        for (int x = 0; x < d_.nx; ++x)
          if (d_.is_boundary(x, y, z))
            for (int m = 0; m < kQ; ++m)
              g[static_cast<std::size_t>(m) * stride_ + static_cast<std::size_t>(state_index(x, y, z))] = Store(0);
  }

  // after_row(y, z) runs on the sweeping thread right after row (y, z) is written.
  // In place (A != Pull), src is not used: dst is the one level.
  // span(y, z): the nodes of row (y, z) to sweep (lit_spans.h).
  template <bool kStream, Access A = Access::Pull, typename RowSpan, typename AfterRow = void (*)(int, int)>
  void sweep(const Store* src, Store* dst, const std::array<CollisionOp<Real>, kMaxMaterials>& ops,
             unsigned absorb_bits, int z_lo, int z_hi, RowSpan&& span, AfterRow&& after_row = [](int, int) {}) const {
#pragma omp parallel num_threads(threads_)
    {
      const ScopedFlushDenormals ftz(flush_denormals_);
#pragma omp for collapse(2) schedule(dynamic, 8)
      for (int z = z_lo; z <= z_hi; ++z)
        for (int y = 1; y < d_.ny - 1; ++y) {
          sweep_row<kStream, A>(src, dst, ops, absorb_bits, y, z, span(y, z));
          after_row(y, z);
        }
      if (kStream) stream_fence();  // make this thread's streaming stores visible before the barrier
    }
  }

  // The automatic wavefront depth: 1 while one system's two levels fit in half the cache (its
  // steps are served from the cache already); else the deepest of 2..8 whose live layers
  // (2 depth + 2 layers of both levels) take at most half the cache, measured in
  // docs/performance.md.
  // 16-bit storage: 1, as its conversions, not the memory, bound it (blocked was 0.8-0.95x of
  // step by step at 128^3 on the development machine).
  int auto_time_block(double system_bytes, double cache) const {
    if (!std::is_same_v<Real, Store>) return 1;
    if (cache <= 0 || system_bytes <= 0.5 * cache) return 1;
    const double layer = 2.0 * kQ * static_cast<double>(plane_) * sizeof(Store);
    int depth = 1;
    for (int k = 2; k <= 8; ++k)
      if ((2.0 * k + 2.0) * layer <= 0.5 * cache) depth = k;
    return depth;
  }

  // `depth` steps of one system in one pass over the lattice (temporal blocking, docs/performance.md):
  // a wavefront moves along z, and at position p step t (0-based) updates layer p - 2t, from
  // level (cur + t) mod 2 into the other. Each step's layer lags its predecessor's by two, so
  // everything it reads (layers z-1..z+1 of step t-1's output) is finished and not yet
  // overwritten (step t+1 writes into the same level two layers behind), and the `depth` layers
  // of one position touch disjoint data: they run in parallel, one barrier per position. Only
  // the layers of about 2 depth + 2 positions of both levels are live, so for a lattice far
  // larger than the cache each value crosses the memory bus once per block instead of once per
  // step. Every node sees the same arithmetic on the same inputs as step by step: the results
  // are the same bits. The last step streams its stores past the cache (when stream_ says so):
  // its layer is not read again in this pass.
  // With measure, stage t = depth is measure()'s row work on the final level (rows_).
  // Each step's rows record where they are lit for the next (lit_spans.h); those spans follow
  // the same dependencies as the data, so they need no more synchronisation.
  void wavefront(Slot& slot, int depth, bool measure = false) {
    const auto& ops = ops_[static_cast<std::size_t>(slot.spec.channel)];
    const unsigned absorb_bits = absorb_bits_[static_cast<std::size_t>(slot.spec.channel)];
    const Store* level[2] = {slot.buffer(cur_), slot.buffer(1 - cur_)};
    const int z_last = d_.nz - 2, rows_y = d_.ny - 2;
    const int stages = depth + (measure ? 1 : 0);
    // the last step's layer is read again by the measure stage: keep it in the cache then
    const bool stream_last = stream_ && !measure;
#pragma omp parallel num_threads(threads_)
    {
      const ScopedFlushDenormals ftz(flush_denormals_);
      for (int p = 1; p <= z_last + 2 * (stages - 1); ++p) {
        // the stages whose layer p - 2t lies in 1..z_last
        const int t_lo = std::max(0, (p - z_last + 1) / 2), t_hi = std::min(stages - 1, (p - 1) / 2);
        const int items = (t_hi - t_lo + 1) * rows_y;
#pragma omp for schedule(dynamic, 4)
        for (int item = 0; item < items; ++item) {
          const int t = t_lo + item / rows_y, y = 1 + item % rows_y, z = p - 2 * t;
          const Store* src = level[t % 2];
          if (t == depth) {
            measure_row(slot, src, y, z);
            continue;
          }
          Store* dst = const_cast<Store*>(level[1 - t % 2]);
          const Span span = slot.lit.advance(t % 2 == 0 ? cur_ : 1 - cur_, y, z);
          if (stream_last && t == depth - 1) sweep_row<true>(src, dst, ops, absorb_bits, y, z, span);
          else sweep_row<false>(src, dst, ops, absorb_bits, y, z, span);
        }
        if (stream_last) stream_fence();
      }
    }
  }

  // measure()'s work on row (y, z) of system slot, whose current level is g: the node rules'
  // sums (backend/node_rules.h) into rows_, the new totals into the scratch array. The totals
  // of a block of nodes are summed across x in SIMD, direction by direction (each node's sum in
  // node_residual's order: the same bits), then reduced node by node in x order.
  void measure_row(const Slot& slot, const Store* g, int y, int z) {
    const auto& ops = ops_[static_cast<std::size_t>(slot.spec.channel)];
    const unsigned absorb_bits = absorb_bits_[static_cast<std::size_t>(slot.spec.channel)];
    const bool plain = plain_totals_[static_cast<std::size_t>(slot.spec.channel)];
    const Real* prev = slot.totals.data();
    Real* next = const_cast<Real*>(slot.scratch.data());
    const std::size_t base = d_.index(0, y, z);
    const int nx = d_.nx;
    RowSums r{};
    // row_base[m][x]: f_m of node x of this row, unless a direction array wraps inside the row
    const Store* row_base[kQ];
    bool whole = true;
    const long long L = static_cast<long long>(stride_), row = state_index(0, y, z);
    for (int m = 0; m < kQ; ++m) {
      const long long at = pre_collision_at(m, row);
      whole = whole && (!shifted_ || shifted_position(m, row) + nx <= L);  // no wrap inside the row
      row_base[m] = g + at;
    }
    if (!whole) {
      for (int x = 1; x < nx - 1; ++x) {
        const std::size_t i = base + static_cast<std::size_t>(x);
        Real f[kQ];
        gather(g, state_index(x, y, z), f);
        const unsigned k = material_[i];
        accumulate(r.v, node_residual(ops[k], f0_keep<Real>(absorb_bits, k) != Real(0), density_[i], f, prev[i], next[i]));
      }
      rows_[static_cast<std::size_t>(z - 1) * (d_.ny - 2) + static_cast<std::size_t>(y - 1)] = r;
      return;
    }
    constexpr int kBlock = 4 * kLine;
    alignas(64) Real t[kBlock], rho[kBlock];
    alignas(64) std::uint8_t mat[kBlock];
    for (int x0 = 1; x0 < nx - 1; x0 += kBlock) {
      const int n = std::min(kBlock, nx - 1 - x0);
      const float* dens = density_.data() + base + x0;
      const std::uint8_t* mats = material_.data() + base + x0;
      const Store* f0 = row_base[0] + x0;
#pragma omp simd
      for (int j = 0; j < n; ++j) {
        t[j] = static_cast<Real>(f0[j]);
        rho[j] = static_cast<Real>(dens[j]);
        mat[j] = mats[j];
      }
      for (int m = 1; m < kQ; ++m) {
        const Store* fm = row_base[m] + x0;
        if (plain) {  // gains 0: factors exactly 1, so the plain sum is the same bits
#pragma omp simd
          for (int j = 0; j < n; ++j) t[j] += static_cast<Real>(fm[j]);
          continue;
        }
        const int p = (m - 1) / 2;
        const Real g0 = ops[0].total_gain[p], g1 = ops[1].total_gain[p], g2 = ops[2].total_gain[p];
#pragma omp simd
        for (int j = 0; j < n; ++j) {
          const Real gain = mat[j] == 0 ? g0 : (mat[j] == 1 ? g1 : g2);
          t[j] += static_cast<Real>(fm[j]) * (Real(1) + rho[j] * gain);
        }
      }
      for (int j = 0; j < n; ++j) {
        const std::size_t i = base + static_cast<std::size_t>(x0 + j);
        next[i] = t[j];
        NodeResidual nr;
        nr.total = static_cast<double>(t[j]);
        nr.diff = static_cast<double>(t[j]) - static_cast<double>(prev[i]);
        const unsigned k = mat[j];
        if (rho[j] > Real(0) && f0_keep<Real>(absorb_bits, k) != Real(0)) {
          Real f[kQ];
          for (int m = 0; m < kQ; ++m) f[m] = static_cast<Real>(row_base[m][x0 + j]);
          nr.deficit = static_cast<double>(f0_deficit(ops[k], f));
        }
        accumulate(r.v, nr);
      }
    }
    rows_[static_cast<std::size_t>(z - 1) * (d_.ny - 2) + static_cast<std::size_t>(y - 1)] = r;
  }

  // Sizes what measure_row and finish_measure fill.
  void begin_measure(std::vector<Residual>& out) {
    out.assign(static_cast<std::size_t>(active_), Residual{});
    rows_.resize(static_cast<std::size_t>(d_.ny - 2) * (d_.nz - 2));
    layer_sums_.assign(static_cast<std::size_t>(active_) * (d_.nz - 2) * kReduceSlots, 0.0);
  }

  // Rows into layers, layers in z order (the order a slab decomposition can repeat exactly);
  // the new totals become the current ones.
  Residual finish_measure(int s) {
    const int rows_y = d_.ny - 2, rows_z = d_.nz - 2;
    double* layers = layer_sums_.data() + static_cast<std::size_t>(s) * rows_z * kReduceSlots;
    double sums[kReduceSlots] = {};
    for (int z = 0; z < rows_z; ++z) {
      double l[kReduceSlots] = {};
      for (int y = 0; y < rows_y; ++y) combine(l, rows_[static_cast<std::size_t>(z) * rows_y + static_cast<std::size_t>(y)].v);
      combine(sums, l);
      std::copy_n(l, kReduceSlots, layers + static_cast<std::size_t>(z) * kReduceSlots);
    }
    Slot& slot = slots_[static_cast<std::size_t>(s)];
    std::swap(slot.totals, slot.scratch);
    return to_residual(sums);
  }

  // One row's pull update: the row's materials pick the kernel (classify_rows).
  template <bool kStream, Access A = Access::Pull>
  LBL_FORCEINLINE void sweep_row(const Store* src, Store* dst, const std::array<CollisionOp<Real>, kMaxMaterials>& ops,
                                 unsigned absorb_bits, int y, int z, Span span) const {
    if (span.empty()) return;  // dark: its zeros are already there
    const std::size_t r = static_cast<std::size_t>(z - 1) * (d_.ny - 2) + static_cast<std::size_t>(y - 1);
    const unsigned mask = row_mask_[r];
    if ((mask & (mask - 1)) == 0) {
      const int k = __builtin_ctz(mask);
      const Real keep = f0_keep<Real>(absorb_bits, static_cast<unsigned>(k));
      if (row_empty_[r]) stream_row<kStream, A>(src, dst, y, z, span, keep);
      else uniform_row<kStream, A>(src, dst, y, z, span, ops[static_cast<std::size_t>(k)], keep);
    } else {
      mixed_row<kStream, A>(src, dst, y, z, span, ops, absorb_bits);
    }
  }

  // pick(c, body) hands chunk c's node function to body (chunk_class_: a row's chunks may take
  // different node functions, chosen per chunk, outside the SIMD loop).
  template <bool kStream, Access A, typename Pick>
  LBL_FORCEINLINE void run(const Store* __restrict src, Store* __restrict dst, int y, int z, Span span,
                           Pick&& pick) const {
    if constexpr (A == Access::Pull) run_row<kStream>(src, dst, y, z, span, pick);
    else if constexpr (A == Access::Shifted) run_row_shifted(dst, y, z, pick);
    else run_row_in_place<A>(dst, y, z, pick);
  }

  // run_row for streaming by position: the chunks of row (y, z) that hold medium, each node
  // once (the tail is not shifted back), through one pointer per direction unless the chunk
  // straddles the end of a direction array.
  template <typename Pick>
  LBL_FORCEINLINE void run_row_shifted(Store* g, int y, int z, Pick&& pick) const {
    const int nx = d_.nx;
    const long long row = state_index(0, y, z);
    const std::uint8_t* cls = chunk_classes(y, z);
    auto load = [&](int x, Real(&f)[kQ]) LBL_INLINE_LAMBDA {
      LBL_UNROLL
      for (int m = 0; m < kQ; ++m) f[m] = static_cast<Real>(g[shifted_at(m, row + x)]);
    };
    const long long L = static_cast<long long>(stride_);
    const std::size_t first = static_cast<std::size_t>(cls - chunk_class_.data());
    for (int c = 0; c < chunks_per_row_; ++c) {
      if (cls[c] == kEmptyChunk) continue;
      prefetch_shifted(g, ahead_[first + static_cast<std::size_t>(c)]);
      const int x0 = 1 + c * kLine, x1 = std::min(x0 + kLine, nx - 1);
      Store* base[kQ];
      bool whole = true;
      for (int m = 0; m < kQ; ++m) {
        const long long p = shifted_position(m, row + x0);
        whole = whole && p + (x1 - x0) <= L;
        base[m] = g + static_cast<long long>(m) * L + p - x0;
      }
      if constexpr (!kCanStream) {  // 16-bit storage: the chunk converted through staged_chunk,
        // a whole line per instruction group, a short or wrapping chunk value by value
        const int count = x1 - x0;
        const bool line = whole && count == kLine;
        pick(c, [&](auto&& node) LBL_INLINE_LAMBDA {
          staged_chunk(
              x0, x1 - 1,
              [&](int m, Real* stage) LBL_INLINE_LAMBDA {
                if (line) return halves_to_reals<kLine>(base[m] + x0, stage);
                for (int l = 0; l < kLine; ++l)
                  stage[l] = l < count ? static_cast<Real>(g[shifted_at(m, row + x0 + l)]) : Real(0);
              },
              [&](int m, const Real* post) LBL_INLINE_LAMBDA {
                if (line) return reals_to_halves<kLine>(post, base[m] + x0);
                for (int l = 0; l < count; ++l) g[shifted_at(m, row + x0 + l)] = static_cast<Store>(post[l]);
              },
              node);
        });
      } else if (whole) {
        auto near = [&](int x, Real(&f)[kQ]) LBL_INLINE_LAMBDA {
          LBL_UNROLL
          for (int m = 0; m < kQ; ++m) f[m] = static_cast<Real>(base[m][x]);
        };
        pick(c, [&](auto&& node) LBL_INLINE_LAMBDA {
          Store* const* to = base;  // a local of this lambda (clang: see run_row)
#pragma omp simd
          for (int x = x0; x < x1; ++x)
            node(x, near, [&](int m, Real v) LBL_INLINE_LAMBDA { to[m][x] = static_cast<Store>(v); });
        });
      } else {
        pick(c, [&](auto&& node) LBL_INLINE_LAMBDA {
          for (int x = x0; x < x1; ++x)
            node(x, load, [&](int m, Real v) LBL_INLINE_LAMBDA { g[shifted_at(m, row + x)] = static_cast<Store>(v); });
        });
      }
    }
  }

  // Asks for the lines of the busy chunk whose first node is q (ahead_; -1: none) at the current
  // positions: chunks with medium lie scattered over 19 arrays whose offsets differ, which the
  // hardware prefetchers do not follow.
  LBL_FORCEINLINE void prefetch_shifted(const Store* g, long long q) const {
    if (q < 0) return;
    LBL_UNROLL
    for (int m = 0; m < kQ; ++m) {
      const Store* a = g + shifted_at(m, q);
      __builtin_prefetch(a, 1, 3);
      __builtin_prefetch(a + kLine - 1, 1, 3);  // a hint: past an array's end it is harmless
    }
  }

  // Offset of q - c_m from q in the state layout.
  LBL_FORCEINLINE long long shift(int m) const {
    return d3q19::cx(m) + d3q19::cy(m) * pitch_ + d3q19::cz(m) * plane_;
  }

  // run_row for the in-place steps: g is the one level, read and written by the same nodes.
  // No shifted last chunk (a node computed twice would read its own output after its store).
  template <Access A, typename Pick>
  LBL_FORCEINLINE void run_row_in_place(Store* g, int y, int z, Pick&& pick) const {
    const int nx = d_.nx;
    const long long row = state_index(0, y, z);
    const long long stride = static_cast<long long>(stride_);
    // where node x's f_m comes from, and where its post-collision g_m goes
    auto from = [&](int m, int x) LBL_INLINE_LAMBDA {
      return A == Access::SwapOut ? m * stride + row + x - shift(m) : d3q19::opposite(m) * stride + row + x;
    };
    auto to = [&](int m, int x) LBL_INLINE_LAMBDA {
      return A == Access::SwapOut ? d3q19::opposite(m) * stride + row + x + shift(m) : m * stride + row + x;
    };
    // the lines kPrefetchChunks chunks ahead of x, for reading and writing: a node's 19 stores go
    // to the 19 entries it reads (to(m, x) is from(opposite(m), x)). Past the row's end the
    // addresses stay inside the state's allocation.
    auto prefetch = [&](int x) LBL_INLINE_LAMBDA {
      LBL_UNROLL
      for (int m = 0; m < kQ; ++m) __builtin_prefetch(g + from(m, x + kPrefetchChunks * kLine), 1, 3);
    };
    if constexpr (kCanStream) {
      auto load = [&](int x, Real(&f)[kQ]) LBL_INLINE_LAMBDA {
        LBL_UNROLL
        for (int m = 0; m < kQ; ++m) f[m] = static_cast<Real>(g[from(m, x)]);
      };
      for (int x0 = 1; x0 < nx - 1; x0 += kLine) {
        prefetch(x0);
        const int x1 = std::min(x0 + kLine, nx - 1);
        pick((x0 - 1) / kLine, [&](auto&& node) LBL_INLINE_LAMBDA {
          Store* const state = g;  // locals of this lambda (clang: see run_row)
          const auto& put = to;
#pragma omp simd
          for (int x = x0; x < x1; ++x)
            node(x, load, [&](int m, Real v) LBL_INLINE_LAMBDA { state[put(m, x)] = static_cast<Store>(v); });
        });
      }
    } else {  // whole chunks converted 16 values per instruction; the remainder by value, its nodes
              // still a whole chunk's SIMD arithmetic (the extra lanes repeat node nx - 2, unstored)
      int x = 1;
      for (; x + kLine - 1 <= nx - 2; x += kLine) {
        prefetch(x);
        pick((x - 1) / kLine, [&](auto&& node) LBL_INLINE_LAMBDA {
          staged_chunk(
              x, nx - 2, [&](int m, Real* stage) LBL_INLINE_LAMBDA { halves_to_reals<kLine>(g + from(m, x), stage); },
              [&](int m, const Real* post) LBL_INLINE_LAMBDA { reals_to_halves<kLine>(post, g + to(m, x)); }, node);
        });
      }
      const int count = nx - 1 - x;
      if (count > 0)
        pick((x - 1) / kLine, [&](auto&& node) LBL_INLINE_LAMBDA {
          staged_chunk(
              x, nx - 2,
              [&](int m, Real* stage) LBL_INLINE_LAMBDA {
                for (int l = 0; l < kLine; ++l) stage[l] = l < count ? static_cast<Real>(g[from(m, x + l)]) : Real(0);
              },
              [&](int m, const Real* post) LBL_INLINE_LAMBDA {
                for (int l = 0; l < count; ++l) g[to(m, x + l)] = static_cast<Store>(post[l]);
              },
              node);
        });
    }
  }

  // Runs node(x, sink) for the interior of row (y, z); node hands each post-collision value to
  // sink(m, value). Full chunks start on a cache line and, with kStream, leave through a small
  // aligned buffer and non-temporal stores. The remainder is a full-width chunk shifted back to
  // end at nx-2: it recomputes a few nodes (same inputs, same outputs) instead of running a
  // scalar tail, which would cost more than the rest of the row. Only the chunks that meet `span`
  // run (the others are dark: lit_spans.h).
  template <bool kStream, typename Pick>
  LBL_FORCEINLINE void run_row(const Store* __restrict src, Store* __restrict dst, int y, int z, Span span,
                               Pick&& pick) const {
    const int nx = d_.nx;
    const long long srow = state_index(0, y, z);
    const long long stride = static_cast<long long>(stride_);
    auto load = [&](int x, Real(&f)[kQ]) LBL_INLINE_LAMBDA { gather_row(src, srow, x, f); };
    if (nx - 2 < kLine) {
      Store* __restrict out = dst + srow;
      pick(0, [&](auto&& node) LBL_INLINE_LAMBDA {
        // clang refuses, inside an OpenMP region within a generic lambda, an inner lambda's
        // reference to the enclosing function's locals: it gets this lambda's own copies
        Store* __restrict to = out;
        const long long step = stride;
#pragma omp simd
        for (int x = 1; x < nx - 1; ++x)
          node(x, load, [&](int m, Real v) LBL_INLINE_LAMBDA { to[m * step + x] = static_cast<Store>(v); });
      });
      return;
    }
    int x0 = 1 + (span.lo - 1) / kLine * kLine;
    for (; x0 + kLine - 1 <= nx - 2 && x0 <= span.hi; x0 += kLine) {
      Store* __restrict out = dst + srow + x0;
      LBL_UNROLL
      for (int m = 0; m < kQ; ++m) {  // past the row's end: still inside the state's allocation
        __builtin_prefetch(src + srow + x0 + kPrefetchChunks * kLine - shift(m) + m * stride, 0, 3);
        if constexpr (!(kStream && kCanStream)) __builtin_prefetch(out + kPrefetchChunks * kLine + m * stride, 1, 3);
      }
      pick((x0 - 1) / kLine, [&](auto&& node) LBL_INLINE_LAMBDA {
        if constexpr (!kCanStream) {
          converted_chunk(src, out, srow + x0, x0, node);
        } else if constexpr (kStream) {
          alignas(64) Real post[kQ][kLine];
#pragma omp simd
          for (int l = 0; l < kLine; ++l) node(x0 + l, load, [&](int m, Real v) LBL_INLINE_LAMBDA { post[m][l] = v; });
          for (int m = 0; m < kQ; ++m) stream_line(out + m * stride, post[m]);
        } else {
          Store* __restrict to = out;
          const long long step = stride;
#pragma omp simd
          for (int l = 0; l < kLine; ++l)
            node(x0 + l, load, [&](int m, Real v) LBL_INLINE_LAMBDA { to[m * step + l] = static_cast<Store>(v); });
        }
      });
    }
    if (x0 <= nx - 2 && x0 <= span.hi) {
      const int xs = nx - 1 - kLine;
      Store* __restrict out = dst + srow + xs;
      pick((x0 - 1) / kLine, [&](auto&& node) LBL_INLINE_LAMBDA {
        if constexpr (!kCanStream) {
          converted_chunk(src, out, srow + xs, xs, node);
        } else {
          Store* __restrict to = out;
          const long long step = stride;
#pragma omp simd
          for (int l = 0; l < kLine; ++l)
            node(xs + l, load, [&](int m, Real v) LBL_INLINE_LAMBDA { to[m * step + l] = static_cast<Store>(v); });
        }
      });
    }
  }

  // 16-bit storage: the kLine nodes from x0 (none past `last`: lanes beyond it repeat node last)
  // run on arithmetic-type copies, filled direction by direction by in(m, stage) and handed back
  // by out(m, post), so the conversions go 16 values per instruction (halves_to_reals).
  template <typename In, typename Out, typename Node>
  LBL_FORCEINLINE void staged_chunk(int x0, int last, In&& in, Out&& out, Node&& node) const {
    alignas(64) Real stage[kQ][kLine];
    alignas(64) Real post[kQ][kLine];
    for (int m = 0; m < kQ; ++m) in(m, stage[m]);
#pragma omp simd
    for (int l = 0; l < kLine; ++l)
      node(
          std::min(x0 + l, last),
          [&](int, Real(&f)[kQ]) LBL_INLINE_LAMBDA {
            LBL_UNROLL
            for (int m = 0; m < kQ; ++m) f[m] = stage[m][l];
          },
          [&](int m, Real v) LBL_INLINE_LAMBDA { post[m][l] = v; });
    for (int m = 0; m < kQ; ++m) out(m, post[m]);
  }

  // The two-level pull's chunk through staged_chunk: at is the state index of node x0.
  template <typename Node>
  LBL_FORCEINLINE void converted_chunk(const Store* __restrict src, Store* __restrict out, long long at, int x0,
                                       Node&& node) const {
    const long long stride = static_cast<long long>(stride_);
    staged_chunk(
        x0, x0 + kLine - 1,
        [&](int m, Real* stage) LBL_INLINE_LAMBDA { halves_to_reals<kLine>(src + at - shift(m) + m * stride, stage); },
        [&](int m, const Real* post) LBL_INLINE_LAMBDA { reals_to_halves<kLine>(post, out + m * stride); }, node);
  }

  // Gathers f for node x of the row whose state starts at `row` (in the source level).
  LBL_FORCEINLINE void gather_row(const Store* __restrict src, long long row, int x, Real (&f)[kQ]) const {
    const long long stride = static_cast<long long>(stride_), pitch = pitch_, plane = plane_;
    LBL_UNROLL
    for (int m = 0; m < kQ; ++m)
      f[m] = static_cast<Real>(src[m * stride + row + x - d3q19::cx(m) - d3q19::cy(m) * pitch - d3q19::cz(m) * plane]);
  }

  // The node function of a medium-free row or chunk: the collision is the identity (rho = 0
  // gives f~ exactly), only the f_0 treatment and the streaming remain.
  static auto stream_node(Real keep) {
    return [keep](int x, auto&& load, auto&& sink) LBL_INLINE_LAMBDA {
      Real f[kQ];
      load(x, f);
      f[0] *= keep;
      LBL_UNROLL
      for (int m = 0; m < kQ; ++m) sink(m, f[m]);
    };
  }

  // The collision's two forms (collide.h) as callables, chosen once per row: a branch per node
  // stops the vectoriser.
  template <typename Body>
  static void with_form(bool cubic, Body&& body) {
    if (cubic)
      body([](const CollisionOp<Real>& op, Real keep, Real rho, const Real(&f)[kQ], auto&& store)
               LBL_INLINE_LAMBDA { collide_cubic(op, keep, rho, f, store); });
    else
      body([](const CollisionOp<Real>& op, Real keep, Real rho, const Real(&f)[kQ], auto&& store)
               LBL_INLINE_LAMBDA { collide_pairs(op, keep, rho, f, store); });
  }

  // Row with no medium: collision is the identity, only streaming remains.
  template <bool kStream, Access A>
  void stream_row(const Store* __restrict src, Store* __restrict dst, int y, int z, Span span, Real keep) const {
    run<kStream, A>(src, dst, y, z, span, [&](int, auto&& body) LBL_INLINE_LAMBDA { body(stream_node(keep)); });
  }

  // Row of one material: its medium-free chunks only stream.
  template <bool kStream, Access A>
  void uniform_row(const Store* __restrict src, Store* __restrict dst, int y, int z, Span span,
                   const CollisionOp<Real>& op, Real keep) const {
    const float* __restrict rho = density_.data() + d_.index(0, y, z);
    const std::uint8_t* chunk = chunk_classes(y, z);
    with_form(op.is_cubic, [&](auto&& collide) LBL_INLINE_LAMBDA {
      const auto dark = stream_node(keep);
      const auto lit = [&](int x, auto&& load, auto&& sink) LBL_INLINE_LAMBDA {
        Real f[kQ];
        load(x, f);
        collide(op, keep, static_cast<Real>(rho[x]), f, sink);
      };
      run<kStream, A>(src, dst, y, z, span, [&](int c, auto&& body) LBL_INLINE_LAMBDA {
        if (chunk[c] == kEmptyChunk) body(dark);
        else body(lit);
      });
    });
  }

  // Rows where materials mix (wood among leaves): one SIMD loop still, as a sum of collisions,
  //   post = C_medium(f, rho (1 - w)) + C_wood(f, rho w) - f~,   w = 1 on wood nodes, else 0,
  // each term exact where it does not apply (rho 0 gives f~ exactly), with the node's own f_0
  // treatment. (A GPU simply picks the node's operator; this form is what GCC vectorises:
  // operator selection, integer compares and byte loads in the loop all stop it.) Chunks without
  // wood run the medium's collision alone and chunks without medium only stream: the terms they
  // leave out are exact zeros there, so the values are the same.
  template <bool kStream, Access A>
  void mixed_row(const Store* __restrict src, Store* __restrict dst, int y, int z, Span span,
                 const std::array<CollisionOp<Real>, kMaxMaterials>& ops, unsigned absorb_bits) const {
    const std::size_t base = d_.index(0, y, z);
    const float* __restrict density = density_.data() + base;
    const float* __restrict wood = wood_.data() + base;
    const std::uint8_t* chunk = chunk_classes(y, z);
    const Real keep0 = f0_keep<Real>(absorb_bits, kMaterialMedium);
    const Real keep1 = f0_keep<Real>(absorb_bits, kMaterialWood);
    const CollisionOp<Real>& medium = ops[kMaterialMedium];
    const CollisionOp<Real>& woody = ops[kMaterialWood];
    with_form(medium.is_cubic && woody.is_cubic, [&](auto&& collide) LBL_INLINE_LAMBDA {
      const auto dark = stream_node(keep0);
      const auto plain = [&](int x, auto&& load, auto&& sink) LBL_INLINE_LAMBDA {
        Real f[kQ];
        load(x, f);
        collide(medium, keep0, static_cast<Real>(density[x]), f, sink);
      };
      const auto mixed = [&](int x, auto&& load, auto&& sink) LBL_INLINE_LAMBDA {
        Real f[kQ];
        load(x, f);
        const Real w = static_cast<Real>(wood[x]);
        const Real rho = static_cast<Real>(density[x]);
        const Real keep = keep0 + (keep1 - keep0) * w;
        const Real f0t = f[0] * keep;
        Real acc[kQ];
        collide(medium, keep, rho * (Real(1) - w), f, [&](int m, Real v) LBL_INLINE_LAMBDA { acc[m] = v; });
        collide(woody, keep, rho * w, f,
                [&](int m, Real v) LBL_INLINE_LAMBDA { acc[m] += v - (m == 0 ? f0t : f[m]); });
        LBL_UNROLL
        for (int m = 0; m < kQ; ++m) sink(m, acc[m]);
      };
      run<kStream, A>(src, dst, y, z, span, [&](int c, auto&& body) LBL_INLINE_LAMBDA {
        if (chunk[c] == kEmptyChunk) body(dark);
        else if (chunk[c] == kPlainChunk) body(plain);
        else body(mixed);
      });
    });
  }

  Dims d_;
  std::size_t n_;
  int capacity_;
  int threads_;
  StoreMode stores_;
  bool flush_denormals_;
  std::vector<float> density_;
  std::vector<std::uint8_t> material_;
  std::vector<float> wood_;  // 1 on wood nodes: the mixed-row kernel's material as a number
  int material_count_ = 1;
  std::vector<std::array<CollisionOp<Real>, kMaxMaterials>> ops_;  // per channel and material
  std::vector<unsigned> absorb_bits_;     // per channel: bit k set when material k absorbs
  std::size_t busy_chunks_ = 0;             // chunks that hold medium (classify_rows)
  std::vector<long long> ahead_;           // per chunk: see classify_rows
  std::vector<bool> plain_totals_;        // per channel: every material's total_gain is 0
  std::vector<std::uint8_t> row_mask_, row_empty_;
  std::vector<std::uint8_t> chunk_class_;  // per interior row, chunks_per_row_ entries (classify_rows)
  int chunks_per_row_ = 1;
  long long pitch_ = 0, plane_ = 0;       // padded row and plane lengths of the state
  std::size_t stride_ = 0;                // elements between direction arrays
  std::vector<Slot> slots_;
  std::vector<AlignedBuffer<Store>> vectors_;  // Krylov vectors
  int active_ = 0;
  long long now_ = 0;  // steps since reset
  int cur_ = 0;        // level holding g(now - 1): f(now) = gather from it
  bool stream_ = false;
  int time_block_option_ = 0;
  bool skip_dark_ = true;  // SolverOptions::skip_dark
  int time_block_ = 1;  // steps per pass over the lattice (wavefront); from the option at reset
  bool in_place_ = false;  // one level, AA pattern (StateLayout::InPlace)
  // Streaming by position (see shift_offsets): chosen at reset for sparse lattices, left for
  // the two-level pull at the first operation that needs the natural layout (unshift).
  bool shift_option_ = true;  // SolverOptions::shift_streaming
  bool sparse_ = false;       // fewer than 3/4 of the chunks hold medium (classify_rows)
  bool shifted_ = false;
  long long offset_[kQ] = {};  // position offsets of f(now_) (shift_offsets)
  struct EdgeRun {
    int m;           // direction
    long long q;     // state index of the first entry
    int length = 1;  // entries f_m(q), f_m(q + 1), ...
  };
  std::vector<EdgeRun> shift_edges_;  // the entries f_m(q) fed by a boundary node
  bool swapped_ = false;   // in place: the last step was a swap-out step (odd steps since reset)
  std::vector<Edge> edges_in_, edges_out_;
};

}  // namespace lblight::openmp
