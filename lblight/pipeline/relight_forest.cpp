#include "lblight/pipeline/relight_forest.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <unordered_map>

#include "lblight/core/error.h"
#include "lblight/core/system_info.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/vdb_io.h"
#include "lblight/lattice/trilinear.h"
#include "lblight/pipeline/manifest.h"
#include "lblight/scene/forest.h"

namespace fs = std::filesystem;

namespace lblight {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// World position -> continuous array index of a dense frame (the inverse of index_to_world, less
// index_min).
class WorldToIndex {
 public:
  explicit WorldToIndex(const DenseFrame& f) {
    const auto& m = f.index_to_world;
    const double a = m[0], b = m[1], c = m[2], d = m[4], e = m[5], g = m[6], h = m[8], i = m[9], k = m[10];
    const double det = a * (e * k - g * i) - b * (d * k - g * h) + c * (d * i - e * h);
    if (!(std::fabs(det) > 0)) throw_invalid("a grid's transform is singular");
    inv_ = {(e * k - g * i) / det, (c * i - b * k) / det, (b * g - c * e) / det,
            (g * h - d * k) / det, (a * k - c * h) / det, (c * d - a * g) / det,
            (d * i - e * h) / det, (b * h - a * i) / det, (a * e - b * d) / det};
    t_ = {m[3], m[7], m[11]};
    for (int a2 = 0; a2 < 3; ++a2) min_[a2] = f.index_min[a2];
  }
  std::array<double, 3> operator()(const Vec3d& p) const {
    const double x = p.x - t_[0], y = p.y - t_[1], z = p.z - t_[2];
    return {inv_[0] * x + inv_[1] * y + inv_[2] * z - min_[0], inv_[3] * x + inv_[4] * y + inv_[5] * z - min_[1],
            inv_[6] * x + inv_[7] * y + inv_[8] * z - min_[2]};
  }

 private:
  std::array<double, 9> inv_{};
  std::array<double, 3> t_{}, min_{};
};

std::size_t nearest(const Dims& d, const std::array<double, 3>& u, bool& inside) {
  const long x = std::lround(u[0]), y = std::lround(u[1]), z = std::lround(u[2]);
  inside = x >= 0 && y >= 0 && z >= 0 && x < d.nx && y < d.ny && z < d.nz;
  return inside ? d.index(static_cast<int>(x), static_cast<int>(y), static_cast<int>(z)) : 0;
}

// One model's fine bake and, with coarse factors, its alone coarse bake.
struct FineModel {
  std::unique_ptr<BaseSolutions> base, alone;
  std::unique_ptr<WorldToIndex> to_index, alone_to_index;
  std::vector<std::uint8_t> near1;   // voxels a renderer needs: occupied and their neighbours
  std::vector<std::size_t> near2;    // one ring more: every node a trilinear sample of near1 reads
  double voxel_edge = 1;
};

// The manifest's forest section, checked: it is input.
struct ForestManifest {
  std::vector<ForestInstance> instances;
  bool coarse = false;
  std::map<std::string, std::string> model_file, alone_file;  // model -> .vdb
  std::string forest_file;
  std::string ground_units;  // the manifest's ground note ("": no ground)
};

ForestManifest read_forest_manifest(const fs::path& dir) {
  const nlohmann::json m = read_manifest(dir);
  const std::string file = (dir / "manifest.json").string();
  auto fail = [&](const std::string& pointer, const std::string& what) { throw_invalid(what, {file, pointer, {}}); };
  if (!m.contains("forest") || !m["forest"].is_object())
    fail("/forest", "this bake holds no forest (no \"forest\" section); relight one model with --model, or bake a scene "
                    "with a forest");
  ForestManifest f;
  if (m.contains("ground") && m["ground"].is_object() && m["ground"].contains("units") && m["ground"]["units"].is_string())
    f.ground_units = m["ground"]["units"].get<std::string>();
  for (std::size_t i = 0; i < m["models"].size(); ++i) {
    const nlohmann::json& e = m["models"][i];
    const std::string at = "/models/" + std::to_string(i);
    if (!e.contains("name") || !e["name"].is_string()) fail(at + "/name", "must be a string");
    if (!e["file"].is_string()) continue;  // no .vdb written
    const std::string name = e["name"].get<std::string>();
    const std::string role = e.contains("role") && e["role"].is_string() ? e["role"].get<std::string>() : "model";
    const std::string path = manifest_file(dir, e["file"].get<std::string>(), at + "/file").string();
    if (role == "model") f.model_file[name] = path;
    else if (role == "forest") f.forest_file = path;
    else if (role == "forest_alone" && e.contains("alone_model") && e["alone_model"].is_string())
      f.alone_file[e["alone_model"].get<std::string>()] = path;
  }
  const nlohmann::json& forest = m["forest"];
  f.coarse = forest.contains("coarse") && forest["coarse"].is_boolean() && forest["coarse"].get<bool>() &&
             !f.forest_file.empty();
  if (!forest.contains("instances") || !forest["instances"].is_array()) fail("/forest/instances", "must be an array");
  const nlohmann::json& rows = forest["instances"];
  if (rows.size() > static_cast<std::size_t>(kMaxForestInstances))
    fail("/forest/instances", "holds " + std::to_string(rows.size()) + " instances; allowed: up to " +
                                  std::to_string(kMaxForestInstances));
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const std::string at = "/forest/instances/" + std::to_string(i);
    const nlohmann::json& r = rows[i];
    if (!r.is_array() || r.size() != 6 || !r[0].is_string())
      fail(at, "must be [model, x, y, z, yaw_degrees, scale]");
    ForestInstance in;
    in.model = r[0].get<std::string>();
    if (!f.model_file.count(in.model)) fail(at, "names model '" + in.model + "', which the bake did not write");
    double v[5];
    for (int k = 0; k < 5; ++k) {
      if (!r[k + 1].is_number() || !std::isfinite(r[k + 1].get<double>())) fail(at + "/" + std::to_string(k + 1), "must be a finite number");
      v[k] = r[k + 1].get<double>();
    }
    if (std::fabs(v[0]) > 1e9 || std::fabs(v[1]) > 1e9 || std::fabs(v[2]) > 1e9) fail(at, "position outside -1e9..1e9");
    if (!(v[4] >= 1e-3 && v[4] <= 1e3)) fail(at + "/5", "scale must be in 1e-3..1e3");
    in.position = {v[0], v[1], v[2]};
    in.yaw_degrees = v[3];
    in.scale = v[4];
    f.instances.push_back(in);
  }
  return f;
}

