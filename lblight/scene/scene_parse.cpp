// Scene file v1 parser. Every rejection names file, JSON pointer, value and what is allowed.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "lblight/core/hash.h"
#include "lblight/core/input_file.h"
#include "lblight/scene/json_reader.h"
#include "lblight/lattice/dense_grid.h"
#include "lblight/scene/scene.h"
#include "lblight/scene/scene_fields.h"

namespace lblight {

const char* to_string(IterationMode mode) {
  switch (mode) {
    case IterationMode::Auto: return "auto";
    case IterationMode::Paper: return "paper";
    case IterationMode::Fixed: return "fixed";
  }
  return "?";
}

const char* to_string(SolverMethod method) {
  switch (method) {
    case SolverMethod::BiCGStab: return "bicgstab";
    case SolverMethod::Dsa: return "dsa";
    default: return "plain";
  }
}

std::optional<SolverMethod> parse_solver_method(const std::string& name) {
  for (SolverMethod m : {SolverMethod::Plain, SolverMethod::BiCGStab, SolverMethod::Dsa})
    if (name == to_string(m)) return m;
  return std::nullopt;
}

std::optional<StateLayout> parse_state_layout(const std::string& name) {
  for (StateLayout s : {StateLayout::TwoLevels, StateLayout::InPlace})
    if (name == to_string(s)) return s;
  return std::nullopt;
}

const char* to_string(SourceType type) {
  switch (type) {
    case SourceType::Procedural: return "procedural";
    case SourceType::Vdb: return "vdb";
    case SourceType::Mesh: return "mesh";
    case SourceType::Gas: return "gas";
  }
  return "?";
}

std::vector<int> parse_solution_list(const std::string& text, const Location& where) {
  std::string t;
  for (char c : text)
    if (!std::isspace(static_cast<unsigned char>(c)) && c != '[' && c != ']') t += c;
  std::set<int> out;
  auto bad = [&](const std::string& why) {
    throw_invalid("solutions '" + text + "': " + why + "; allowed: all, or indices 0..18 and ranges like 0,1,5-7",
                  where);
  };
  if (t == "all") {
    for (int i = 0; i < 19; ++i) out.insert(i);
  } else {
    if (t.empty()) bad("empty list");
    std::stringstream ss(t);
    std::string item;
    while (std::getline(ss, item, ',')) {
      if (item.empty()) bad("empty item");
      const auto dash = item.find('-', 1);
      try {
        std::size_t used = 0;
        const int lo = std::stoi(item.substr(0, dash), &used);
        if (used != item.substr(0, dash).size()) bad("'" + item + "' is not an index");
        int hi = lo;
        if (dash != std::string::npos) {
          const std::string rest = item.substr(dash + 1);
          hi = std::stoi(rest, &used);
          if (used != rest.size()) bad("'" + item + "' is not a range");
        }
        if (lo < 0 || hi > 18 || lo > hi) bad("'" + item + "' is outside 0..18");
        for (int i = lo; i <= hi; ++i) out.insert(i);
      } catch (const std::logic_error&) {
        bad("'" + item + "' is not an index");
      }
    }
  }
  return {out.begin(), out.end()};
}

namespace {

bool valid_name(const std::string& s) {
  if (s.empty() || s.size() > 64) return false;
  for (char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) return false;
  return s != "." && s != "..";
}

// sigma_a, sigma_s, g: one number for all channels or [r, g, b]; checked per docs/model.md sec. 6.
void read_channel_values(const JsonReader& mat, const std::string& key, const std::string& material_name,
                         Material& m) {
  const JsonReader v = mat.child(key);
  double lo = 0.0, hi = 1e300;
  std::string allowed = key + " >= 0";
  if (key == "g") {
    lo = -1.0;
    hi = 1.0;
    allowed = "-1 <= g <= 1";
  }
  auto assign = [&](int c, double value) {
    OpticalParams& p = m.channel[c];
    (key == "sigma_a" ? p.sigma_a : key == "sigma_s" ? p.sigma_s : p.g) = value;
  };
  auto check = [&](const JsonReader& node, int channel_or_all) {
    const std::string which = channel_or_all < 0 ? "all channels" : std::string("channel ") + kChannelNames[channel_or_all];
    if (!node.json().is_number())
      node.fail("material '" + material_name + "', " + which + ": " + key + " must be a number, found " +
                JsonReader::describe(node.json()) + "; allowed: " + allowed);
    const double x = node.json().get<double>();
    if (!std::isfinite(x) || x < lo || x > hi)
      node.fail("material '" + material_name + "', " + which + ": " + key + " = " + JsonReader::describe(node.json()) +
                " is out of range; allowed: " + allowed);
    return x;
  };
  if (v.json().is_array()) {
    if (v.json().size() != kChannels)
      v.fail("material '" + material_name + "': " + key + " must be one number or [red, green, blue], found " +
             JsonReader::describe(v.json()));
    for (int c = 0; c < kChannels; ++c) assign(c, check(v.element(static_cast<std::size_t>(c)), c));
  } else {
    const double x = check(v, -1);
    for (int c = 0; c < kChannels; ++c) assign(c, x);
  }
}

std::string preset_list() {
  std::string s;
  for (const auto& n : material_preset_names()) s += (s.empty() ? "" : ", ") + n;
  return s;
}

Material read_material(const JsonReader& r) {
  if (r.json().is_string()) {
    const std::string name = r.json().get<std::string>();
    auto preset = material_preset(name);
    if (!preset) r.fail("unknown material preset '" + name + "'; allowed: " + preset_list());
    return *preset;
  }
  if (!r.json().is_object())
    r.fail("a material is a preset name or an object with preset/sigma_a/sigma_s/g/absorb, found " +
           JsonReader::describe(r.json()));
  check_fields(r, scene_object("material"));
  Material m;
  const bool has_preset = r.has("preset");
  if (has_preset) {
    const std::string name = r.string("preset");
    auto preset = material_preset(name);
    if (!preset) r.fail("unknown material preset '" + name + "'; allowed: " + preset_list(), "preset");
    m = *preset;
  } else {
    for (const char* k : {"sigma_a", "sigma_s", "g"})
      if (!r.has(k)) r.fail(std::string("material without a preset needs '") + k + "'", k);
  }
  m.name = r.string_or("name", has_preset ? m.name : "custom");
  for (const char* k : {"sigma_a", "sigma_s", "g"})
    if (r.has(k)) read_channel_values(r, k, m.name, m);
  m.absorbs = r.boolean_or("absorb", m.absorbs);
  return m;
}

DensitySpec read_density(const JsonReader& r, const std::filesystem::path& dir) {
  r.expect_object();
  DensitySpec d;
  d.json_path = r.path();
  const std::string type = r.string("type");
  if (type == "procedural") {
    const ObjectSpec& o = scene_object("density.procedural");
    check_fields(r, o);
    d.type = SourceType::Procedural;
    d.procedural.shape = string_field(r, o, "shape");
    if (d.procedural.shape != "cloud" && d.procedural.shape != "plant" && d.procedural.shape != "box")
      r.fail("unknown procedural shape '" + d.procedural.shape + "'; allowed: cloud, plant, box", "shape");
    d.procedural.resolution = static_cast<int>(integer_field(r, o, "resolution"));
    d.procedural.seed = static_cast<std::uint64_t>(integer_field(r, o, "seed"));
    d.procedural.size = number_field(r, o, "size");
    if (d.procedural.size / d.procedural.resolution < kMinNodeSize)
      r.fail("size " + message_number(d.procedural.size) + " at resolution " +
                 std::to_string(d.procedural.resolution) + " makes nodes narrower than " +
                 message_number(kMinNodeSize) + " world units, which OpenVDB transforms cannot hold; " +
                 "allowed: size >= resolution x " + message_number(kMinNodeSize),
             "size");
  } else if (type == "vdb") {
    const ObjectSpec& o = scene_object("density.vdb");
    check_fields(r, o);
    d.type = SourceType::Vdb;
    const std::filesystem::path p = string_field(r, o, "path");
    d.vdb.path = p.is_absolute() ? p : dir / p;
    d.vdb.grid = string_field(r, o, "grid");
    d.vdb.wood_grid = string_field(r, o, "wood_grid");
  } else if (type == "mesh") {
    const ObjectSpec& o = scene_object("density.mesh");
    check_fields(r, o);
    d.type = SourceType::Mesh;
    const std::filesystem::path p = string_field(r, o, "path");
    d.mesh.path = p.is_absolute() ? p : dir / p;
    d.mesh.resolution = static_cast<int>(integer_field(r, o, "resolution"));
    d.mesh.supersample = static_cast<int>(integer_field(r, o, "supersample"));
    for (const char* key : {"leaf_patterns", "wood_patterns"}) {
      if (!r.has(key)) continue;
      const JsonReader list = r.child(key);
      if (!list.json().is_array()) list.fail("expected a list of name patterns");
      auto& out = std::string(key) == "leaf_patterns" ? d.mesh.leaf_patterns : d.mesh.wood_patterns;
      for (std::size_t i = 0; i < list.json().size(); ++i) {
        const JsonReader e = list.element(i);
        if (!e.json().is_string() || e.json().get<std::string>().empty()) e.fail("expected a non-empty string");
        out.push_back(e.json().get<std::string>());
      }
    }
    if (r.has("bounds")) {
      const JsonReader b = r.child("bounds");
      check_fields(b, scene_object("density.mesh.bounds"));
      for (const char* key : {"min", "max"}) {
        const JsonReader v = b.child(key);
        if (!v.json().is_array() || v.json().size() != 3) v.fail("expected [x, y, z]");
        for (std::size_t i = 0; i < 3; ++i)
          (std::string(key) == "min" ? d.mesh.bounds_min : d.mesh.bounds_max)[i] =
              v.element(i).as_number(-1e30, 1e30, "a finite coordinate");
      }
      for (int i = 0; i < 3; ++i)
        if (!(d.mesh.bounds_max[i] > d.mesh.bounds_min[i])) b.fail("bounds max must exceed min on every axis");
      d.mesh.has_bounds = true;
    }
    d.mesh.fill = string_field(r, o, "fill");
    if (d.mesh.fill != "none" && d.mesh.fill != "parity" && d.mesh.fill != "winding")
      r.fail("unknown fill mode '" + d.mesh.fill + "'; allowed: none, parity, winding", "fill");
  } else if (type == "gas") {
    const ObjectSpec& o = scene_object("density.gas");
    check_fields(r, o);
    d.type = SourceType::Gas;
    GasSource& g = d.gas;
    if (r.has("resolution")) {
      const JsonReader v = r.child("resolution");
      if (!v.json().is_array() || v.json().size() != 3) v.fail("expected [nx, ny, nz], found " + JsonReader::describe(v.json()));
      for (std::size_t k = 0; k < 3; ++k) {
        const JsonReader e = v.element(k);
        if (!e.json().is_number_integer() || e.json().get<long long>() < 4 || e.json().get<long long>() > 512)
          e.fail("gas resolution " + JsonReader::describe(e.json()) + "; allowed: an integer 4..512");
        g.resolution[k] = e.json().get<int>();
      }
    }
    g.size = number_field(r, o, "size");
    g.tau = number_field(r, o, "tau");
    g.tau_temperature = number_field(r, o, "tau_temperature");
    g.tau_smoke = number_field(r, o, "tau_smoke");
    g.ambient_temperature = number_field(r, o, "ambient_temperature");
    g.buoyancy = number_field(r, o, "buoyancy");
    g.frames = static_cast<int>(integer_field(r, o, "frames"));
    g.steps_per_frame = static_cast<int>(integer_field(r, o, "steps_per_frame"));
    g.frame = static_cast<int>(integer_field(r, o, "frame"));
    if (g.frame > g.frames) r.fail("frame " + std::to_string(g.frame) + " is after the last; allowed: 1.." + std::to_string(g.frames) + " (0 = the last)", "frame");
    if (r.has("obstacles")) {
      const JsonReader list = r.child("obstacles");
      if (!list.json().is_array()) list.fail("expected a list of obstacles, found " + JsonReader::describe(list.json()));
      const ObjectSpec& ob = scene_object("density.gas.obstacle");
      for (std::size_t k = 0; k < list.json().size(); ++k) {
        const JsonReader e = list.element(k);
        check_fields(e, ob);
        GasObstacle o;
        const std::filesystem::path p = string_field(e, ob, "path");
        o.path = p.is_absolute() ? p : dir / p;
        if (e.has("position")) {
          const std::vector<double> v = e.child("position").as_numbers(3, "[x, y, z]", -1e9, 1e9, "a finite coordinate");
          std::copy(v.begin(), v.end(), o.position.begin());
        }
        o.scale = number_field(e, ob, "scale");
        o.part = string_field(e, ob, "part");
        if (o.part != "all" && o.part != "wood") e.fail("unknown part '" + o.part + "'; allowed: all, wood", "part");
        o.fill = string_field(e, ob, "fill");
        if (o.fill != "none" && o.fill != "parity" && o.fill != "winding")
          e.fail("unknown fill mode '" + o.fill + "'; allowed: none, parity, winding", "fill");
        g.obstacles.push_back(o);
      }
    }
    if (r.has("inlet")) {
      const JsonReader in = r.child("inlet");
      const ObjectSpec& io = scene_object("density.gas.inlet");
      check_fields(in, io);
      if (in.has("center")) {
        const std::vector<double> c = in.child("center").as_numbers(2, "[x, y]", -1e9, 1e9, "a finite coordinate");
        std::copy(c.begin(), c.end(), g.inlet_center.begin());
      }
      g.inlet_radius = number_field(in, io, "radius");
      g.inlet_speed = number_field(in, io, "speed");
      g.inlet_temperature = number_field(in, io, "temperature");
      g.inlet_smoke = number_field(in, io, "smoke");
    }
  } else {
    r.fail("unknown density type '" + type + "'; allowed: procedural, vdb, mesh, gas", "type");
  }
  d.density_scale = number_field(r, scene_object("density.procedural"), "density_scale");  // the same in every source
  return d;
}

ModelSpec read_model(const JsonReader& r, const std::filesystem::path& dir, const LbModel& lb_model) {
  const ObjectSpec& o = scene_object("model");
  check_fields(r, o);
  ModelSpec m;
  m.json_path = r.path();
  m.name = r.string("name");
  if (!valid_name(m.name))
    r.fail("model name '" + m.name + "' is not usable as a file name; allowed: 1-64 of A-Z a-z 0-9 _ - .", "name");
  m.density = read_density(r.child("density"), dir);
  m.material = read_material(r.child("material"));
  m.wood_material = r.has("wood_material") ? read_material(r.child("wood_material")) : default_wood(m.material, lb_model.calibrated);
  m.margin = static_cast<int>(integer_field(r, o, "margin"));
  m.crop = boolean_field(r, o, "crop");
  m.ground = boolean_field(r, o, "ground");
  return m;
}

// "ground": {"albedo": A or [r, g, b], "height": z}
GroundSpec read_ground(const JsonReader& r) {
  const ObjectSpec& o = scene_object("ground");
  r.expect_object();
  check_fields(r, o);
  GroundSpec g;
  g.enabled = true;
  g.height = number_field(r, o, "height");
  const JsonReader a = r.child("albedo");
  const std::string allowed = o.field("albedo").allowed;
  if (a.json().is_array()) {
    const std::vector<double> v = a.as_numbers(3, "[red, green, blue]", 0.0, 1.0, allowed);
    g.albedo = {v[0], v[1], v[2]};
  } else {
    g.albedo.fill(a.as_number(0.0, 1.0, allowed));
  }
  return g;
}

Vec3d read_vec3(const JsonReader& r) {
  const std::vector<double> v = r.as_numbers(3, "[x, y, z]", -1e30, 1e30, "a finite number");
  return {v[0], v[1], v[2]};
}

// {"direction": [x, y, z]} or {"elevation": deg, "azimuth": deg}: a unit vector toward the sun.
Vec3d read_sun(const JsonReader& sun) {
  sun.expect_object();
  if (sun.has("direction")) {
    check_fields(sun, scene_object("sun.direction"));
    Vec3d d = read_vec3(sun.child("direction"));
    const double len = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    if (!(len > 0)) sun.fail("sun direction must be non-zero", "direction");
    return {d.x / len, d.y / len, d.z / len};
  }
  const ObjectSpec& o = scene_object("sun.angles");
  check_fields(sun, o);
  const double el = number_field(sun, o, "elevation");
  const double az = number_field(sun, o, "azimuth");
  return toward_sun_from_angles(el, az);
}

// Base lighting: which solutions to bake, either listed ("all", "0,1,5-7", [0, 6]) or "auto":
// the ones the declared sun range, fixed sun and instance rotation can select (docs/model.md sec. 4).
void read_base_lighting(const JsonReader& r, LightingSpec& l) {
  const ObjectSpec& o = scene_object("lighting.base");
  check_fields(r, o);
  l.mode = LightingMode::Base;
  SunConstraints& c = l.sun_constraints;
  if (r.has("sun_range")) {
    const JsonReader sr = r.child("sun_range");
    sr.expect_object();
    const ObjectSpec& range = scene_object("sun_range");
    check_fields(sr, range);
    c.min_elevation = number_field(sr, range, "min_elevation");
    c.max_elevation = number_field(sr, range, "max_elevation");
    if (c.max_elevation < c.min_elevation) sr.fail("max_elevation must be >= min_elevation", "max_elevation");
  }
  if (r.has("sun")) {
    if (r.has("sun_range")) r.fail("give either a fixed sun or a sun_range, not both", "sun");
    c.fixed_toward_sun = read_sun(r.child("sun"));
  }
  const std::string rot = string_field(r, o, "instance_rotation");
  if (rot == "any") c.rotation = InstanceRotation::Any;
  else if (rot == "yaw") c.rotation = InstanceRotation::Yaw;
  else if (rot == "none") c.rotation = InstanceRotation::None;
  else r.fail("unknown instance_rotation '" + rot + "'; allowed: none, yaw (about the vertical axis), any", "instance_rotation");
  c.ambient = boolean_field(r, o, "ambient");
  l.ambient_from_sum = boolean_field(r, o, "ambient_from_sum");

  const bool constrained =
      r.has("sun_range") || r.has("sun") || r.has("ambient") || r.has("instance_rotation");
  std::string listed = "auto";
  if (r.has("solutions")) {
    const JsonReader s = r.child("solutions");
    if (s.json().is_string()) {
      listed = s.json().get<std::string>();
      if (listed != "auto") l.solutions = parse_solution_list(listed, s.location());
    } else if (s.json().is_array()) {
      std::string text;
      for (std::size_t i = 0; i < s.json().size(); ++i) {
        const JsonReader e = s.element(i);
        if (!e.json().is_number_integer()) e.fail("expected a solution index 0..18, found " + JsonReader::describe(e.json()));
        text += (i ? "," : "") + std::to_string(e.json().get<long long>());
      }
      l.solutions = parse_solution_list(text, s.location());
      listed = text;
    } else {
      s.fail("expected \"auto\", \"all\", a string like \"0,1,5-7\" or a list of indices");
    }
    if (listed != "auto" && constrained)
      s.fail("the solutions are listed and also follow from sun/sun_range/instance_rotation/ambient; give one of them "
             "(\"solutions\": \"auto\" bakes what the sun declarations need)");
  }
  l.solutions_from_sun = listed == "auto";
  if (l.solutions_from_sun) {
    const std::array<bool, 19> need = needed_base_solutions(c);
    l.solutions.clear();
    for (int j = 0; j < 19; ++j)
      if (need[static_cast<std::size_t>(j)]) l.solutions.push_back(j);
    if (l.solutions.empty()) r.fail("no base solution is needed (no sun direction in range and ambient false)");
  }
}

LightingSpec read_lighting(const JsonReader& r) {
  LightingSpec l;
  r.expect_object();
  const std::string mode = r.string_or("mode", "base");
  if (mode == "base") {
    read_base_lighting(r, l);
  } else if (mode == "static") {
    const ObjectSpec& o = scene_object("lighting.static");
    check_fields(r, o);
    l.mode = LightingMode::Static;
    l.toward_sun = read_sun(r.child("sun"));
    l.intensity = number_field(r, o, "intensity");
    l.ambient = number_field(r, o, "ambient");
  } else {
    r.fail("unknown lighting mode '" + mode + "'; allowed: base, static", "mode");
  }
  return l;
}

SolverSpec read_solver(const JsonReader& r) {
  const ObjectSpec& o = scene_object("solver");
  check_fields(r, o);
  SolverSpec s;
  if (r.has("iterations")) {
    const JsonReader it = r.child("iterations");
    if (it.json().is_string()) {
      const std::string v = it.json().get<std::string>();
      if (v == "auto") s.mode = IterationMode::Auto;
      else if (v == "paper") s.mode = IterationMode::Paper;
      else it.fail("unknown iteration mode '" + v + "'; allowed: auto, paper, or a step count 1..100000000");
    } else if (it.json().is_number_integer()) {
      const long long n = it.json().get<long long>();
      if (n < 1 || n > 100000000) it.fail("step count " + std::to_string(n) + " is out of range; allowed: 1..100000000");
      s.mode = IterationMode::Fixed;
      s.iterations = static_cast<int>(n);
    } else {
      it.fail("expected \"auto\", \"paper\" or a step count, found " + JsonReader::describe(it.json()));
    }
  }
  s.tolerance = number_field(r, o, "tolerance");
  if (r.has("tolerance") && !(s.tolerance > 0)) r.fail("tolerance must be > 0", "tolerance");
  s.max_iterations = static_cast<int>(integer_field(r, o, "max_iterations"));
  s.check_interval = static_cast<int>(integer_field(r, o, "check_interval"));
  const std::string method = string_field(r, o, "method");
  if (const auto m = parse_solver_method(method)) s.method = *m;
  else r.fail("unknown solver method '" + method + "'; allowed: " + kSolverMethodNames, "method");
  if (s.method != SolverMethod::Plain && s.mode != IterationMode::Auto)
    r.fail("method " + method + " needs iterations \"auto\" (it stops on the error estimate)", "method");
  const std::string prec = string_field(r, o, "precision");
  if (prec == "float32") s.precision = Precision::Float32;
  else if (prec == "float64") s.precision = Precision::Float64;
  else if (prec == "float16") s.precision = Precision::Float16;
  else r.fail("unknown precision '" + prec + "'; allowed: float32, float64, float16", "precision");
  const std::string state = string_field(r, o, "state");
  if (const auto layout = parse_state_layout(state)) s.state = *layout;
  else if (state != "auto") r.fail("unknown state layout '" + state + "'; allowed: auto, two-levels, in-place", "state");
  const std::string model = string_field(r, o, "model");
  if (model == "calibrated") s.model.calibrated = true;
  else if (model != "paper") r.fail("unknown LB model '" + model + "'; allowed: paper, calibrated", "model");
  if (r.has("calibration")) {
    if (!s.model.calibrated) r.fail("calibration applies to \"model\": \"calibrated\"", "calibration");
    const JsonReader c = r.child("calibration");
    check_fields(c, scene_object("solver.calibration"));  // kCalibrationNames
    for (int k = 0; k < static_cast<int>(kCalibrationNames.size()); ++k)
      *calibration_switch(s.model, k) = c.boolean_or(kCalibrationNames[k], *calibration_switch(s.model, k));
    if (s.model.first_collision && s.method == SolverMethod::Dsa)
      c.fail("first_collision solves B00's scattered light from a volume source, which method dsa does not take; "
             "allowed: \"method\": \"plain\" or \"bicgstab\"", "first_collision");
    if (s.model.first_collision && !(s.model.isotropic_ambient && s.model.remove_absorbed))
      c.fail("first_collision builds on isotropic_ambient (B00 is isotropic light) and remove_absorbed (no f_0 "
             "reservoir to feed); switch those on or first_collision off", "first_collision");
  }
  return s;
}

// "output": {"vdb": true|false, "lbh": {"threshold": T, "relative": true|false}}; "lbh": true
// takes the defaults.
OutputSpec read_output(const JsonReader& r) {
  r.expect_object();
  const ObjectSpec& o = scene_object("output");
  check_fields(r, o);
  OutputSpec out;
  out.vdb = boolean_field(r, o, "vdb");
  out.full_box = boolean_field(r, o, "full_box");
  out.half = boolean_field(r, o, "half");
  out.moments = boolean_field(r, o, "moments");
  out.nanovdb = boolean_field(r, o, "nanovdb");
  if (out.nanovdb && !out.vdb) r.fail("nanovdb converts each model's .vdb: it needs vdb true", "nanovdb");
  if (!r.has("lbh")) {
    if (!out.vdb) r.fail("nothing to write: vdb is false and no lbh output is asked for", "vdb");
    return out;
  }
  const JsonReader lbh = r.child("lbh");
  if (lbh.json().is_boolean()) {
    out.lbh.enabled = lbh.json().get<bool>();
    if (!out.vdb && !out.lbh.enabled) r.fail("nothing to write: vdb and lbh are both false", "vdb");
    return out;
  }
  if (!lbh.json().is_object())
    r.fail("expected true, false or an object {\"threshold\": number, \"relative\": bool}", "lbh");
  const ObjectSpec& lo = scene_object("output.lbh");
  check_fields(lbh, lo);
  out.lbh.enabled = true;
  out.lbh.relative = boolean_field(lbh, lo, "relative");
  out.lbh.threshold = out.lbh.relative ? lbh.number_or("threshold", 0.01, 0.0, 1.0, "0 <= threshold <= 1 (a fraction "
                                                                                     "of each solution's maximum)")
                                       : lbh.number_or("threshold", 0.01, 0.0, 1e30, "threshold >= 0");
  if (lbh.has("coefficients")) {
    const JsonReader c = lbh.child("coefficients");
    const auto parsed = parse_lbh_coefficients(c.json().is_string() ? c.json().get<std::string>() : std::string());
    if (!parsed)
      c.fail("coefficient storage " + c.json().dump() + " is not allowed; allowed: \"auto\" (8-bit details when "
             "the threshold is > 0), \"f32\" (every kept coefficient as float), \"q8\" (8-bit details)");
    out.lbh.coefficients = *parsed;
  }
  return out;
}

}  // namespace

Scene parse_scene(const std::string& text, const std::filesystem::path& file) {
  const nlohmann::json j = JsonReader::parse_strict(text, file.string());
  const JsonReader root(j, "", file.string());
  root.expect_object();
  check_fields(root, scene_object("scene"));
  Scene scene;
  scene.file = file;
  scene.dir = file.has_parent_path() ? file.parent_path() : std::filesystem::path(".");
  if (!root.has("version")) root.fail("required field 'version' is missing; this lblight reads version 1", "version");
  const long long version = root.integer_or("version", 1, 1, 1000000);
  if (version != kSceneVersion)
    root.fail("scene version " + std::to_string(version) + " is not supported; allowed: 1", "version");
  scene.name = root.string_or("name", file.stem().string());
  // The solver first: a model's default wood depends on the LB model (docs/model.md, "Wood").
  if (root.has("solver")) scene.solver = read_solver(root.child("solver"));
  else scene.solver.model.calibrated = std::string(kDefaultLbModel) == "calibrated";
  const JsonReader models = root.child("models");
  if (!models.json().is_array() || models.json().empty()) models.fail("expected a non-empty list of models");
  std::set<std::string> names;
  for (std::size_t i = 0; i < models.json().size(); ++i) {
    ModelSpec m = read_model(models.element(i), scene.dir, scene.solver.model);
    if (!names.insert(m.name).second)
      models.element(i).fail("model name '" + m.name + "' is used twice; names must be unique", "name");
    scene.models.push_back(std::move(m));
  }
  if (root.has("lighting")) scene.lighting = read_lighting(root.child("lighting"));
  else scene.lighting.solutions = parse_solution_list("all", root.location());  // "auto" with no constraints
  if (root.has("output")) scene.output = read_output(root.child("output"));
  if (root.has("ground")) scene.ground = read_ground(root.child("ground"));
  if (root.has("forest")) {
    scene.forest = read_forest(root.child("forest"), names, scene.lighting.sun_constraints.rotation);
    // generated instances stand on the ground unless the generator says otherwise
    const JsonReader forest = root.child("forest");
    if (scene.forest.generator && scene.ground.enabled && !(forest.has("generator") && forest.child("generator").has("height")))
      scene.forest.generator->height = scene.ground.height;
    // The coarse forest lattices are written as forest.vdb and forest.alone.<model>.vdb.
    for (std::size_t i = 0; i < scene.models.size(); ++i) {
      const std::string& n = scene.models[i].name;
      if (n == "forest" || n.rfind("forest.", 0) == 0)
        models.element(i).fail("model name '" + n + "' is taken by the coarse forest grid's files (forest.vdb, "
                               "forest.alone.<model>.vdb) in a scene with a forest; rename the model",
                               "name");
    }
  }
  scene.hash = "fnv1a64:" + hex64(fnv1a64(j.dump()));
  return scene;
}

Scene load_scene(const std::filesystem::path& file) {
  return parse_scene(read_input_file(file, "scene file", kMaxSceneBytes), file);
}

std::vector<std::filesystem::path> scene_input_files(const Scene& scene) {
  std::vector<std::filesystem::path> files = {scene.file};
  for (const ModelSpec& m : scene.models) {
    const DensitySpec& d = m.density;
    if (d.type == SourceType::Vdb) files.push_back(d.vdb.path);
    if (d.type == SourceType::Mesh) files.push_back(d.mesh.path);
    if (d.type == SourceType::Gas)
      for (const GasObstacle& o : d.gas.obstacles) files.push_back(o.path);
  }
  return files;
}

}  // namespace lblight
