// Density sources generated in code, deterministic from their parameters, so example scenes
// run with no data files.
#pragma once

#include "lblight/core/run_context.h"
#include "lblight/lattice/dense_grid.h"
#include "lblight/scene/scene.h"

namespace lblight {

// "cloud": a noise-displaced blob, wider than tall, densest in its core, centred at the origin.
// "plant": a small tree standing on z = 0 at the origin: a brown trunk with branches and green
// leaf clusters of partial occupancy. "box": a cube of density 1 (the docs/model.md sec. 5 example).
// `where` locates the source in messages (a grid too large for this machine's memory).
// Layers are generated in parallel (the same grid for any thread count) and the generation stops
// with Error(Cancelled) soon after ctx.cancel is set.
ModelGrid make_procedural(const ProceduralSource& src, const Location& where = {}, const RunContext& ctx = {});

// The box (in nodes) the shape occupies at least: what cropping cannot cut, so a plan can refuse a
// model that cannot fit before generating it. From the same shape generated at a coarse
// resolution (the shapes scale with the grid), less one coarse voxel at each end.
Dims procedural_least_occupied(const ProceduralSource& src);

// Index to world for a box of nodes at spacing h: x and y centred on the origin, z centred or
// (on_ground) starting half a node above z = 0.
std::array<double, 16> centred_transform(const Dims& dims, double h, bool on_ground);

}  // namespace lblight
