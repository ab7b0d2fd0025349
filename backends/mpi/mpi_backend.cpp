#include "backends/mpi/mpi_backend.h"

#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "backends/openmp/openmp_backend.h"
#include "lblight/backend/node_rules.h"
#include "lblight/core/error.h"

namespace lblight {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void check(int rc, const char* what) {
  if (rc != MPI_SUCCESS) throw Error(ErrorCategory::Internal, std::string("MPI: ") + what + " failed");
}

int world_rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}
int world_size() {
  int n = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &n);
  return n;
}

// This rank's part of the lattice: layers first - 1 .. last + 1 of the whole (its ghosts or the
// lattice's own boundary layers at both ends). Ghost layers are boundary nodes to the CPU solver:
// density 0 there, as it requires; their light comes from the neighbours.
LatticeGeometry slab_geometry(const LatticeGeometry& g, SlabRange s) {
  const Dims& d = g.dims;
  LatticeGeometry out;
  out.dims = {d.nx, d.ny, s.last - s.first + 3};
  out.material_count = g.material_count;
  const std::size_t layer = static_cast<std::size_t>(d.nx) * d.ny;
  const std::size_t from = static_cast<std::size_t>(s.first - 1) * layer, count = out.dims.count();
  out.density.assign(g.density.begin() + static_cast<std::ptrdiff_t>(from),
                     g.density.begin() + static_cast<std::ptrdiff_t>(from + count));
  out.material.assign(g.material.begin() + static_cast<std::ptrdiff_t>(from),
                      g.material.begin() + static_cast<std::ptrdiff_t>(from + count));
  std::fill(out.density.begin(), out.density.begin() + static_cast<std::ptrdiff_t>(layer), 0.0f);
  std::fill(out.density.end() - static_cast<std::ptrdiff_t>(layer), out.density.end(), 0.0f);
  std::fill(out.material.begin(), out.material.begin() + static_cast<std::ptrdiff_t>(layer), std::uint8_t{0});
  std::fill(out.material.end() - static_cast<std::ptrdiff_t>(layer), out.material.end(), std::uint8_t{0});
  return out;
}

class MpiSlabSolver final : public LatticeSolver {
 public:
  MpiSlabSolver(std::unique_ptr<LatticeSolver> inner, const Dims& whole, SlabRange slab, int rank, int ranks)
      : inner_(std::move(inner)), halo_(dynamic_cast<SlabHalo*>(inner_.get())), whole_(whole), slab_(slab),
        rank_(rank), ranks_(ranks), local_{whole.nx, whole.ny, slab.last - slab.first + 3} {
    if (!halo_) throw std::logic_error("MPI backend: the CPU solver offers no layer exchange");
    layer_ = SlabHalo::layer_values(local_);
    up_ = rank_ + 1 < ranks_ ? rank_ + 1 : -1;
    down_ = rank_ > 0 ? rank_ - 1 : -1;
  }
  ~MpiSlabSolver() override {
    if (rank_ == 0 && steps_ > 0)
      spdlog::info("MPI: {} rank(s), {} steps: stepping {:.3g} s, halo exchange {:.3g} s ({:.0f}% of the two: packing, "
                   "storing and the wait left after the inner layers' sweep; {} bytes per step and system each way)",
                   ranks_, steps_, step_seconds_, halo_seconds_,
                   100.0 * halo_seconds_ / std::max(1e-12, step_seconds_ + halo_seconds_), layer_ * sizeof(double));
  }

  int capacity() const override { return inner_->capacity(); }

  void reset(const std::vector<SystemSpec>& batch) override {
    inner_->reset(batch);
    active_ = static_cast<int>(batch.size());
    // Ghost layers start as the interior does: dark (the solver set them to the boundary values).
    const std::vector<double> zeros(layer_, 0.0);
    for (int s = 0; s < active_; ++s) {
      if (rank_ > 0) halo_->write_layer(s, 0, +1, zeros.data());
      if (rank_ + 1 < ranks_) halo_->write_layer(s, local_.nz - 1, -1, zeros.data());
    }
    ghosts_current_ = true;
  }

  // Each step: the edge layers leave for the neighbours while the slab's inner layers are swept;
  // then the ghosts arrive and the two edge layers are swept (bit for bit the whole step).
  void step(int steps) override {
    for (int t = 0; t < steps; ++t, ++steps_) {
      auto t0 = std::chrono::steady_clock::now();
      if (ranks_ == 1) {
        inner_->step(1);
        step_seconds_ += seconds_since(t0);
        continue;
      }
      const bool exchange = !ghosts_current_;  // measure() may have brought them already
      if (exchange) begin_exchange();
      halo_seconds_ += seconds_since(t0);
      t0 = std::chrono::steady_clock::now();
      const int top = local_.nz - 2;
      if (top - 1 >= 2) halo_->step_layers(2, top - 1);
      step_seconds_ += seconds_since(t0);
      t0 = std::chrono::steady_clock::now();
      if (exchange) finish_exchange();
      halo_seconds_ += seconds_since(t0);
      t0 = std::chrono::steady_clock::now();
      halo_->step_layers(1, 1);
      if (top > 1) halo_->step_layers(top, top);
      halo_->end_step();
      ghosts_current_ = false;
      step_seconds_ += seconds_since(t0);
    }
  }

