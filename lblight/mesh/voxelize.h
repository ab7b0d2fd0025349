// Mesh to density grid ([Steele2009] sec. 5.1): every triangle is intersected exactly with a fine grid of
// resolution x supersample cells along the longest edge, and the fine grid is box-filtered down
// to `resolution`: a node's density is the fraction of its supersample^3 fine cells that some
// triangle touches. A node is brown (wood) when more of its fine cells are touched by wood
// triangles than by leaf triangles ([Steele2009] sec. 4.1). docs/voxelization.md has the details.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "lblight/core/error.h"
#include "lblight/core/run_context.h"
#include "lblight/mesh/classify.h"
#include "lblight/mesh/triangle_mesh.h"
#include "lblight/lattice/dense_grid.h"

namespace lblight {

// Solid filling of closed meshes (a surface voxelisation of a closed solid is a hollow shell).
enum class FillMode {
  None,     // surface only (plants: leaves are surfaces)
  Parity,   // inside where a ray along +z has crossed the surface an odd number of times
  Winding,  // inside where the signed crossing count (outward normals) is non-zero: unions
            // overlapping closed parts correctly, needs consistently oriented triangles
};

struct VoxelizeOptions {
  int resolution = 64;   // nodes along the longest edge of the box
  int supersample = 8;   // fine cells per node along each axis (1..64)
  bool has_bounds = false;              // voxelise this world box instead of the mesh's bounds
  std::array<double, 3> bounds_min{}, bounds_max{};
  int padding = 0;       // empty nodes added on every side (index_min becomes -padding)
  FillMode fill = FillMode::None;
};

struct VoxelizeStats {
  std::size_t triangles = 0;       // in the mesh
  std::size_t degenerate = 0;      // zero area: skipped
  std::size_t outside = 0;         // entirely outside the box: skipped
  std::uint64_t fine_occupied = 0; // fine cells touched (or filled)
  std::uint64_t fine_leaf = 0, fine_wood = 0, fine_both = 0;
  std::uint64_t open_columns = 0;  // fill: fine columns whose crossings do not close (mesh not closed)
  std::size_t occupied_nodes = 0, brown_nodes = 0;
  std::array<int, 3> fine_dims{};  // the fine grid (never stored)
  double seconds = 0;
  int threads = 1;
};

struct VoxelizeResult {
  ModelGrid grid;  // density in [0, 1]; material kMaterialWood where brown; no density_scale
  VoxelizeStats stats;
};

// `part_class` gives leaf or wood per mesh part (classify_parts). Throws Error(InvalidInput)
// with `where` for options out of range, non-finite vertices, a box of zero size, or a mesh
// with no triangle of non-zero area inside the box. Runs on ctx.threads threads (0: all cores)
// and polls ctx.cancel per tile column: Error(Cancelled) once it is set.
VoxelizeResult voxelize(const TriangleMesh& mesh, const std::vector<TriangleClass>& part_class,
                        const VoxelizeOptions& options, const Location& where = {}, const RunContext& ctx = {});

}  // namespace lblight
