// The rules of docs/model.md sec. 6 that need a loaded grid: finite densities in [0, 1] after the
// scene's density_scale, and rho * sigma_t < 2 everywhere (the LB diffusion coefficient of
// [Geist2010] eq. (4) must stay positive). Violations throw Error(InvalidInput); soft problems become
// warnings.
#pragma once

#include <string>
#include <vector>

#include "lblight/lattice/dense_grid.h"
#include "lblight/scene/scene.h"

namespace lblight {

struct GridStats {
  float max_density[2] = {0, 0};                 // per material index (medium, wood)
  std::size_t max_index[2] = {0, 0};             // where that maximum sits
  std::size_t occupied = 0, wood = 0;
};

// Density values: finite and in [0, 1]. `source` names the file/grid for messages.
void check_density_values(const ModelSpec& model, const ModelGrid& grid, const Scene& scene);

// Stability: rho * sigma_t < 2 for every material and channel; warns when 1 + rho Omega_mm < 0.
GridStats check_stability(const ModelSpec& model, const ModelGrid& grid, const Scene& scene,
                          std::vector<std::string>& warnings);

std::string voxel_string(const ModelGrid& grid, std::size_t index);

}  // namespace lblight
