#include "lblight/pipeline/relight.h"

#include <cmath>
#include <cstdio>
#include <string>

#include "lblight/core/error.h"
#include "lblight/io/vdb_io.h"

namespace lblight {
namespace {

std::string grid_name(int solution) {
  char b[8];
  std::snprintf(b, sizeof b, "B%02d", solution);
  return b;
}

}  // namespace

RelitModel relight_model(const std::filesystem::path& vdb, const RelightRequest& req, const RunContext& ctx) {
  const Vec3d& t = req.toward_sun;
  const double len = std::sqrt(t.x * t.x + t.y * t.y + t.z * t.z);
  if (!(len > 0) || !std::isfinite(len)) throw_invalid("the sun direction must be a finite, non-zero vector");
  const SunWeights w = decompose_direction({-t.x / len, -t.y / len, -t.z / len});
  RelitModel out;
  for (int k = 0; k < 3; ++k)
    if (w.weight[k] > kNegligibleSunWeight && req.intensity != 0.0)
      out.weights.push_back({w.direction[k], req.intensity * w.weight[k]});
  if (req.ambient != 0.0) out.weights.push_back({0, req.ambient});
  const nlohmann::json grids = inspect_vdb(vdb, ctx).at("grids");
  auto has = [&](const std::string& name) {
    for (const auto& g : grids)
      if (g.at("name") == name) return true;
    return false;
  };
  if (!has("density")) throw_invalid("no grid 'density': not an lblight bake", {vdb.string(), {}, {}});
  for (const auto& [solution, weight] : out.weights)
    if (!has(grid_name(solution)))
      throw_invalid("this sun needs base solution " + grid_name(solution) + " (weight " + std::to_string(weight) +
                        "), which the bake left out; bake it (lighting.solutions, or a sun_range / instance_rotation "
                        "that includes this sun)",
                    {vdb.string(), {}, {}});
  const DenseGridIn density = read_vdb_grid_dense(vdb, "density", ctx);
  out.frame = density.frame;
  out.density = density.values[0];
  const std::size_t n = out.frame.dims.count();
  for (auto& c : out.light) c.assign(n, 0.0f);
  std::array<std::vector<double>, 3> sum;
  for (auto& c : sum) c.assign(n, 0.0);
  for (const auto& [solution, weight] : out.weights) {
    const DenseGridIn b = read_vdb_grid_dense(vdb, grid_name(solution), ctx);
    if (!(b.frame.dims == out.frame.dims) || b.frame.index_min != out.frame.index_min)
      throw_invalid("grid " + grid_name(solution) + " does not cover the lattice box of grid 'density'",
                    {vdb.string(), {}, {}});
    for (int c = 0; c < 3; ++c) {
      const std::vector<float>& v = b.values[c].empty() ? b.values[0] : b.values[c];
      for (std::size_t i = 0; i < n; ++i) sum[c][i] += weight * v[i];
    }
    ctx.check_cancelled();
  }
  // Occupied nodes and their 26 neighbours (what a renderer interpolates between); the lattice's
  // boundary layer holds the fixed source values, which are not light in the medium.
  const Dims& d = out.frame.dims;
  for (int z = 1; z < d.nz - 1; ++z)
    for (int y = 1; y < d.ny - 1; ++y)
      for (int x = 1; x < d.nx - 1; ++x) {
        bool near = false;
        for (int dz = -1; dz <= 1 && !near; ++dz)
          for (int dy = -1; dy <= 1 && !near; ++dy)
            for (int dx = -1; dx <= 1 && !near; ++dx) near = out.density[d.index(x + dx, y + dy, z + dz)] > 0.0f;
        if (!near) continue;
        const std::size_t i = d.index(x, y, z);
        for (int c = 0; c < 3; ++c) out.light[c][i] = static_cast<float>(sum[c][i]);
      }
  return out;
}

}  // namespace lblight
