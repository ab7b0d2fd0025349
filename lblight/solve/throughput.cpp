#include "lblight/solve/throughput.h"

#include <algorithm>
#include <chrono>

#include "lblight/lattice/sun.h"
#include "lblight/scene/procedural.h"

namespace lblight {

LatticeGeometry bench_lattice(const std::string& shape, int size) {
  LatticeGeometry lat;
  lat.dims = {size, size, size};
  lat.density.assign(lat.dims.count(), 0.0f);
  lat.material.assign(lat.dims.count(), kMaterialMedium);
  if (shape == "uniform") {
    for (int z = 1; z < size - 1; ++z)
      for (int y = 1; y < size - 1; ++y)
        for (int x = 1; x < size - 1; ++x) lat.density[lat.dims.index(x, y, z)] = 0.5f;
    return lat;
  }
  ProceduralSource src;
  src.shape = shape;
  src.resolution = size - 2;
  const ModelGrid grid = make_procedural(src);
  for (int z = 0; z < grid.dims.nz; ++z)
    for (int y = 0; y < grid.dims.ny; ++y)
      for (int x = 0; x < grid.dims.nx; ++x) {
        const std::size_t i = lat.dims.index(x + 1, y + 1, z + 1);
        lat.density[i] = grid.density[grid.dims.index(x, y, z)];
        lat.material[i] = grid.material[grid.dims.index(x, y, z)];
      }
  lat.material_count = shape == "plant" ? 2 : 1;
  return lat;
}

ChannelMaterials bench_materials() {
  ChannelMaterials ch;
  ch.omega[kMaterialMedium] = build_omega({0.008, 0.792, 0.9});
  ch.omega[kMaterialWood] = build_omega({0.008, 0.792, -1.0});
  return ch;
}

namespace {

std::vector<SystemSpec> bench_batch(int systems) {
  std::vector<SystemSpec> batch(static_cast<std::size_t>(systems));
  for (int s = 0; s < systems; ++s) batch[static_cast<std::size_t>(s)].boundary = base_boundary(1 + s % 18);
  return batch;
}

double seconds_of(LatticeSolver& solver, int steps, std::vector<Residual>& r) {
  const auto t0 = std::chrono::steady_clock::now();
  solver.step_and_measure(steps, r);  // the measure also waits for an asynchronous backend's steps
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

ThroughputRun measure_throughput(const Backend& backend, const LatticeGeometry& lattice, Precision precision,
                                 int systems, int steps, double warmup_seconds, double target_seconds,
                                 int time_block, StateLayout layout, bool symmetric_collision, const RunContext& ctx) {
  SolverOptions so;
  so.symmetric_collision = symmetric_collision;
  so.precision = precision;
  so.max_systems = systems;
  so.time_block = time_block;
  so.layout = layout;
  auto solver = backend.create(lattice, {bench_materials()}, so);
  solver->reset(bench_batch(systems));
  // Warm up (an idle GPU clocks down; caches and pages settle), doubling the steps.
  std::vector<Residual> r;
  double step_seconds = 0, warm = 0;
  for (int n = 2; n <= (1 << 20); n *= 2) {
    ctx.check_cancelled();
    const double dt = seconds_of(*solver, n, r);
    step_seconds = dt / n;
    warm += dt;
    if (warm >= warmup_seconds) break;
  }
  ThroughputRun run;
  run.steps = steps > 0 ? steps
                        : std::max(4, std::min(1 << 22, static_cast<int>(target_seconds / std::max(step_seconds, 1e-9))));
  // Spans of about half a second (a measure each: negligible against that), polling ctx between.
  const int span = std::max(1, static_cast<int>(0.5 / std::max(step_seconds, 1e-9)));
  for (int done = 0; done < run.steps; done += span) {
    ctx.check_cancelled();
    run.seconds += seconds_of(*solver, std::min(span, run.steps - done), r);
  }
  run.updates_per_second =
      static_cast<double>(lattice.dims.interior_count()) * run.steps * systems / std::max(run.seconds, 1e-9);
  run.steps_per_pass = solver->steps_per_pass();
  run.by_position = solver->streams_by_position();
  run.swept_fraction = solver->swept_fraction();
  const bool one_level = layout == StateLayout::InPlace || run.by_position;
  run.state_bytes = (one_level ? 1.0 : 2.0) * 19.0 * static_cast<double>(lattice.dims.count()) * systems *
                    bytes_per_value(precision);
  return run;
}

double measure_updates_per_second(const Backend& backend, Precision precision, int edge, int steps) {
  const bool device = !backend.occupies_host_cores();
  if (edge <= 0) edge = device ? 128 : 48;
  if (steps <= 0) steps = device ? 20 : 8;
  return measure_throughput(backend, bench_lattice("uniform", edge), precision, 1, steps, 0.0).updates_per_second;
}

std::vector<float> bench_totals(const Backend& backend, const LatticeGeometry& lattice, Precision precision, int steps) {
  SolverOptions so;
  so.precision = precision;
  so.max_systems = 1;
  auto solver = backend.create(lattice, {bench_materials()}, so);
  solver->reset(bench_batch(1));
  solver->step(steps);
  std::vector<Residual> r;
  solver->measure(r);
  std::vector<float> t(lattice.dims.count());
  solver->read_totals(0, t.data());
  return t;
}

}  // namespace lblight
