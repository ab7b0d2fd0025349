#include "lblight/scene/forest.h"
#include "lblight/scene/scene_fields.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "lblight/core/error.h"

namespace lblight {
namespace {

bool yawed(double degrees) {
  const double r = std::fmod(std::fabs(degrees), 360.0);
  return r > 1e-9 && 360.0 - r > 1e-9;
}

void check_yaw(const JsonReader& r, const std::string& key, double degrees, InstanceRotation rotation) {
  if (rotation == InstanceRotation::None && yawed(degrees))
    r.fail("a yaw of " + JsonReader::describe(degrees) +
               " degrees rotates the instance, but lighting.instance_rotation is \"none\": the bake leaves out "
               "the base solutions a rotated copy needs; set instance_rotation to \"yaw\" or use yaw 0",
           key);
}

std::array<double, 2> range(const JsonReader& r, const std::string& key, std::array<double, 2> fallback, double lo,
                            double hi, const std::string& allowed) {
  if (!r.has(key)) return fallback;
  const JsonReader v = r.child(key);
  const std::vector<double> lh = v.as_numbers(2, "[low, high]", lo, hi, allowed);
  const std::array<double, 2> out{lh[0], lh[1]};
  if (out[1] < out[0]) v.fail("high must be >= low");
  return out;
}

std::string model_name(const JsonReader& r, const std::string& key, const std::set<std::string>& models) {
  const std::string name = r.string(key);
  if (!models.count(name)) {
    std::string list;
    for (const std::string& m : models) list += (list.empty() ? "" : ", ") + m;
    r.fail("unknown model '" + name + "'; the scene's models: " + list, key);
  }
  return name;
}

// SplitMix64: one stream per generator seed.
struct Random {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0); }  // [0, 1)
};

}  // namespace

ForestSpec read_forest(const JsonReader& r, const std::set<std::string>& models, InstanceRotation rotation) {
  r.expect_object();
  check_fields(r, scene_object("forest"));
  ForestSpec f;
  if (r.has("coarse")) {
    const JsonReader c = r.child("coarse");
    if (c.json().is_boolean()) {
      f.coarse = c.json().get<bool>();
    } else {
      c.expect_object();
      const ObjectSpec& o = scene_object("forest.coarse");
      check_fields(c, o);
      f.cell_size = number_field(c, o, "cell_size");
      f.coarse_tolerance = number_field(c, o, "tolerance");
    }
  }
  if (r.has("instances")) {
    const JsonReader list = r.child("instances");
    if (!list.json().is_array()) list.fail("expected a list of instances");
    for (std::size_t i = 0; i < list.json().size(); ++i) {
      const JsonReader e = list.element(i);
      e.expect_object();
      const ObjectSpec& o = scene_object("forest.instance");
      check_fields(e, o);
      ForestInstance inst;
      inst.model = model_name(e, "model", models);
      const std::vector<double> p = e.child("position").as_numbers(3, "[x, y, z]", -1e9, 1e9, "-1e9..1e9 world units");
      std::copy(p.begin(), p.end(), inst.position.begin());
      inst.yaw_degrees = number_field(e, o, "yaw_degrees");
      check_yaw(e, "yaw_degrees", inst.yaw_degrees, rotation);
      inst.scale = number_field(e, o, "scale");
      f.instances.push_back(inst);
      f.instance_paths.push_back(e.path());
    }
  }
  if (r.has("generator")) {
    const JsonReader g = r.child("generator");
    g.expect_object();
    const ObjectSpec& o = scene_object("forest.generator");
    check_fields(g, o);
    ForestGenerator gen;
    gen.json_path = g.path();
    const JsonReader a = g.child("area");
    const std::vector<double> corners = a.as_numbers(4, "[x_min, y_min, x_max, y_max]", -1e9, 1e9, "-1e9..1e9 world units");
    std::copy(corners.begin(), corners.end(), gen.area.begin());
    if (!(gen.area[2] > gen.area[0] && gen.area[3] > gen.area[1])) a.fail("x_max must be > x_min and y_max > y_min");
    gen.height = number_field(g, o, "height");
    const double area = (gen.area[2] - gen.area[0]) * (gen.area[3] - gen.area[1]);
    if (g.has("count") == g.has("density")) g.fail("give either count or density (instances per unit area)");
    if (g.has("count")) {
      gen.count = static_cast<int>(integer_field(g, o, "count"));
    } else {
      const double density = number_field(g, o, "density");
      const double n = std::round(density * area);
      if (n < 1 || n > kMaxForestInstances)
        g.fail("density x area gives " + JsonReader::describe(n) + " instances; allowed: 1.." +
                   std::to_string(kMaxForestInstances),
               "density");
      gen.count = static_cast<int>(n);
    }
    gen.min_spacing = number_field(g, o, "min_spacing");
    gen.yaw_degrees = range(g, "yaw_degrees", {0, 0}, -3600.0, 3600.0, "-3600..3600 degrees");
    if (rotation == InstanceRotation::None && (yawed(gen.yaw_degrees[0]) || gen.yaw_degrees[0] != gen.yaw_degrees[1]))
      g.fail("yaw_degrees " + JsonReader::describe(nlohmann::json(gen.yaw_degrees)) +
                 " rotates the instances, but lighting.instance_rotation is \"none\": the bake leaves out the base "
                 "solutions rotated copies need; set instance_rotation to \"yaw\" or use [0, 0]",
             "yaw_degrees");
    gen.scale = range(g, "scale", {1, 1}, 1e-3, 1e3, "1e-3..1e3");
    gen.seed = static_cast<std::uint64_t>(integer_field(g, o, "seed"));
    const JsonReader ms = g.child("models");
    if (!ms.json().is_array() || ms.json().empty()) ms.fail("expected a non-empty list of {\"model\": name, \"weight\": w}");
    for (std::size_t i = 0; i < ms.json().size(); ++i) {
      const JsonReader e = ms.element(i);
      e.expect_object();
      const ObjectSpec& w = scene_object("forest.model_weight");
      check_fields(e, w);
      gen.models.push_back({model_name(e, "model", models), number_field(e, w, "weight")});
    }
    f.generator = gen;
  }
  if (f.empty()) r.fail("a forest needs instances or a generator");
  return f;
}

