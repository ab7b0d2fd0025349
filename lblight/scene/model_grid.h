// A model's density grid in memory: what every density source produces and the lattice is
// built from.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "lblight/lattice/lattice.h"

namespace lblight {

inline constexpr std::uint8_t kMaterialMedium = 0;  // cloud medium, plastic, or leaf ("green")
inline constexpr std::uint8_t kMaterialWood = 1;    // wood ("brown")

// Smallest node edge (world units) an output can have: OpenVDB refuses transforms whose scale
// is below ~1e-5 ("nearly singular"), which would fail only when the .vdb is written.
inline constexpr double kMinNodeSize = 2e-5;

struct ModelGrid {
  Dims dims;                               // nodes of the density grid (no margin)
  std::array<int, 3> index_min{0, 0, 0};   // index-space coordinate of node (0, 0, 0)
  // Index to world, row-major 4x4 acting on (i, j, k, 1) as OpenVDB's transform does: the
  // world position of the centre of voxel (i, j, k).
  std::array<double, 16> index_to_world{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  std::vector<float> density;              // dims.count(), after density_scale
  std::vector<std::uint8_t> material;      // dims.count(): kMaterialMedium or kMaterialWood
  std::string description;                 // where it came from, for plans and manifests

  std::size_t wood_nodes() const;
  std::size_t occupied_nodes() const;
  // Edge length of a voxel along each index axis in world units.
  std::array<double, 3> voxel_size() const;
};

}  // namespace lblight
