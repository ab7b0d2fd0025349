// Density sources generated in code, deterministic from their parameters, so example scenes
// run with no data files.
#pragma once

#include "lblight/lattice/dense_grid.h"
#include "lblight/scene/scene.h"

namespace lblight {

// "cloud": a noise-displaced blob, wider than tall, densest in its core, centred at the origin.
// "plant": a small tree standing on z = 0 at the origin: a brown trunk with branches and green
// leaf clusters of partial occupancy. "box": a cube of density 1 (the docs/model.md sec. 5 example).
// `where` locates the source in messages (a grid too large for this machine's memory).
ModelGrid make_procedural(const ProceduralSource& src, const Location& where = {});

}  // namespace lblight
