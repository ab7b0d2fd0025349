// The CPU sweep in float16 (backends/openmp/cpu_solvers.h).
#include "backends/openmp/cpu_lattice_solver.h"
#include "backends/openmp/cpu_solvers.h"

namespace lblight::openmp {

std::unique_ptr<LatticeSolver> make_solver_float16(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels,
                                                 int capacity, int threads, const SolverOptions& options) {
#if LBLIGHT_CPU_FLOAT16
  return std::make_unique<CpuLatticeSolver<float, _Float16>>(g, channels, capacity, threads, options);
#else
  (void)g, (void)channels, (void)capacity, (void)threads, (void)options;
  throw Error(ErrorCategory::Unavailable, "this compiler has no _Float16: the cpu backend stores float32 or float64");
#endif
}

}  // namespace lblight::openmp
