#include "lblight/scene/gas_source.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "lblight/core/system_info.h"
#include "lblight/scene/mesh_source.h"
#include "lblight/scene/procedural.h"

namespace lblight {

namespace {
double node_size(const GasSource& s) {
  return s.size / *std::max_element(s.resolution.begin(), s.resolution.end());
}
}  // namespace

std::array<double, 16> gas_transform(const GasSource& s) {
  return centred_transform({s.resolution[0], s.resolution[1], s.resolution[2]}, node_size(s), true);
}

fluid::GasSettings gas_settings(const GasSource& s, const Location& where) {
  fluid::GasSettings g;
  g.dims = {s.resolution[0], s.resolution[1], s.resolution[2]};
  g.tau = s.tau;
  g.tau_temperature = s.tau_temperature;
  g.tau_smoke = s.tau_smoke;
  g.t_ambient = s.ambient_temperature;
  g.buoyancy = s.buoyancy;
  using fluid::FaceType;
  g.faces = {FaceType::Open, FaceType::Open, FaceType::Open, FaceType::Open, FaceType::Wall, FaceType::Open};
  const std::array<double, 16> m = gas_transform(s);
  const double h = m[0];
  const Location size_at{where.file, where.json_path + "/size", {}};
  if (!(h >= kMinNodeSize))
    throw_invalid("size " + message_number(s.size) + " over " + std::to_string(std::max({g.dims.nx, g.dims.ny, g.dims.nz})) +
                      " nodes makes them " + message_number(h) + " world units apart; allowed: at least " +
                      message_number(kMinNodeSize) + " (OpenVDB transforms): a larger size or fewer nodes",
                  size_at);
  check_host_memory(static_cast<double>(g.dims.count()) * fluid::kGasBytesPerNode,
                    "the gas solver's " + std::to_string(g.dims.nx) + "x" + std::to_string(g.dims.ny) + "x" +
                        std::to_string(g.dims.nz) + " nodes",
                    "lower the resolution", {where.file, where.json_path + "/resolution", {}});
  fluid::Inlet& in = g.inlet;
  in.enabled = true;
  in.speed = s.inlet_speed;
  in.temperature = s.inlet_temperature;
  in.smoke = s.inlet_smoke;
  in.mask.assign(static_cast<std::size_t>(g.dims.nx) * g.dims.ny, 0);
  in.x0 = g.dims.nx, in.y0 = g.dims.ny, in.x1 = -1, in.y1 = -1;
  for (int y = 0; y < g.dims.ny; ++y)
    for (int x = 0; x < g.dims.nx; ++x) {
      const double wx = m[3] + h * x - s.inlet_center[0], wy = m[7] + h * y - s.inlet_center[1];
      if (wx * wx + wy * wy > s.inlet_radius * s.inlet_radius) continue;
      in.mask[static_cast<std::size_t>(y) * g.dims.nx + x] = 1;
      in.x0 = std::min(in.x0, x), in.x1 = std::max(in.x1, x), in.y0 = std::min(in.y0, y), in.y1 = std::max(in.y1, y);
    }
  if (in.x1 < 0)
    throw_invalid("the inlet (centre [" + message_number(s.inlet_center[0]) + ", " + message_number(s.inlet_center[1]) +
                      "], radius " + message_number(s.inlet_radius) + ") covers no node of the floor, whose nodes are " +
                      message_number(h) + " apart; allowed: a centre inside the floor and a radius that reaches the nearest node centre",
                  where);
  // Obstacles: each mesh voxelised onto the gas nodes (bounds = the box, in the mesh's own units).
  if (!s.obstacles.empty()) g.solid.assign(g.dims.count(), 0);
  for (std::size_t k = 0; k < s.obstacles.size(); ++k) {
    const GasObstacle& o = s.obstacles[k];
    const Location at{where.file, where.json_path + "/obstacles/" + std::to_string(k), {}};
    MeshSource src;
    src.path = o.path;
    src.resolution = std::max({g.dims.nx, g.dims.ny, g.dims.nz});
    src.supersample = 4;
    src.fill = o.fill;
    src.has_bounds = true;
    const double lo[3] = {m[3] - 0.5 * h, m[7] - 0.5 * h, m[11] - 0.5 * h};
    const int n[3] = {g.dims.nx, g.dims.ny, g.dims.nz};
    for (int a = 0; a < 3; ++a) {
      src.bounds_min[a] = (lo[a] - o.position[a]) / o.scale;
      src.bounds_max[a] = (lo[a] + n[a] * h - o.position[a]) / o.scale;
    }
    const ModelGrid v = voxelize_mesh_source(src, 0, at, {}).voxels.grid;
    if (!(v.dims == g.dims)) throw_invalid("the obstacle's voxels do not line up with the gas nodes", at);
    std::size_t solid = 0;
    for (std::size_t i = 0; i < v.density.size(); ++i)
      if (v.density[i] >= 0.5f && (o.part == "all" || v.material[i] == kMaterialWood)) g.solid[i] = 1, ++solid;
    if (solid == 0)
      throw_invalid("obstacle " + o.path.string() + " fills no node of the gas (" + o.part +
                        " parts, at least half a node each); allowed: a mesh inside the box, large against its " +
                        message_number(h) + " spacing",
                    at);
  }
  // The inlet must blow into gas, not into an obstacle.
  if (!g.solid.empty())
    for (int y = 0; y < g.dims.ny; ++y)
      for (int x = 0; x < g.dims.nx; ++x)
        if (in.mask[static_cast<std::size_t>(y) * g.dims.nx + x] && g.solid[g.dims.index(x, y, 0)])
          in.mask[static_cast<std::size_t>(y) * g.dims.nx + x] = 0;
  const std::string why = fluid::check_gas_settings(g);
  if (!why.empty()) throw_invalid(why, where);
  return g;
}

namespace {
// BGK is a low-Mach model: buoyancy can accelerate the gas past what it holds, which ends in NaN a
// few hundred steps later. Checked every 10 steps, so the node named is where it starts.
void check_gas_speed(const fluid::GasSolver& solver, int f, const Location& where) {
  const auto [fastest, at] = solver.fastest_node();
  if (!(fastest > kMaxGasSpeed)) return;
  const Dims& d = solver.settings().dims;
  const std::string node = "(" + std::to_string(at % d.nx) + ", " + std::to_string(at / d.nx % d.ny) + ", " +
                           std::to_string(at / (static_cast<std::size_t>(d.nx) * d.ny)) + ")";
  throw_invalid("the gas reached speed " + message_number(fastest) + " (Mach " + message_number(fastest * std::sqrt(3.0)) +
                    ") at node " + node + " by frame " + std::to_string(f) + "; allowed: at most " +
                    message_number(kMaxGasSpeed) + " lattice units per step: lower buoyancy or inlet speed, or raise tau",
                where);
}
}  // namespace

void run_gas(const GasSource& s, int last, const Location& where, const RunContext& ctx,
             const std::function<void(int, const fluid::GasSolver&)>& on_frame) {
  fluid::GasSolver solver(gas_settings(s, where));
  const int frames = last > 0 ? last : s.frames;
  for (int f = 1; f <= frames; ++f) {
    for (int t = 0; t < s.steps_per_frame; t += 10) {
      ctx.check_cancelled();
      solver.step(std::min(10, s.steps_per_frame - t));
      check_gas_speed(solver, f, where);
    }
    on_frame(f, solver);
  }
}

ModelGrid gas_density(const GasSource& s, const fluid::GasSolver& solver) {
  ModelGrid g;
  g.dims = {s.resolution[0], s.resolution[1], s.resolution[2]};
  g.index_to_world = gas_transform(s);
  const std::vector<double> smoke = solver.smoke();
  const double scale = s.inlet_smoke > 0 ? 1.0 / s.inlet_smoke : 0.0;
  g.density.resize(smoke.size());
  // Traces below kMinGasDensity are air: diffusion leaves 1e-10 everywhere, which would make the
  // whole box "occupied" (no crop, every node lit and written).
  for (std::size_t i = 0; i < smoke.size(); ++i) {
    const double v = std::clamp(smoke[i] * scale, 0.0, 1.0);
    g.density[i] = v < kMinGasDensity ? 0.0f : static_cast<float>(v);
  }
  g.material.assign(smoke.size(), kMaterialMedium);
  return g;
}

std::string gas_frame_name(const std::string& model, int frame) {
  char buf[16];
  std::snprintf(buf, sizeof buf, ".%04d", frame);
  return model + buf;
}

ModelGrid make_gas_density(const GasSource& s, const Location& where, const RunContext& ctx) {
  ModelGrid out;
  const int frame = s.frame > 0 ? s.frame : s.frames;
  run_gas(s, frame, where, ctx, [&](int f, const fluid::GasSolver& solver) {
    if (f == frame) out = gas_density(s, solver);
  });
  out.description = "gas smoke, frame " + std::to_string(frame) + " of " + std::to_string(s.frames) + " (" +
                    std::to_string(frame * s.steps_per_frame) + " steps)";
  return out;
}

}  // namespace lblight