  // Every rank gathers every layer's sums and combines them in z order, as one CPU solver does
  // for the whole lattice: the same residuals, bit for bit, for any number of ranks.
  void measure(std::vector<Residual>& out) override {
    if (!ghosts_current_) {  // the edge layers' totals take light from the ghosts
      const auto t0 = std::chrono::steady_clock::now();
      begin_exchange();
      finish_exchange();
      halo_seconds_ += seconds_since(t0);
    }
    std::vector<Residual> local;
    inner_->measure(local);
    const int layers = slab_.last - slab_.first + 1, all_layers = whole_.nz - 2;
    std::vector<int> counts(static_cast<std::size_t>(ranks_)), offsets(static_cast<std::size_t>(ranks_));
    for (int k = 0; k < ranks_; ++k) {
      const SlabRange s = slab_range(whole_.nz, ranks_, k);
      counts[static_cast<std::size_t>(k)] = (s.last - s.first + 1) * kReduceSlots;
      offsets[static_cast<std::size_t>(k)] = (s.first - 1) * kReduceSlots;
    }
    std::vector<double> all(static_cast<std::size_t>(all_layers) * kReduceSlots);
    out.assign(local.size(), Residual{});
    for (std::size_t s = 0; s < local.size(); ++s) {
      check(MPI_Allgatherv(halo_->layer_sums(static_cast<int>(s)), layers * kReduceSlots, MPI_DOUBLE, all.data(),
                           counts.data(), offsets.data(), MPI_DOUBLE, MPI_COMM_WORLD),
            "gathering the residuals");
      double sums[kReduceSlots] = {};
      for (int z = 0; z < all_layers; ++z) combine(sums, all.data() + static_cast<std::size_t>(z) * kReduceSlots);
      out[s] = to_residual(sums);
    }
  }

  // Every rank gets the whole lattice's totals: its slab's layers, the lowest rank adding the
  // bottom boundary layer and the highest the top one.
  void read_totals(int system, float* out) const override {
    std::vector<float> local(local_.count());
    inner_->read_totals(system, local.data());
    const int layer = whole_.nx * whole_.ny;
    const int lo = rank_ == 0 ? 0 : 1, hi = rank_ + 1 == ranks_ ? local_.nz - 1 : local_.nz - 2;
    std::vector<int> counts(static_cast<std::size_t>(ranks_)), offsets(static_cast<std::size_t>(ranks_));
    for (int k = 0; k < ranks_; ++k) {
      const SlabRange s = slab_range(whole_.nz, ranks_, k);
      const int first = k == 0 ? 0 : s.first, last = k + 1 == ranks_ ? whole_.nz - 1 : s.last;
      counts[static_cast<std::size_t>(k)] = (last - first + 1) * layer;
      offsets[static_cast<std::size_t>(k)] = first * layer;
    }
    check(MPI_Allgatherv(local.data() + static_cast<std::size_t>(lo) * layer, (hi - lo + 1) * layer, MPI_FLOAT, out,
                         counts.data(), offsets.data(), MPI_FLOAT, MPI_COMM_WORLD),
          "gathering the totals");
  }

  std::size_t bytes_in_use() const override { return inner_->bytes_in_use(); }

 private:
  // The 5 directions crossing each face, all systems in one message per neighbour, non-blocking.
  void begin_exchange() {
    const std::size_t n = layer_ * static_cast<std::size_t>(active_);
    send_up_.resize(n), send_down_.resize(n), recv_up_.resize(n), recv_down_.resize(n);
    requests_ = 0;
    if (ranks_ == 1) return;
    if (up_ >= 0) {
      for (int s = 0; s < active_; ++s) halo_->read_layer(s, local_.nz - 2, +1, send_up_.data() + s * layer_);
      check(MPI_Irecv(recv_up_.data(), static_cast<int>(n), MPI_DOUBLE, up_, 1, MPI_COMM_WORLD, &req_[requests_++]),
            "receive");
      check(MPI_Isend(send_up_.data(), static_cast<int>(n), MPI_DOUBLE, up_, 0, MPI_COMM_WORLD, &req_[requests_++]),
            "send");
    }
    if (down_ >= 0) {
      for (int s = 0; s < active_; ++s) halo_->read_layer(s, 1, -1, send_down_.data() + s * layer_);
      check(MPI_Irecv(recv_down_.data(), static_cast<int>(n), MPI_DOUBLE, down_, 0, MPI_COMM_WORLD, &req_[requests_++]),
            "receive");
      check(MPI_Isend(send_down_.data(), static_cast<int>(n), MPI_DOUBLE, down_, 1, MPI_COMM_WORLD, &req_[requests_++]),
            "send");
    }
  }
  // Waits for the ghosts (the time left after the inner layers' sweep) and stores them.
  void finish_exchange() {
    check(MPI_Waitall(requests_, req_, MPI_STATUSES_IGNORE), "halo exchange");
    ghosts_current_ = true;
    for (int s = 0; s < active_; ++s) {
      if (up_ >= 0) halo_->write_layer(s, local_.nz - 1, -1, recv_up_.data() + s * layer_);
      if (down_ >= 0) halo_->write_layer(s, 0, +1, recv_down_.data() + s * layer_);
    }
  }

