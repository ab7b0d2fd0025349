// Quick throughput measurement used to turn planned steps into a run-time estimate.
#pragma once

#include "lblight/backend/backend.h"

namespace lblight {

// Lattice updates per second of one system on `backend`, from a few steps on an edge^3 lattice
// of uniform density. edge 0: 48 on the CPU, 128 on a GPU (a smaller lattice would sit in the
// GPU's L2 cache and time launches rather than memory).
double measure_updates_per_second(const Backend& backend, Precision precision, int edge = 0, int steps = 0);

}  // namespace lblight
