// Dense grids over a box of index space: the frame every density source, lattice and output file
// shares, and a model's density grid, which every density source produces and the lattice is
// built from. Plain values, so the mesh, io, scene and solve layers can all pass them around.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "lblight/core/error.h"
#include "lblight/lattice/lattice.h"

namespace lblight {

// Material index per node. A lattice holds at most kMaxMaterials of them.
inline constexpr std::uint8_t kMaterialMedium = 0;  // cloud medium, plastic, or leaf ("green")
inline constexpr std::uint8_t kMaterialWood = 1;    // wood ("brown")
// The reflective ground layer a lattice may stand on (lattice/ground.h): in lattices only, never in
// a density grid or an output.
inline constexpr std::uint8_t kMaterialGround = 2;
inline constexpr int kMaxMaterials = 3;

// Smallest node edge (world units) an output can have: OpenVDB refuses transforms whose scale
// is below ~1e-5 ("nearly singular"), which would fail only when the .vdb is written.
inline constexpr double kMinNodeSize = 2e-5;

// Index coordinates lblight takes: OpenVDB's dense copies walk tree nodes 4096 voxels wide and
// overflow 32-bit coordinates near 2^31, so every box stays within +-2^30, and an axis holds at
// most 2^20 nodes (the .lbh format's limit).
inline constexpr std::int64_t kMaxIndexCoord = std::int64_t{1} << 30;
inline constexpr std::int64_t kMaxNodesPerAxis = std::int64_t{1} << 20;

// Error(InvalidInput) at `where` unless the inclusive box [lo, hi] is non-empty, lies within
// +-kMaxIndexCoord and has at most kMaxNodesPerAxis nodes per axis; `what` names the box in the
// message ("the active voxels of grid 'density'").
void check_index_box(const std::array<std::int64_t, 3>& lo, const std::array<std::int64_t, 3>& hi,
                     const std::string& what, const Location& where);

// Where a dense array of nodes sits: node (i, j, k) is index coordinate index_min + (i, j, k);
// index_to_world is row-major 4x4 acting on (i, j, k, 1), as OpenVDB's transform does (the world
// position of the centre of voxel (i, j, k)).
struct DenseFrame {
  Dims dims;
  std::array<int, 3> index_min{};
  std::array<double, 16> index_to_world{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  // Error(InvalidInput) unless the frame's box passes check_index_box.
  void check(const std::string& what, const Location& where) const;
  bool operator==(const DenseFrame& o) const {
    return dims == o.dims && index_min == o.index_min && index_to_world == o.index_to_world;
  }
};

// The nodes a renderer interpolates from: the occupied nodes of `density` and their 26
// neighbours, `rings` times over. A lattice's outer layer holds fixed boundary sources, not light
// in the medium, so it never grows into it unless `outer_layer` (a volume cut from a sparse grid,
// whose box edge may be occupied).
std::vector<std::uint8_t> near_medium(const Dims& dims, const std::vector<float>& density, int rings,
                                      bool outer_layer = false);

struct ModelGrid {
  Dims dims;                               // nodes of the density grid (no margin)
  std::array<int, 3> index_min{0, 0, 0};   // index-space coordinate of node (0, 0, 0)
  std::array<double, 16> index_to_world{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};  // as DenseFrame's
  std::vector<float> density;              // dims.count(), after density_scale
  std::vector<std::uint8_t> material;      // dims.count(): kMaterialMedium or kMaterialWood
  std::string description;                 // where it came from, for plans and manifests

  DenseFrame frame() const { return {dims, index_min, index_to_world}; }
  std::size_t wood_nodes() const;
  std::size_t occupied_nodes() const;
  // Edge length of a voxel along each index axis in world units.
  std::array<double, 3> voxel_size() const;
};

}  // namespace lblight