  std::unique_ptr<LatticeSolver> inner_;
  SlabHalo* halo_;
  Dims whole_;
  SlabRange slab_;
  int rank_, ranks_;
  Dims local_;
  std::size_t layer_ = 0;
  int active_ = 0;
  long long steps_ = 0;
  double step_seconds_ = 0, halo_seconds_ = 0;
  int up_ = -1, down_ = -1;  // neighbour ranks, -1 at the lattice's ends
  bool ghosts_current_ = true;  // the ghosts hold the neighbours' current level
  std::vector<double> send_up_, send_down_, recv_up_, recv_down_;
  MPI_Request req_[4];
  int requests_ = 0;
};

class MpiBackend final : public Backend {
 public:
  explicit MpiBackend(int threads) : cpu_(make_openmp_backend(threads)), rank_(world_rank()), ranks_(world_size()) {}

  std::string name() const override { return "mpi"; }
  std::string description() const override {
    return "MPI, " + std::to_string(ranks_) + " rank(s) of " + cpu_->description() + ", the lattice in slabs along z";
  }
  bool supports(Precision p) const override { return cpu_->supports(p); }
  bool occupies_host_cores() const override { return true; }
  bool writes_output() const override { return rank_ == 0; }
  std::size_t bytes_per_system(const Dims& d, Precision p) const override { return cpu_->bytes_per_system(slab(d), p); }
  std::size_t bytes_per_lattice(const Dims& d) const override { return cpu_->bytes_per_lattice(slab(d)); }
  std::size_t available_bytes() const override { return cpu_->available_bytes(); }
  std::size_t cache_bytes() const override { return cpu_->cache_bytes(); }
  int preferred_batch(const Dims& d, Precision p, int total) const override { return cpu_->preferred_batch(d, p, total); }
  double measure_copy_bandwidth(std::size_t bytes) const override { return cpu_->measure_copy_bandwidth(bytes); }

  std::unique_ptr<LatticeSolver> create(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels,
                                        const SolverOptions& options) const override {
    check_geometry(g, "mpi");
    if (options.layout == StateLayout::InPlace)
      throw Error(ErrorCategory::Unavailable, "--backend mpi keeps two levels of lattice state; use state two-levels or auto");
    if (g.dims.nz - 2 < ranks_)
      throw Error(ErrorCategory::InvalidInput, "--backend mpi: " + std::to_string(ranks_) + " ranks for a lattice of " +
                                                   std::to_string(g.dims.nz - 2) +
                                                   " interior layers; each rank needs at least one (run fewer ranks)");
    const SlabRange s = slab_range(g.dims.nz, ranks_, rank_);
    SolverOptions slab = options;
    slab.shift_streaming = false;  // the halo exchange reads and writes layers in the natural layout
    return std::make_unique<MpiSlabSolver>(cpu_->create(slab_geometry(g, s), channels, slab), g.dims, s, rank_,
                                           ranks_);
  }

 private:
  // The largest slab any rank holds, with its two ghost layers.
  Dims slab(const Dims& d) const {
    if (d.nz - 2 < ranks_) return d;
    const SlabRange s = slab_range(d.nz, ranks_, 0);
    return {d.nx, d.ny, s.last - s.first + 3};
  }
  std::unique_ptr<Backend> cpu_;
  int rank_, ranks_;
};

void finalize_mpi() {
  int done = 0;
  MPI_Finalized(&done);
  if (!done) MPI_Finalize();
}

}  // namespace

std::unique_ptr<Backend> make_mpi_backend(int threads) {
  int initialized = 0;
  MPI_Initialized(&initialized);
  if (!initialized) {
    int provided = 0;
    // SERIALIZED: a bake may start the backend on one thread and step it on another
    if (MPI_Init_thread(nullptr, nullptr, MPI_THREAD_SERIALIZED, &provided) != MPI_SUCCESS)
      throw Error(ErrorCategory::Unavailable, "--backend mpi: MPI_Init failed");
    std::atexit(finalize_mpi);
  }
  return std::make_unique<MpiBackend>(threads);
}

}  // namespace lblight
