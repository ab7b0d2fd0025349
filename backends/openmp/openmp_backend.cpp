// OpenMP backend: what the planner asks of the CPU (precisions, memory, cache, copy bandwidth) and
// the factory of its solver. The sweep itself is backends/openmp/cpu_lattice_solver.h, built once
// per precision (solver_float32.cpp, solver_float64.cpp, solver_float16.cpp).
#include "backends/openmp/openmp_backend.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <string>

#include "backends/openmp/chunks.h"
#include "backends/openmp/cpu_solvers.h"
#include "backends/openmp/simd.h"
#include "lblight/core/aligned_buffer.h"
#include "lblight/core/error.h"
#include "lblight/core/system_info.h"
#include "lblight/lattice/d3q19.h"

namespace lblight {
namespace {

using d3q19::kQ;

class OpenMpBackend final : public Backend {
 public:
  explicit OpenMpBackend(int threads) { threads_ = threads > 0 ? threads : omp_get_max_threads(); }
  std::string name() const override { return "cpu"; }
  std::string description() const override {
    return "OpenMP, " + std::to_string(threads_) + " thread" + (threads_ == 1 ? "" : "s") + ", " + host_cpu_model();
  }
  bool supports(Precision p) const override { return p != Precision::Float16 || openmp::kHasFloat16; }
  bool occupies_host_cores() const override { return true; }
  std::size_t bytes_per_system(const Dims& d, Precision p) const override {
    const std::size_t v = static_cast<std::size_t>(bytes_per_value(p)), totals = p == Precision::Float64 ? 8 : 4;
    const std::size_t padded = static_cast<std::size_t>(d.nx + 64) * static_cast<std::size_t>(d.ny) *
                               static_cast<std::size_t>(d.nz);
    return 2 * kQ * padded * v + 2 * d.count() * totals;
  }
  // One level, plus the surface lists of the boundary entries (two per node of the faces, about).
  std::size_t bytes_per_system_in_place(const Dims& d, Precision p) const override {
    const std::size_t surface = 2 * (static_cast<std::size_t>(d.nx) * d.ny + static_cast<std::size_t>(d.ny) * d.nz +
                                     static_cast<std::size_t>(d.nx) * d.nz);
    const std::size_t two = bytes_per_system(d, p), level = (two - 2 * d.count() * (p == Precision::Float64 ? 8 : 4)) / 2;
    return two - level + surface * 10 * sizeof(std::size_t);
  }
  // Measured in docs/performance.md ("In-place streaming"): once two levels exceed the cache, in
  // place ran 1.1-1.6x faster than two levels with temporal blocking in float32 (the stores land
  // on lines the same node just read); float16 ran slower in place (its conversions by chunk).
  // Not where the lattice is sparse: streaming by position (two-level layout) beats both there
  // (plant-128: 3x the in-place rate), unless the solve rewrites the state, which leaves it.
  bool prefers_in_place(const LatticeGeometry& g, Precision p, bool rewrites_state) const override {
    const double cache = static_cast<double>(host_last_level_cache_bytes());
    if (p == Precision::Float16 || cache <= 0 || static_cast<double>(bytes_per_system(g.dims, p)) <= 2.0 * cache)
      return false;
    return rewrites_state || !openmp::position_streaming_pays(g, 64 / bytes_per_value(p));
  }
  std::size_t bytes_per_lattice(const Dims& d) const override { return d.count() * (sizeof(float) + 1); }
  std::size_t available_bytes() const override { return host_memory_limit().bytes; }
  std::size_t cache_bytes() const override { return host_last_level_cache_bytes(); }
  int preferred_batch(const Dims&, Precision, int total_systems) const override { return std::min(total_systems, 3); }

  std::unique_ptr<LatticeSolver> create(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels,
                                        const SolverOptions& options) const override {
    const int capacity = options.max_systems > 0 ? options.max_systems : 3;
    switch (options.precision) {
      case Precision::Float32: return openmp::make_solver_float32(g, channels, capacity, threads_, options);
      case Precision::Float64: return openmp::make_solver_float64(g, channels, capacity, threads_, options);
      case Precision::Float16:
        if (openmp::kHasFloat16) return openmp::make_solver_float16(g, channels, capacity, threads_, options);
        [[fallthrough]];
      default:
        throw Error(ErrorCategory::Unavailable, "the cpu backend stores float32 or float64" +
                                                    std::string(openmp::kHasFloat16 ? " or float16" : "") + ", not " +
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
      // Each thread copies its share with memcpy: the C library picks its fastest method
      // (non-temporal stores for large blocks), so this is the best copy the machine offers.
#pragma omp parallel num_threads(threads_)
      {
        const int t = omp_get_thread_num(), nt = omp_get_num_threads();
        const std::size_t lo = n * static_cast<std::size_t>(t) / static_cast<std::size_t>(nt);
        const std::size_t hi = n * static_cast<std::size_t>(t + 1) / static_cast<std::size_t>(nt);
        std::memcpy(dst + lo, src + lo, (hi - lo) * sizeof(float));
      }
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
