// The CPU solver, one translation unit per precision (the sweep is compiled three times over;
// apart, the three build side by side and a change to the backend's planning rebuilds none).
#pragma once

#include <memory>
#include <vector>

#include "lblight/backend/backend.h"

namespace lblight::openmp {

using SolverFactory = std::unique_ptr<LatticeSolver>(const LatticeGeometry& g,
                                                     const std::vector<ChannelMaterials>& channels, int capacity,
                                                     int threads, const SolverOptions& options);
SolverFactory make_solver_float32;  // solver_float32.cpp
SolverFactory make_solver_float64;  // solver_float64.cpp
SolverFactory make_solver_float16;  // solver_float16.cpp: float arithmetic, _Float16 storage (kHasFloat16)

}  // namespace lblight::openmp
