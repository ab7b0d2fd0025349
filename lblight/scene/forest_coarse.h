// The coarse forest grid ([Steele2009] sec. 4.3, docs/forest.md sec. 2): one lattice over the
// whole forest whose nodes are cells of `cell_size` world units, each holding the optical depth
// of the instances' fine voxels that fall into it; and the same coarse grid of each model standing
// alone, so relighting can scale an instance's own light by (forest's coarse light / its alone
// coarse light) without counting its self-shadowing twice.
#pragma once

#include <string>
#include <vector>

#include "lblight/core/error.h"
#include "lblight/lattice/dense_grid.h"
#include "lblight/scene/forest.h"
#include "lblight/scene/scene.h"

namespace lblight {

// A model the forest places: its scene entry and its (fine) density grid.
struct ForestModel {
  const ModelSpec* spec = nullptr;
  const ModelGrid* grid = nullptr;
};

// A coarse lattice's density grid and its material (optical depth per cell = density x sigma_t).
struct CoarseGrid {
  ModelGrid grid;  // node (i, j, k) is the cell centred at cell_size (i, j, k) (world or model frame)
  Material medium, wood;  // wood = medium: every cell has the one coarse material
  double max_optical_depth = 0;  // largest rho sigma_t of a cell (channel mean), before clamping
  std::size_t clamped_cells = 0;  // cells whose optical depth was clamped to kMaxCoarseOpticalDepth
};

struct CoarseForest {
  double cell_size = 0;
  CoarseGrid forest;              // world frame
  std::vector<CoarseGrid> alone;  // per model (the order given): the instance at yaw 0, scale 1, origin 0
};

// The largest optical depth per coarse cell: below the stability bound rho sigma_t < 2
// (docs/model.md sec. 6) with room for the coarse material's per-channel spread.
inline constexpr double kMaxCoarseOpticalDepth = 1.0;

// Default cell edge: this many of the coarsest model voxel (times the largest instance scale).
inline constexpr double kDefaultCoarseCellVoxels = 2.0;

double default_coarse_cell_size(const std::vector<ForestModel>& models, const std::vector<ForestInstance>& instances);

// Each fine voxel of every instance adds its optical depth per fine length, rho sigma_t, times
// (its world edge / cell_size)^2 to the cell holding its centre: a cell's density x sigma_t is
// then the mean extinction over its volume times its edge, so optical depth along any path is
// kept. The coarse material carries the extinction-weighted albedo and g of the leaf and wood
// voxels, and f_0 dumping when most of the extinction does. A cell deeper than
// kMaxCoarseOpticalDepth is clamped to it (counted in clamped_cells). Error(InvalidInput) at
// `where` when the grid's index box or memory would not fit.
CoarseForest build_coarse_forest(const std::vector<ForestModel>& models, const std::vector<ForestInstance>& instances,
                                 double cell_size, const Location& where);

// The model called `name` (Error(Internal) when there is none: names are checked at parse time).
const ForestModel& forest_model(const std::vector<ForestModel>& models, const std::string& name);

}  // namespace lblight
