// Lattice updates per second on a backend: `lblight bench` reports them against the measured
// memory bandwidth, and `validate` turns planned steps into a run-time estimate with them.
#pragma once

#include <string>
#include <vector>

#include "lblight/backend/backend.h"
#include "lblight/core/run_context.h"

namespace lblight {

// A size^3 lattice for timing: "uniform" (density 0.5 on every interior node: every node
// collides, the worst case for compute), or a procedural "cloud" or "plant" (a realistic mix of
// dense, thin and empty rows) resampled into the cube.
LatticeGeometry bench_lattice(const std::string& shape, int size);
// The cloud medium of [Geist2010] sec. 3.2.1 (sigma_a 0.008, sigma_s 0.792, g 0.9), and wood of
// the same sigma with g = -1.
ChannelMaterials bench_materials();

struct ThroughputRun {
  int steps = 0;
  double seconds = 0;
  double updates_per_second = 0;  // per system (one channel of one solution)
  double state_bytes = 0;         // every system's state (both time levels, or the one in place)
  int steps_per_pass = 1;         // the solver's temporal blocking depth (SolverOptions::time_block)
  bool by_position = false;       // streaming by position (LatticeSolver::streams_by_position)
  double swept_fraction = 1.0;    // of the interior nodes, those a step reads and writes
};

// Times `steps` steps of `systems` systems (suns along lattice directions 1, 2, ...) on `lattice`
// after a warm-up of at least `warmup_seconds` (doubling the steps from 2; 0: one 2-step
// warm-up). steps 0: about `target_seconds` of work. measure() closes each timed span, so an
// asynchronous backend's queued steps count. The timed steps run in spans of about half a second,
// between which `ctx` is polled, so that a long --steps stops on Ctrl-C.
// time_block, layout, symmetric_collision: those of SolverOptions (time_block 0: the backend's choice).
ThroughputRun measure_throughput(const Backend& backend, const LatticeGeometry& lattice, Precision precision,
                                 int systems, int steps, double warmup_seconds = 0.3, double target_seconds = 2.0,
                                 int time_block = 0, StateLayout layout = StateLayout::TwoLevels,
                                 bool symmetric_collision = true, const RunContext& ctx = {});

// The quick figure behind run-time estimates: one system on an edge^3 uniform lattice (edge 0: 48
// on the CPU, 128 on a GPU, where a smaller lattice would sit in the L2 cache and time launches
// rather than memory) for a few steps (steps 0: 8 on the CPU, 20 on a GPU).
double measure_updates_per_second(const Backend& backend, Precision precision, int edge = 0, int steps = 0);

// Totals of one system (sun along lattice direction 1) after `steps` steps from t = 0: what the
// storage precision costs, compared between precisions by `bench`.
std::vector<float> bench_totals(const Backend& backend, const LatticeGeometry& lattice, Precision precision, int steps);

}  // namespace lblight
