#pragma once

#include "lblight/core/run_context.h"

#include "lblight/lattice/dense_grid.h"
#include "lblight/scene/scene.h"

namespace lblight {

// Produces a model's density grid from its source, with density_scale applied and values
// checked (finite, in [0, 1]). Materials of empty nodes are reset to the medium so that only
// occupied nodes count as wood. Error(Cancelled) once ctx.cancel is set (voxelisation polls it).
ModelGrid load_model_grid(const ModelSpec& model, const Scene& scene, const RunContext& ctx = {});

// What load_model_grid does to the grid a source produced: density_scale, the value checks and
// the materials of empty nodes. For grids made elsewhere (a gas sequence's frames).
ModelGrid finish_model_grid(const ModelSpec& model, const Scene& scene, ModelGrid grid);

}  // namespace lblight
