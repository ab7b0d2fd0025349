// Quick throughput measurement used to turn planned steps into a run-time estimate.
#pragma once

#include "lblight/backend/backend.h"

namespace lblight {

// Lattice updates per second of one system on `backend`, from a few steps on an edge^3 lattice
// of uniform density.
double measure_updates_per_second(const Backend& backend, Precision precision, int edge = 48, int steps = 8);

}  // namespace lblight
