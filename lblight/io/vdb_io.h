// Every .vdb is read once in a child process before it is read here (a corrupt file that crashes
// or hangs OpenVDB becomes an input error); ctx.cancel stops that wait.
// Everything that touches OpenVDB lives behind this header (one translation unit compiles
// openvdb.h, which is slow to build and does not compile under nvcc).
#pragma once

#include <array>
#include <bitset>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lblight/core/error.h"
#include "lblight/core/run_context.h"
#include "lblight/lattice/dense_grid.h"

namespace lblight {

// Reads the float grid `density_grid` of `file` (and the optional `wood_grid`: voxels > 0.5 are
// wood) into a dense ModelGrid over the density grid's active bounding box. Throws
// Error(InvalidInput) naming file and grid.
ModelGrid read_vdb_density(const std::filesystem::path& file, const std::string& density_grid,
                           const std::string& wood_grid, const Location& where, const RunContext& ctx = {});

// One grid to write: a float grid (scalar) or a Vec3f grid (rgb), over a dense lattice.
struct DenseGridOut {
  std::string name;
  const std::vector<float>* scalar = nullptr;
  const std::array<std::vector<float>, 3>* rgb = nullptr;
  bool fog_volume = false;                      // GRID_FOG_VOLUME class (density)
  nlohmann::json metadata = nlohmann::json::object();  // int, float, bool, string, [3 ints] values
  bool half = false;                            // stored as 16-bit floats
};

// The largest |half(v) - v| over the values, relative to the largest |v| (0 for all zeros): what
// storing them as OpenVDB's 16-bit floats costs.
double half_rounding_error(const std::array<std::vector<float>, 3>& rgb);

// Writes the grids to `file` (which should be a staging path; see output_dir.h).
void write_vdb(const std::filesystem::path& file, const DenseFrame& frame, const std::vector<DenseGridOut>& grids,
               const nlohmann::json& file_metadata);

// A sparse world-space volume in bricks of 8^3 voxels (OpenVDB's leaf size), for volumes too
// large to hold densely (a whole forest's light). Voxel (x, y, z) of a brick, x fastest, is index
// coordinate origin + (x, y, z); index coordinate (i, j, k) sits at voxel_size (i, j, k).
inline constexpr int kBrickEdge = 8;
inline constexpr int kBrickVoxels = kBrickEdge * kBrickEdge * kBrickEdge;
struct VolumeBrick {
  std::array<int, 3> origin{};                      // multiples of kBrickEdge
  std::array<float, kBrickVoxels> density{};        // written as fog volume 'density' (active where > 0)
  std::array<std::array<float, kBrickVoxels>, 3> light{};  // Vec3f 'light' (active where `active`)
  std::array<float, kBrickVoxels> wood{};           // float 'brown': 1 where wood, active there
  std::bitset<kBrickVoxels> active;
};
struct BrickVolumeOut {
  double voxel_size = 1;
  std::vector<const VolumeBrick*> bricks;  // distinct origins
  bool with_wood = false;
  nlohmann::json light_metadata = nlohmann::json::object(), density_metadata = nlohmann::json::object();
};
void write_brick_vdb(const std::filesystem::path& file, const BrickVolumeOut& volume, const nlohmann::json& file_metadata);

// A grid read back densely over a frame (tests, compression): float grids fill channel 0.
struct DenseGridIn {
  std::string name, type;
  DenseFrame frame;
  std::array<std::vector<float>, 3> values;  // 1 or 3 channels used
  nlohmann::json metadata;
};
DenseGridIn read_vdb_grid_dense(const std::filesystem::path& file, const std::string& grid, const RunContext& ctx = {});

// Grid names, types, classes, bounding boxes, transforms and metadata, without voxel data.
nlohmann::json inspect_vdb(const std::filesystem::path& file, const RunContext& ctx = {});

}  // namespace lblight