InstanceTransform::InstanceTransform(const ForestInstance& in)
    : cos_(std::cos(in.yaw_degrees * (M_PI / 180.0))),
      sin_(std::sin(in.yaw_degrees * (M_PI / 180.0))),
      scale_(in.scale),
      position_{in.position[0], in.position[1], in.position[2]} {
  // Exact quarter turns, so a 90-degree instance permutes lattice directions exactly.
  const double q = in.yaw_degrees / 90.0;
  if (q == std::round(q)) {
    const long k = ((static_cast<long>(q) % 4) + 4) % 4;
    cos_ = k == 0 ? 1.0 : k == 2 ? -1.0 : 0.0;
    sin_ = k == 1 ? 1.0 : k == 3 ? -1.0 : 0.0;
  }
}

Vec3d InstanceTransform::to_world(const Vec3d& p) const {
  return {position_.x + scale_ * (cos_ * p.x - sin_ * p.y), position_.y + scale_ * (sin_ * p.x + cos_ * p.y),
          position_.z + scale_ * p.z};
}

Vec3d InstanceTransform::to_model(const Vec3d& w) const {
  const double x = (w.x - position_.x) / scale_, y = (w.y - position_.y) / scale_, z = (w.z - position_.z) / scale_;
  return {cos_ * x + sin_ * y, -sin_ * x + cos_ * y, z};
}

Vec3d InstanceTransform::direction_to_model(const Vec3d& d) const {
  return {cos_ * d.x + sin_ * d.y, -sin_ * d.x + cos_ * d.y, d.z};
}

Vec3d frame_to_world(const DenseFrame& f, double i, double j, double k) {
  const auto& m = f.index_to_world;
  i += f.index_min[0];
  j += f.index_min[1];
  k += f.index_min[2];
  return {m[0] * i + m[1] * j + m[2] * k + m[3], m[4] * i + m[5] * j + m[6] * k + m[7],
          m[8] * i + m[9] * j + m[10] * k + m[11]};
}

double frame_voxel_edge(const DenseFrame& f) {
  const ModelGrid g{f.dims, f.index_min, f.index_to_world, {}, {}, {}};
  const std::array<double, 3> v = g.voxel_size();
  return std::cbrt(v[0] * v[1] * v[2]);
}

