#include "lblight/pipeline/relight.h"

#include <cmath>
#include <cstdio>
#include <string>

#include "lblight/core/error.h"
#include "lblight/io/vdb_io.h"
#include "lblight/pipeline/manifest.h"
#include "lblight/lattice/d3q19.h"
#include "lblight/solve/plan.h"

namespace lblight {

std::vector<std::pair<int, double>> relight_weights(const RelightRequest& req) {
  const Vec3d& t = req.toward_sun;
  const double len = std::sqrt(t.x * t.x + t.y * t.y + t.z * t.z);
  if (!(len > 0) || !std::isfinite(len)) throw_invalid("the sun direction must be a finite, non-zero vector");
  const SunWeights w = decompose_direction({-t.x / len, -t.y / len, -t.z / len});
  std::vector<std::pair<int, double>> out;
  for (int k = 0; k < 3; ++k)
    if (w.weight[k] > kNegligibleSunWeight && req.intensity != 0.0) out.push_back({w.direction[k], req.intensity * w.weight[k]});
  if (req.ambient != 0.0) out.push_back({0, req.ambient});
  if (req.sky != 0.0)
    for (int j = 1; j < 19; ++j) {
      const int cz = d3q19::cz(j);
      if (cz <= 0) out.push_back({j, cz < 0 ? req.sky : 0.5 * req.sky});
    }
  return out;
}

void check_base_solution_grid(const DenseGridIn& g, int solution, const DenseFrame& density_frame,
                              const std::filesystem::path& file) {
  const Location where{file.string(), {}, {}};
  const std::string name = "grid '" + g.name + "'";
  if (g.type != "vec3s" && g.type != "float")
    throw_invalid(name + " is of type " + g.type + "; allowed: vec3s (or float) light", where);
  if (!(g.frame.dims == density_frame.dims) || g.frame.index_min != density_frame.index_min)
    throw_invalid(name + " does not cover the lattice box of grid 'density' (copied in from another bake?)", where);
  if (g.frame.index_to_world != density_frame.index_to_world)
    throw_invalid(name + " has another transform (voxel size, rotation or position) than grid 'density'", where);
  if (g.metadata.contains("lblight_solution")) {
    const nlohmann::json& tag = g.metadata["lblight_solution"];
    if (!tag.is_number_integer() || tag.get<long long>() != solution)
      throw_invalid(name + " is tagged lblight_solution = " + tag.dump() + "; a grid named " + base_grid_name(solution) +
                        " must hold base solution " + std::to_string(solution) + " (renamed grids?)",
                    where);
  }
  const Dims& d = g.frame.dims;
  for (int c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < g.values[c].size(); ++i)
      if (!std::isfinite(g.values[c][i])) {
        const std::size_t x = i % d.nx, y = (i / d.nx) % d.ny, z = i / (static_cast<std::size_t>(d.nx) * d.ny);
        throw_invalid(name + " holds a non-finite value (" + std::to_string(g.values[c][i]) + ") at lattice node (" +
                          std::to_string(x + g.frame.index_min[0]) + ", " + std::to_string(y + g.frame.index_min[1]) +
                          ", " + std::to_string(z + g.frame.index_min[2]) + "); the bake is damaged: bake it again",
                      where);
      }
}

void check_manifest_lattice(const std::filesystem::path& vdb, const DenseFrame& frame) {
  const std::filesystem::path dir = vdb.parent_path().empty() ? "." : vdb.parent_path();
  std::error_code ec;
  if (!std::filesystem::exists(dir / "manifest.json", ec)) return;
  const nlohmann::json manifest = read_manifest(dir);
  for (const auto& m : manifest.at("models")) {
    if (m.value("file", nlohmann::json()) != vdb.filename().string()) continue;
    const nlohmann::json& l = m.at("lattice");
    const nlohmann::json dims = {frame.dims.nx, frame.dims.ny, frame.dims.nz}, lo = frame.index_min;
    if (l.at("dims") != dims || l.at("index_min") != lo)
      throw_invalid("the grids are on the lattice box " + dims.dump() + " from " + lo.dump() + " but " +
                        (dir / "manifest.json").string() + " gives model '" + m.value("name", std::string{}) +
                        "' the box " + l.at("dims").dump() + " from " + l.at("index_min").dump() +
                        " (a .vdb copied in from another bake?)",
                    {vdb.string(), {}, {}});
  }
}

BaseSolutions::BaseSolutions(const std::filesystem::path& vdb, const std::optional<std::set<int>>& wanted, const std::string& why,
                             const RunContext& ctx)
    : file_(vdb) {
  const nlohmann::json grids = inspect_vdb(vdb, ctx).at("grids");
  std::set<std::string> names;
  for (const auto& g : grids) names.insert(g.at("name").get<std::string>());
  if (!names.count("density")) throw_invalid("no grid 'density': not an lblight bake", {vdb.string(), {}, {}});
  std::set<int> solutions = wanted.value_or(std::set<int>{});
  if (!wanted)
    for (int j = 0; j < 19; ++j)
      if (names.count(base_grid_name(j))) solutions.insert(j);
  for (int j : solutions)
    if (!names.count(base_grid_name(j)))
      throw_invalid(why + " needs base solution " + base_grid_name(j) +
                        ", which the bake left out; bake it (lighting.solutions, or a sun_range / instance_rotation "
                        "that includes this sun)",
                    {vdb.string(), {}, {}});
  const DenseGridIn density = read_vdb_grid_dense(vdb, "density", ctx);
  frame_ = density.frame;
  density_ = density.values[0];
  density_metadata_ = density.metadata;
  check_manifest_lattice(vdb, frame_);
  if (names.count("brown")) wood_ = read_vdb_grid_dense(vdb, "brown", ctx).values[0];
  // The flux grids (docs/output-format.md) when the bake wrote them for every solution read.
  has_flux_ = !solutions.empty();
  for (int j : solutions)
    for (const char* c : {"_flux_r", "_flux_g", "_flux_b"}) has_flux_ = has_flux_ && names.count(base_grid_name(j) + c);
  for (int j : solutions) {
    DenseGridIn b = read_vdb_grid_dense(vdb, base_grid_name(j), ctx);
    check_base_solution_grid(b, j, frame_, vdb);
    auto& g = grids_[j];
    for (int c = 0; c < 3; ++c) g[c] = b.values[c].empty() ? b.values[0] : std::move(b.values[c]);
    ctx.check_cancelled();
    if (!has_flux_) continue;
    for (int c = 0; c < 3; ++c) {
      DenseGridIn f = read_vdb_grid_dense(vdb, base_grid_name(j) + "_flux_" + "rgb"[c], ctx);
      check_base_solution_grid(f, j, frame_, vdb);
      if (f.values[1].empty()) throw_invalid("grid " + f.name + " is not a vector grid", {vdb.string(), f.name, {}});
      for (int a = 0; a < 3; ++a) flux_[j][c][a] = std::move(f.values[a]);
      ctx.check_cancelled();
    }
  }
}

namespace {

// out[k][i] = sum_w weight x source_w[k][i] for the K arrays of each source, in double.
template <std::size_t K>
void combine_arrays(const std::vector<std::pair<int, double>>& weights,
                    const std::vector<const std::array<std::vector<float>, K>*>& src, std::array<std::vector<float>, K>& out,
                    std::size_t count, const std::vector<std::size_t>* nodes) {
  auto one = [&](std::size_t i) {
    for (std::size_t c = 0; c < K; ++c) {
      double s = 0;
      for (std::size_t k = 0; k < src.size(); ++k) s += weights[k].second * (*src[k])[c][i];
      out[c][i] = static_cast<float>(s);
    }
  };
  if (nodes)
    for (std::size_t i : *nodes) one(i);
  else
    for (std::size_t i = 0; i < count; ++i) one(i);
}

}  // namespace

void BaseSolutions::combine(const std::vector<std::pair<int, double>>& weights, std::array<std::vector<float>, 3>& out,
                            const std::vector<std::size_t>* nodes) const {
  std::vector<const std::array<std::vector<float>, 3>*> src;
  for (const auto& [solution, weight] : weights) {
    const auto it = grids_.find(solution);
    if (it == grids_.end())
      throw_invalid("relighting needs base solution " + base_grid_name(solution) + ", which was not read", {file_.string(), {}, {}});
    src.push_back(&it->second);
  }
  combine_arrays(weights, src, out, frame_.dims.count(), nodes);
}

void BaseSolutions::combine_flux(const std::vector<std::pair<int, double>>& weights, std::array<FluxField, 3>& out,
                                 const std::vector<std::size_t>* nodes) const {
  for (int c = 0; c < 3; ++c) {
    std::vector<const FluxField*> src;
    for (const auto& [solution, weight] : weights) {
      const auto it = flux_.find(solution);
      if (it == flux_.end())
        throw_invalid("relighting needs the flux of base solution " + base_grid_name(solution) + ", which was not read",
                      {file_.string(), {}, {}});
      src.push_back(&it->second[static_cast<std::size_t>(c)]);
    }
    combine_arrays(weights, src, out[static_cast<std::size_t>(c)], frame_.dims.count(), nodes);
  }
}

RelitModel relight_model(const std::filesystem::path& vdb, const RelightRequest& req, const RunContext& ctx) {
  RelitModel out;
  out.weights = relight_weights(req);
  std::set<int> needed;
  for (const auto& w : out.weights) needed.insert(w.first);
  const BaseSolutions base(vdb, needed, "this sun", ctx);
  out.frame = base.frame();
  out.density = base.density();
  out.wood = base.wood();
  out.density_metadata = base.density_metadata();
  const std::size_t n = out.frame.dims.count();
  std::array<std::vector<float>, 3> sum;
  for (int c = 0; c < 3; ++c) {
    sum[c].assign(n, 0.0f);
    out.light[c].assign(n, 0.0f);
  }
  base.combine(out.weights, sum);
  const std::vector<std::uint8_t> near = near_medium(out.frame.dims, out.density, 1);
  for (std::size_t i = 0; i < n; ++i)
    if (near[i])
      for (int c = 0; c < 3; ++c) out.light[c][i] = sum[c][i];
  if (base.has_flux()) {
    for (FluxField& f : out.flux)
      for (auto& axis : f) axis.assign(n, 0.0f);
    std::vector<std::size_t> nodes;
    for (std::size_t i = 0; i < n; ++i)
      if (near[i]) nodes.push_back(i);
    base.combine_flux(out.weights, out.flux, &nodes);
  }
  return out;
}

}  // namespace lblight
