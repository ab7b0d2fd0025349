#include "lblight/solve/calibrate.h"

#include <algorithm>
#include <chrono>
#include <vector>

#include "lblight/lattice/sun.h"

namespace lblight {

double measure_updates_per_second(const Backend& backend, Precision precision, int edge, int steps) {
  const bool device = !backend.occupies_host_cores();
  if (edge <= 0) edge = device ? 128 : 48;
  if (steps <= 0) steps = device ? 20 : 8;
  LatticeGeometry g;
  g.dims = {edge, edge, edge};
  g.density.assign(g.dims.count(), 0.0f);
  g.material.assign(g.dims.count(), 0);
  for (int z = 1; z < edge - 1; ++z)
    for (int y = 1; y < edge - 1; ++y)
      for (int x = 1; x < edge - 1; ++x) g.density[g.dims.index(x, y, z)] = 0.5f;
  ChannelMaterials ch;
  ch.omega[0] = build_omega({0.1, 0.8, 0.5});
  SolverOptions so;
  so.precision = precision;
  so.max_systems = 1;
  auto solver = backend.create(g, {ch}, so);
  SystemSpec sys;
  const auto b = base_boundary(0);
  for (int i = 0; i < 19; ++i) sys.boundary[i] = b[i];
  solver->reset({sys});
  // measure() waits for the device: a GPU's step() only queues kernels, and timing it alone would
  // time the launches
  std::vector<Residual> r;
  solver->step(2);
  solver->measure(r);
  const auto t0 = std::chrono::steady_clock::now();
  solver->step(steps);
  solver->measure(r);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return static_cast<double>(g.dims.interior_count()) * steps / std::max(s, 1e-9);
}

}  // namespace lblight