void instance_world_bounds(const DenseFrame& f, const InstanceTransform& t, double pad, Vec3d& lo, Vec3d& hi) {
  const double big = std::numeric_limits<double>::max();
  lo = {big, big, big};
  hi = {-big, -big, -big};
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3d p = t.to_world(frame_to_world(f, (corner & 1) ? f.dims.nx - 1 + pad : -pad,
                                              (corner & 2) ? f.dims.ny - 1 + pad : -pad,
                                              (corner & 4) ? f.dims.nz - 1 + pad : -pad));
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
}

std::vector<ForestInstance> forest_instances(const ForestSpec& f, const std::string& file) {
  std::vector<ForestInstance> out = f.instances;
  if (!f.generator) return out;
  const ForestGenerator& g = *f.generator;
  double total_weight = 0;
  for (const auto& m : g.models) total_weight += m.second;
  // Up front, not after millions of tries: random placement (dart throwing) jams when discs of
  // diameter min_spacing cover about 0.547 of the area (random sequential adsorption's limit),
  // well below a hexagonal packing's 0.907. The area grows by one spacing for the discs that
  // overhang its edges.
  if (g.min_spacing > 0) {
    const double pi = 3.14159265358979323846, s = g.min_spacing;
    const double area = (g.area[2] - g.area[0] + s) * (g.area[3] - g.area[1] + s);
    const double fits = 0.547 * area / (pi * s * s / 4);
    if (static_cast<double>(g.count) > fits)
      throw_invalid("the forest generator cannot place " + std::to_string(g.count) + " instances " +
                        JsonReader::describe(g.min_spacing) + " apart in its area: random placement fits about " +
                        std::to_string(static_cast<long long>(fits)) +
                        " there; lower count/density or min_spacing, or enlarge the area",
                    {file, g.json_path, {}});
  }
  Random rng{g.seed};
  // Dart throwing with a hash of cells min_spacing wide: each candidate is checked against the
  // instances in its and the neighbouring cells only.
  const double cell = g.min_spacing > 0 ? g.min_spacing : 1.0;
  std::unordered_map<long long, std::vector<std::size_t>> cells;
  auto key = [&](long long cx, long long cy) { return cx * 1000003LL + cy; };
  const std::size_t first = out.size();
  const long long max_tries = 100LL * g.count + 1000;
  long long tries = 0;
  while (static_cast<int>(out.size() - first) < g.count) {
    if (++tries > max_tries)
      throw_invalid("the forest generator placed only " + std::to_string(out.size() - first) + " of " +
                        std::to_string(g.count) + " instances " + JsonReader::describe(g.min_spacing) +
                        " apart in its area; lower count/density or min_spacing, or enlarge the area",
                    {file, g.json_path, {}});
    const double x = g.area[0] + rng.uniform() * (g.area[2] - g.area[0]);
    const double y = g.area[1] + rng.uniform() * (g.area[3] - g.area[1]);
    const double yaw = g.yaw_degrees[0] + rng.uniform() * (g.yaw_degrees[1] - g.yaw_degrees[0]);
    const double scale = g.scale[0] + rng.uniform() * (g.scale[1] - g.scale[0]);
    double pick = rng.uniform() * total_weight;
    std::size_t m = 0;
    while (m + 1 < g.models.size() && pick >= g.models[m].second) pick -= g.models[m++].second;
    const long long cx = static_cast<long long>(std::floor(x / cell)), cy = static_cast<long long>(std::floor(y / cell));
    bool clear = true;
    if (g.min_spacing > 0)
      for (long long dx = -1; dx <= 1 && clear; ++dx)
        for (long long dy = -1; dy <= 1 && clear; ++dy) {
          const auto it = cells.find(key(cx + dx, cy + dy));
          if (it == cells.end()) continue;
          for (std::size_t k : it->second) {
            const double ex = out[k].position[0] - x, ey = out[k].position[1] - y;
            if (ex * ex + ey * ey < g.min_spacing * g.min_spacing) {
              clear = false;
              break;
            }
          }
        }
    if (!clear) continue;
    cells[key(cx, cy)].push_back(out.size());
    out.push_back({g.models[m].first, {x, y, g.height}, yaw, scale});
  }
  return out;
}

}  // namespace lblight
