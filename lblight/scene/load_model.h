#pragma once

#include "lblight/core/run_context.h"

#include "lblight/lattice/dense_grid.h"
#include "lblight/scene/scene.h"

namespace lblight {

// Produces a model's density grid from its source, with density_scale applied and values
// checked (finite, in [0, 1]). Materials of empty nodes are reset to the medium so that only
// occupied nodes count as wood. Error(Cancelled) once ctx.cancel is set (voxelisation polls it).
ModelGrid load_model_grid(const ModelSpec& model, const Scene& scene, const RunContext& ctx = {});

}  // namespace lblight