// World voxel box an instance can touch: its lattice box turned into the world, one voxel wider.
void world_box(const DenseFrame& frame, const InstanceTransform& t, double h, std::array<std::int64_t, 3>& lo,
               std::array<std::int64_t, 3>& hi) {
  Vec3d mn, mx;
  instance_world_bounds(frame, t, 0.0, mn, mx);
  const double a[3] = {mn.x, mn.y, mn.z}, b[3] = {mx.x, mx.y, mx.z};
  for (int k = 0; k < 3; ++k) {
    lo[k] = static_cast<std::int64_t>(std::floor(a[k] / h)) - 1;
    hi[k] = static_cast<std::int64_t>(std::ceil(b[k] / h)) + 1;
  }
}

// World voxels of one slab (a range of brick columns in x), in bricks keyed by brick coordinate.
struct Slab {
  std::int64_t x_lo = 0, x_hi = 0;  // voxel x range [x_lo, x_hi)
  std::vector<VolumeBrick> bricks;
  std::vector<std::array<float, kBrickVoxels>> weight;
  std::unordered_map<std::uint64_t, std::uint32_t> index;
  std::vector<std::array<double, 5>> instance_sums;  // per instance: sum w f_c (3), sum w, voxels

  std::pair<VolumeBrick*, float*> voxel(std::int64_t x, std::int64_t y, std::int64_t z, int& offset) {
    const std::int64_t bx = x >> 3, by = y >> 3, bz = z >> 3;
    const std::uint64_t key = (static_cast<std::uint64_t>(bx + (1 << 20)) << 42) |
                              (static_cast<std::uint64_t>(by + (1 << 20)) << 21) | static_cast<std::uint64_t>(bz + (1 << 20));
    auto [it, fresh] = index.try_emplace(key, static_cast<std::uint32_t>(bricks.size()));
    if (fresh) {
      bricks.emplace_back();
      bricks.back().origin = {static_cast<int>(bx * 8), static_cast<int>(by * 8), static_cast<int>(bz * 8)};
      weight.emplace_back();
      weight.back().fill(0.0f);
    }
    offset = static_cast<int>((x & 7) + 8 * ((y & 7) + 8 * (z & 7)));
    return {&bricks[it->second], weight[it->second].data()};
  }
};

}  // namespace

