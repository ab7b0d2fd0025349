// Relighting a baked forest into one world-space volume (`lblight relight` on a forest bake,
// docs/forest.md): each instance's own light from its model's base solutions (the sun turned into
// the instance's frame, weights as [Steele2009] sec. 4.2 per instance), scaled per voxel by the
// coarse factor (forest's coarse light / the model's alone coarse light, [Steele2009] sec. 4.3),
// resampled onto a world grid and written sparse: light active on the occupied voxels and their
// neighbours, with the matching world density (and brown) grids.
#pragma once

#include <array>
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "lblight/core/run_context.h"
#include "lblight/pipeline/relight.h"

namespace lblight {

struct ForestRelightRequest {
  RelightRequest sun;                  // in world space
  bool coarse = true;                  // scale by the coarse factors (needs a bake with forest.vdb)
  double voxel_size = 0;               // world voxel edge; 0 = the finest instance voxel
  std::optional<std::size_t> instance; // only this instance (0-based, the manifest's order)
};

struct InstanceRelight {
  std::string model;
  std::vector<std::pair<int, double>> weights;  // in the model's frame
  std::array<double, 3> mean_factor{1, 1, 1};   // density-weighted over its voxels
  std::size_t voxels = 0;                       // world voxels it lit
};

struct ForestRelightResult {
  double voxel_size = 0;
  std::size_t instances = 0, active_voxels = 0, bricks = 0;
  bool coarse = false;
  std::vector<std::pair<int, double>> forest_weights;  // the coarse forest grid's (world frame)
  std::vector<InstanceRelight> per_instance;           // per relit instance, in order
  double read_seconds = 0, relight_seconds = 0, write_seconds = 0;
};

// The smallest light a coarse factor divides by, as a fraction of the open-air light of the sun and
// ambient (intensity + 18 ambient + 9 sky): deep inside both coarse solutions the ratio is noise.
inline constexpr double kCoarseFactorFloor = 1e-3;

// Reads the bake folder (its manifest's forest section and the .vdb files it names), relights and
// writes `output` (atomically). `file_metadata` is added to the .vdb's own. Error(InvalidInput)
// naming the folder when it holds no forest, when coarse factors are asked of a bake without
// forest.vdb, or when a base solution an instance needs was left out.
ForestRelightResult relight_forest(const std::filesystem::path& bake, const ForestRelightRequest& request,
                                   const std::filesystem::path& output, const nlohmann::json& file_metadata,
                                   const RunContext& ctx = {});

}  // namespace lblight
