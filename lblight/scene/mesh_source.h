// Mesh density sources (voxelised triangle meshes, [Steele2009] sec. 5.1): read, classify leaf / wood by
// name, voxelise. Shared by the scene's `mesh` source and `lblight voxelize`.
#pragma once

#include "lblight/core/error.h"
#include "lblight/mesh/classify.h"
#include "lblight/mesh/voxelize.h"
#include "lblight/lattice/dense_grid.h"
#include "lblight/scene/scene.h"

namespace lblight {

struct MeshVoxels {
  VoxelizeResult voxels;           // grid (no density_scale) and statistics
  Classification classes;          // leaf / wood per part, unmatched counts
  std::size_t vertices = 0, triangles = 0, polygons = 0;
  double read_seconds = 0;         // reading and classifying
};

// Reads source.path, classifies its parts and voxelises it with `padding` empty nodes around.
// Logs a summary (info) and every skipped item (warn: unmatched parts, degenerate triangles,
// triangles outside the bounds, open columns when filling). Errors name `where` and the mesh.
// Voxelises on ctx.threads threads (0: all cores); Error(Cancelled) once ctx.cancel is set.
MeshVoxels voxelize_mesh_source(const MeshSource& source, int padding, const Location& where,
                                const RunContext& ctx = {});

// The scene's `mesh` density source: voxelize_mesh_source with no padding (the model's margin
// adds the empty boundary layer).
ModelGrid load_mesh_density(const MeshSource& source, const Location& where, const RunContext& ctx);

FillMode parse_fill_mode(const std::string& text);  // none | parity | winding; throws std::invalid_argument

}  // namespace lblight