ForestRelightResult relight_forest(const fs::path& dir, const ForestRelightRequest& req, const fs::path& output,
                                   const nlohmann::json& file_metadata, const RunContext& ctx) {
  auto t0 = Clock::now();
  ForestRelightResult result;
  const ForestManifest fm = read_forest_manifest(dir);
  if (req.coarse && !fm.coarse)
    throw_invalid("this bake has no coarse forest grid (forest.vdb; the scene's forest.coarse is false); relight "
                  "with --local to use each instance's own light only",
                  {dir.string(), {}, {}});
  result.coarse = req.coarse;
  std::vector<std::size_t> chosen;
  if (req.instance) {
    if (*req.instance >= fm.instances.size())
      throw_invalid("--instance " + std::to_string(*req.instance) + ": the forest has " + std::to_string(fm.instances.size()) +
                    " instances (0.." + std::to_string(fm.instances.size() - 1) + ")", {dir.string(), {}, {}});
    chosen.push_back(*req.instance);
  } else {
    for (std::size_t i = 0; i < fm.instances.size(); ++i) chosen.push_back(i);
  }
  result.instances = chosen.size();

  // Every base solution each model's instances need, read once.
  const Vec3d sun = req.sun.toward_sun;
  std::vector<std::vector<std::pair<int, double>>> weights(fm.instances.size());
  std::map<std::string, std::set<int>> needed;
  for (std::size_t i : chosen) {
    const InstanceTransform t(fm.instances[i]);
    RelightRequest local = req.sun;
    local.toward_sun = t.direction_to_model(sun);
    weights[i] = relight_weights(local);
    std::set<int>& n = needed[fm.instances[i].model];
    for (const auto& w : weights[i]) n.insert(w.first);
  }
  std::map<std::string, FineModel> models;
  for (const auto& [name, solutions] : needed) {
    FineModel& m = models[name];
    m.base = std::make_unique<BaseSolutions>(fm.model_file.at(name), solutions, "an instance of model '" + name + "'", ctx);
    m.to_index = std::make_unique<WorldToIndex>(m.base->frame());
    m.near1 = near_medium(m.base->frame().dims, m.base->density(), 1);
    const std::vector<std::uint8_t> near2 = near_medium(m.base->frame().dims, m.base->density(), 2);
    for (std::size_t n = 0; n < near2.size(); ++n)
      if (near2[n]) m.near2.push_back(n);
    m.voxel_edge = frame_voxel_edge(m.base->frame());
    if (req.coarse) {
      const auto it = fm.alone_file.find(name);
      if (it == fm.alone_file.end())
        throw_invalid("the coarse grid of model '" + name + "' alone (forest.alone." + name + ".vdb) is missing", {dir.string(), {}, {}});
      m.alone = std::make_unique<BaseSolutions>(it->second, solutions, "the coarse grid of model '" + name + "' alone", ctx);
      m.alone_to_index = std::make_unique<WorldToIndex>(m.alone->frame());
    }
  }
  // The coarse forest's light for the world sun, over its whole lattice (boundary values are the
  // open-air light there, which is what a factor near the forest's edge should see).
  std::unique_ptr<BaseSolutions> forest;
  std::unique_ptr<WorldToIndex> forest_to_index;
  std::array<std::vector<float>, 3> forest_light;
  if (req.coarse) {
    result.forest_weights = relight_weights(req.sun);
    std::set<int> s;
    for (const auto& w : result.forest_weights) s.insert(w.first);
    forest = std::make_unique<BaseSolutions>(fm.forest_file, s, "the coarse forest grid", ctx);
    forest_to_index = std::make_unique<WorldToIndex>(forest->frame());
    for (auto& c : forest_light) c.assign(forest->frame().dims.count(), 0.0f);
    forest->combine(result.forest_weights, forest_light);
  }
  double h = req.voxel_size;
  if (!(h > 0)) {
    h = std::numeric_limits<double>::max();
    for (std::size_t i : chosen) h = std::min(h, models.at(fm.instances[i].model).voxel_edge * fm.instances[i].scale);
  }
  result.voxel_size = h;
  result.read_seconds = since(t0);
  t0 = Clock::now();

  // Slabs of brick columns in x, split where the instances' centres fall, so the threads share
  // the work; each slab writes only its own bricks, and every voxel sums its instances in index
  // order whatever the slab: the result does not depend on the thread count.
  std::vector<std::array<std::int64_t, 3>> lo(fm.instances.size()), hi(fm.instances.size());
  std::vector<std::int64_t> centres;
  double voxels_estimate = 0;
  for (std::size_t i : chosen) {
    const FineModel& m = models.at(fm.instances[i].model);
    world_box(m.base->frame(), InstanceTransform(fm.instances[i]), h, lo[i], hi[i]);
    for (int a = 0; a < 3; ++a)
      if (lo[i][a] < -(std::int64_t{1} << 23) + 8 || hi[i][a] > (std::int64_t{1} << 23) - 8)  // brick keys hold 21 bits
        throw_invalid("instance " + std::to_string(i) + " lies outside the +-8.4e6 voxels a world grid of voxel size " +
                      message_number(h) + " holds; use a larger --voxel-size", {dir.string(), {}, {}});
    centres.push_back(((lo[i][0] + hi[i][0]) / 2) >> 3);
    voxels_estimate += static_cast<double>(m.near2.size()) * std::pow(m.voxel_edge * fm.instances[i].scale / h, 3);
  }
  // Bricks hold 8^3 voxels of 5 floats and a bit; partly filled ones about double that.
  check_host_memory(voxels_estimate * 2.0 * (6 * 4) + static_cast<double>(fm.instances.size()) * 64,
                    "the world-space light of " + std::to_string(chosen.size()) + " instance(s) at voxel size " + message_number(h),
                    "use a larger --voxel-size, or relight fewer instances (--instance)", {dir.string(), {}, {}});
  std::sort(centres.begin(), centres.end());
  const int threads = ctx.threads > 0 ? ctx.threads : std::max(1, omp_get_max_threads());
  const int slab_count = std::max(1, std::min<int>(4 * threads, static_cast<int>(centres.size())));
  std::vector<Slab> slabs(static_cast<std::size_t>(slab_count));
  for (int s = 0; s < slab_count; ++s) {
    const std::int64_t from = s == 0 ? std::numeric_limits<std::int64_t>::min() / 4 : centres[centres.size() * s / slab_count] * 8;
    const std::int64_t to = s + 1 == slab_count ? std::numeric_limits<std::int64_t>::max() / 4
                                                : centres[centres.size() * (s + 1) / slab_count] * 8;
    slabs[s].x_lo = from;
    slabs[s].x_hi = std::max(from, to);
  }
  const double eps = kCoarseFactorFloor * (req.sun.intensity + 18.0 * req.sun.ambient + 9.0 * req.sun.sky);
  std::exception_ptr failure;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (int s = 0; s < slab_count; ++s) {
    try {
      Slab& slab = slabs[s];
      if (slab.x_hi <= slab.x_lo) continue;
      slab.instance_sums.assign(fm.instances.size(), {0, 0, 0, 0, 0});
      std::map<std::string, std::array<std::vector<float>, 3>> light, alone_light;
      for (std::size_t i : chosen) {
        const std::int64_t x0 = std::max(lo[i][0], slab.x_lo), x1 = std::min(hi[i][0] + 1, slab.x_hi);
        if (x0 >= x1) continue;
        ctx.check_cancelled();
        const ForestInstance& in = fm.instances[i];
        const FineModel& m = models.at(in.model);
        const Dims& d = m.base->frame().dims;
        auto& l = light[in.model];
        if (l[0].empty())
          for (auto& c : l) c.assign(d.count(), 0.0f);
        m.base->combine(weights[i], l, &m.near2);
        std::array<std::vector<float>, 3>* la = nullptr;
        if (req.coarse) {
          la = &alone_light[in.model];
          if ((*la)[0].empty())
            for (auto& c : *la) c.assign(m.alone->frame().dims.count(), 0.0f);
          m.alone->combine(weights[i], *la);
        }
        const InstanceTransform t(in);
        auto& sums = slab.instance_sums[i];
        for (std::int64_t z = lo[i][2]; z <= hi[i][2]; ++z)
          for (std::int64_t y = lo[i][1]; y <= hi[i][1]; ++y)
            for (std::int64_t x = x0; x < x1; ++x) {
              const Vec3d pw{h * static_cast<double>(x), h * static_cast<double>(y), h * static_cast<double>(z)};
              const Vec3d pm = t.to_model(pw);
              const std::array<double, 3> u = (*m.to_index)(pm);
              bool inside = false;
              const std::size_t n = nearest(d, u, inside);
              if (!inside || !m.near1[n]) continue;
              const Trilinear tri(d, u);
              const double rho = tri(m.base->density());
              double value[3] = {tri(l[0]), tri(l[1]), tri(l[2])};
              double factor[3] = {1, 1, 1};
              if (la) {
                const Trilinear ta(m.alone->frame().dims, (*m.alone_to_index)(pm));
                const Trilinear tf(forest->frame().dims, (*forest_to_index)(pw));
                for (int c = 0; c < 3; ++c) factor[c] = (tf(forest_light[c]) + eps) / (ta((*la)[c]) + eps);
              }
              const bool wood = !m.base->wood().empty() && tri(m.base->wood()) >= 0.5;
              int off = 0;
              auto [brick, weight] = slab.voxel(x, y, z, off);
              const double w = rho + 1e-6;  // the one-voxel rim (rho 0) still gets light
              for (int c = 0; c < 3; ++c) brick->light[c][off] += static_cast<float>(w * value[c] * factor[c]);
              weight[off] += static_cast<float>(w);
              brick->density[off] += static_cast<float>(rho);
              if (wood) brick->wood[off] += static_cast<float>(rho);
              brick->active.set(static_cast<std::size_t>(off));
              for (int c = 0; c < 3; ++c) sums[c] += w * factor[c];
              sums[3] += w;
              sums[4] += 1;
            }
      }
      // Overlapping instances: light is their density-weighted mean, density their sum (at most 1).
      for (std::size_t b = 0; b < slab.bricks.size(); ++b) {
        VolumeBrick& brick = slab.bricks[b];
        for (int v = 0; v < kBrickVoxels; ++v) {
          const float w = slab.weight[b][v];
          if (!(w > 0.0f)) continue;
          for (int c = 0; c < 3; ++c) brick.light[c][v] /= w;
          brick.wood[v] = brick.wood[v] > 0.5f * brick.density[v] && brick.density[v] > 0.0f ? 1.0f : 0.0f;
          brick.density[v] = std::min(1.0f, brick.density[v]);
        }
      }
    } catch (...) {
#pragma omp critical(lblight_relight_forest)
      if (!failure) failure = std::current_exception();
    }
  }
  if (failure) std::rethrow_exception(failure);
  ctx.check_cancelled();
  for (std::size_t i : chosen) {
    InstanceRelight r;
    r.model = fm.instances[i].model;
    r.weights = weights[i];
    std::array<double, 5> s{0, 0, 0, 0, 0};
    for (const Slab& slab : slabs)
      if (!slab.instance_sums.empty())
        for (int k = 0; k < 5; ++k) s[k] += slab.instance_sums[i][k];
    for (int c = 0; c < 3; ++c) r.mean_factor[c] = s[3] > 0 ? s[c] / s[3] : 1.0;
    r.voxels = static_cast<std::size_t>(s[4]);
    result.per_instance.push_back(r);
  }
  BrickVolumeOut volume;
  volume.voxel_size = h;
  for (const Slab& slab : slabs)
    for (const VolumeBrick& b : slab.bricks) {
      volume.bricks.push_back(&b);
      result.active_voxels += b.active.count();
      for (float w : b.wood) volume.with_wood = volume.with_wood || w > 0.0f;
    }
  result.bricks = volume.bricks.size();
  result.relight_seconds = since(t0);
  t0 = Clock::now();
  volume.light_metadata = {
      {"lblight_meaning", "light of a static bake of this sun, per instance from its model's base solutions" +
                              std::string(req.coarse ? " x the coarse forest factor" : "") +
                              "; 1 = the open-air value of a unit sun (ambient a: 18 a in open air, sky S: 9 S)" +
                              (fm.ground_units.empty() ? std::string() : "; " + fm.ground_units)},
      {"lblight_units", "open-air light of a unit sun"}};
  volume.density_metadata = {{"lblight_meaning", "the forest's density: the instances' fine densities resampled, summed, at most 1"}};
  write_file_atomically(output, [&](const fs::path& tmp) {
    write_brick_vdb(tmp, volume, file_metadata);
    ctx.check_cancelled();
  });
  result.write_seconds = since(t0);
  return result;
}

}  // namespace lblight
