// The CPU sweep in float64 (backends/openmp/cpu_solvers.h).
#include "backends/openmp/cpu_lattice_solver.h"
#include "backends/openmp/cpu_solvers.h"

namespace lblight::openmp {

std::unique_ptr<LatticeSolver> make_solver_float64(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels,
                                                 int capacity, int threads, const SolverOptions& options) {
  return std::make_unique<CpuLatticeSolver<double>>(g, channels, capacity, threads, options);
}

}  // namespace lblight::openmp
