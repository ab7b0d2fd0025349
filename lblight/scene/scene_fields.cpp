#include "lblight/scene/scene_fields.h"

#include <cstdio>
#include <stdexcept>

#include "lblight/lattice/lb_model.h"
#include "lblight/scene/forest.h"
#include "lblight/scene/material.h"
#include "lblight/scene/scene.h"

namespace lblight {
namespace {

using nlohmann::json;

std::string bound_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// Every range message states both bounds (a size of 1e10 told only "a positive length" before):
// a description without a "lo..hi" range gets the field's bounds appended.
FieldSpec number(const std::string& key, double lo, double hi, json fallback, const std::string& allowed) {
  FieldSpec f;
  f.key = key;
  f.kind = FieldKind::Number;
  f.lo = lo;
  f.hi = hi;
  f.fallback = std::move(fallback);
  f.allowed = allowed.find("..") != std::string::npos
                  ? allowed
                  : allowed + " (" + bound_text(lo) + ".." + bound_text(hi) + ")";
  return f;
}
FieldSpec integer(const std::string& key, double lo, double hi, json fallback, const std::string& allowed) {
  FieldSpec f = number(key, lo, hi, std::move(fallback), allowed);
  f.kind = FieldKind::Integer;
  return f;
}
FieldSpec boolean(const std::string& key, json fallback, const std::string& allowed) {
  FieldSpec f;
  f.key = key;
  f.kind = FieldKind::Boolean;
  f.fallback = std::move(fallback);
  f.allowed = allowed;
  return f;
}
FieldSpec text(const std::string& key, json fallback, std::vector<std::string> choices, const std::string& allowed) {
  FieldSpec f;
  f.key = key;
  f.kind = FieldKind::String;
  f.fallback = std::move(fallback);
  f.choices = std::move(choices);
  f.allowed = allowed;
  return f;
}
FieldSpec custom(const std::string& key, json schema, const std::string& allowed) {
  FieldSpec f;
  f.key = key;
  f.schema = std::move(schema);
  f.allowed = allowed;
  return f;
}
FieldSpec required(FieldSpec f) {
  f.required = true;
  return f;
}
json ref(const std::string& id) { return {{"$ref", "#/$defs/" + id}}; }
json array_of(json items, int min_items = 0, int max_items = -1) {
  json a = {{"type", "array"}, {"items", std::move(items)}};
  if (min_items > 0) a["minItems"] = min_items;
  if (max_items >= 0) a["maxItems"] = max_items;
  return a;
}
json numbers(int n, double lo, double hi) {
  return array_of({{"type", "number"}, {"minimum", lo}, {"maximum", hi}}, n, n);
}
json channel_values(double lo, double hi) {
  const json one = {{"type", "number"}, {"minimum", lo}, {"maximum", hi}};
  return {{"oneOf", {one, array_of(one, 3, 3)}}};
}
FieldSpec comment() { return custom("comment", json::object(), "anything (ignored)"); }
FieldSpec density_scale() { return number("density_scale", 0.0, 1e30, 1.0, "density_scale >= 0"); }
FieldSpec density_type(const char* type) {
  return required(custom("type", {{"const", type}}, std::string("\"") + type + "\""));
}

std::vector<ObjectSpec> build() {
  std::vector<ObjectSpec> t;
  json presets = json::array();
  for (const std::string& n : material_preset_names()) presets.push_back(n);
  const json material = {{"oneOf", {{{"enum", presets}}, ref("material")}}};
  const std::string degrees = "-90..90 degrees";

  t.push_back({"scene", "An lblight scene file, version 1 (docs/scene-format.md).",
               {required(custom("version", {{"const", 1}}, "1")),
                text("name", nullptr, {}, "any name (default: the file's stem)"),
                required(custom("models", array_of(ref("model"), 1), "a non-empty list of models with unique names")),
                custom("lighting", {{"oneOf", {ref("lighting.base"), ref("lighting.static")}}},
                       "base solutions (mode base, the default) or one static sun (mode static)"),
                custom("solver", ref("solver"), "solver settings"), custom("output", ref("output"), "what is written"),
                custom("forest", ref("forest"), "instances of the models, placed in a world (docs/forest.md)"),
                custom("ground", ref("ground"), "a reflective ground under the models and the forest (docs/model.md sec. 4.3)"),
                text("$schema", nullptr, {}, "the schema's address, for editors"), comment()}});
  t.push_back({"model", "One model: a density source, its materials and lattice margin.",
               {required(custom("name", {{"type", "string"}, {"pattern", "^[A-Za-z0-9_.-]{1,64}$"}},
                                "1-64 of A-Z a-z 0-9 _ - . (used as a file name)")),
                required(custom("density",
                                {{"oneOf", {ref("density.procedural"), ref("density.vdb"), ref("density.mesh"),
                                            ref("density.gas")}}},
                                "a procedural, vdb, mesh or gas density source")),
                required(custom("material", material, "a preset name or a material object")),
                custom("wood_material", material, "a preset name or a material object (default: the medium's wood)"),
                integer("margin", 1, 64, 1, "1..64 empty nodes around the density"),
                boolean("crop", true, "crop the lattice to the occupied box"),
                boolean("ground", true, "stands on the scene's ground (false: floats, no ground under it)")}});
  t.push_back({"ground", "A reflective ground: light arriving at it goes back up, diffusely (docs/model.md sec. 4.3).",
               {required(custom("albedo", channel_values(0, 1), "0..1, one number or [red, green, blue]")),
                number("height", -1e9, 1e9, 0.0, "-1e9..1e9 world units (the forest's ground; models stand on theirs)"),
                comment()}});
  t.push_back({"density.procedural", "A procedural density.",
               {density_type("procedural"), text("shape", "cloud", {"cloud", "plant", "box"}, "cloud, plant, box"),
                integer("resolution", 4, 1024, 48, "4..1024"),
                integer("seed", 0, 9007199254740992.0, 1, "0..2^53"),
                number("size", 1e-9, 1e9, 1.0, "a positive length"), density_scale()}});
  t.push_back({"density.vdb", "A density grid from an OpenVDB file.",
               {density_type("vdb"), required(text("path", nullptr, {}, "a .vdb file, relative to the scene file")),
                text("grid", "density", {}, "a float grid's name"),
                text("wood_grid", "", {}, "a float grid marking wood above 0.5 (empty: none)"), density_scale()}});
  t.push_back({"density.mesh", "A triangle mesh (OBJ) voxelised into density and wood.",
               {density_type("mesh"), required(text("path", nullptr, {}, "an .obj file, relative to the scene file")),
                integer("resolution", 4, 2048, 64, "4..2048"), integer("supersample", 1, 64, 8, "1..64"),
                custom("leaf_patterns", array_of({{"type", "string"}, {"minLength", 1}}), "a list of name patterns"),
                custom("wood_patterns", array_of({{"type", "string"}, {"minLength", 1}}), "a list of name patterns"),
                custom("bounds", ref("density.mesh.bounds"), "{min: [x, y, z], max: [x, y, z]}"),
                text("fill", "none", {"none", "parity", "winding"}, "none, parity, winding"), density_scale()}});
  t.push_back({"density.gas", "Smoke from the gas solver (docs/fluid.md): a box standing on z = 0 with an inlet in its floor.",
               {density_type("gas"),
                custom("resolution", array_of({{"type", "integer"}, {"minimum", 4}, {"maximum", 512}}, 3, 3),
                       "[nx, ny, nz] nodes, each 4..512"),
                number("size", 1e-6, 1e9, 1.0, "1e-6..1e9 world units along the longest edge"),
                number("tau", 0.503, 5.0, 0.56, "flow relaxation time, 0.503..5 (viscosity (tau - 1/2)/3)"),
                number("tau_temperature", 0.503, 5.0, 0.52, "0.503..5 (heat diffusivity (tau - 1/2)/4)"),
                number("tau_smoke", 0.503, 5.0, 0.51, "0.503..5 (smoke diffusivity (tau - 1/2)/4)"),
                number("ambient_temperature", -1e4, 1e4, 28.0, "degrees"),
                number("buoyancy", -1e-2, 1e-2, 2e-5, "lattice force per node per degree above ambient, |H g| <= 0.01"),
                custom("inlet", ref("density.gas.inlet"), "the inlet in the floor"),
                integer("frames", 1, 10000, 8, "1..10000"), integer("steps_per_frame", 1, 1000000, 50, "1..1000000"),
                integer("frame", 0, 10000, 0, "the frame a bake lights, 1..frames (0 = the last)"),
                custom("obstacles", array_of(ref("density.gas.obstacle")), "meshes the gas flows around"),
                density_scale()}});
  t.push_back({"density.gas.obstacle", "A mesh the gas flows around (bounce-back nodes).",
               {required(text("path", nullptr, {}, "an .obj file, relative to the scene file")),
                custom("position", numbers(3, -1e9, 1e9), "[x, y, z] world: where the mesh's origin goes"),
                number("scale", 1e-6, 1e6, 1.0, "1e-6..1e6 world units per mesh unit"),
                text("part", "all", {"all", "wood"}, "all, wood (the parts classified as wood)"),
                text("fill", "none", {"none", "parity", "winding"}, "none, parity, winding")}});
  t.push_back({"density.gas.inlet", "A round inlet in the floor, blowing upward.",
               {custom("center", numbers(2, -1e9, 1e9), "[x, y] world"),
                number("radius", 1e-9, 1e9, 0.1, "world units (at least one node)"),
                number("speed", 0.0, 0.1732, 0.05, "lattice units per step, at most Mach 0.3 (0.1732)"),
                number("temperature", -1e4, 1e4, 40.0, "degrees"), number("smoke", 0.0, 1e6, 1.0, "concentration >= 0")}});
  t.push_back({"density.mesh.bounds", "The box voxelised, in the mesh's units.",
               {required(custom("min", numbers(3, -1e30, 1e30), "[x, y, z]")),
                required(custom("max", numbers(3, -1e30, 1e30), "[x, y, z]"))}});
  t.push_back({"material", "Optical parameters per voxel length: one number or [red, green, blue] each.",
               {text("preset", nullptr, material_preset_names(), "a preset name"),
                text("name", nullptr, {}, "any name"), custom("sigma_a", channel_values(0, 1e300), "sigma_a >= 0"),
                custom("sigma_s", channel_values(0, 1e300), "sigma_s >= 0"),
                custom("g", channel_values(-1, 1), "-1 <= g <= 1"),
                boolean("absorb", nullptr, "whether absorbed light leaves the medium (default: the preset's)")}});
  t.push_back({"lighting.base", "Base solutions: the ambient and directional solutions a renderer relights from.",
               {text("mode", "base", {"base"}, "base"),
                custom("solutions",
                       {{"oneOf", {{{"type", "string"}}, array_of({{"type", "integer"}, {"minimum", 0}, {"maximum", 18}})}}},
                       "\"auto\", \"all\", a string like \"0,1,5-7\" or a list of indices 0..18"),
                custom("sun", {{"oneOf", {ref("sun.direction"), ref("sun.angles")}}}, "a fixed sun"),
                custom("sun_range", ref("sun_range"), "the elevations a renderer's sun can take"),
                text("instance_rotation", "none", {"none", "yaw", "any"}, "none, yaw (about the vertical axis), any"),
                boolean("ambient", true, "bake the ambient solution B00"),
                boolean("ambient_from_sum", true, "B00 as the sum of the directional solutions when all are baked")}});
  t.push_back({"lighting.static", "One static sun (and ambient) baked into a 'light' grid.",
               {required(text("mode", nullptr, {"static"}, "static")),
                required(custom("sun", {{"oneOf", {ref("sun.direction"), ref("sun.angles")}}}, "the sun")),
                number("intensity", 0.0, 1e30, 1.0, "intensity >= 0"), number("ambient", 0.0, 1e30, 0.0, "ambient >= 0")}});
  t.push_back({"sun.direction", "A direction toward the sun.",
               {required(custom("direction", numbers(3, -1e30, 1e30), "[x, y, z], non-zero"))}});
  t.push_back({"sun.angles", "A sun by elevation and azimuth.",
               {required(number("elevation", -90, 90, nullptr, degrees)),
                required(number("azimuth", -360, 360, nullptr, "-360..360 degrees"))}});
  t.push_back({"sun_range", "Elevations the sun can take.",
               {number("min_elevation", -90, 90, -90.0, degrees), number("max_elevation", -90, 90, 90.0, degrees)}});
  t.push_back({"solver", "How each base solution is solved (docs/accuracy.md, docs/model.md).",
               {custom("iterations",
                       {{"oneOf", {{{"enum", {"auto", "paper"}}}, {{"type", "integer"}, {"minimum", 1}, {"maximum", 100000000}}}}},
                       "auto, paper, or a step count 1..100000000"),
                number("tolerance", 1e-15, 0.5, 1e-4, "0 < tolerance <= 0.5"),
                integer("max_iterations", 1, 100000000, 0, "1..100000000 (default: from the lattice size)"),
                integer("check_interval", 1, 100000, 0, "1..100000 (default: from the lattice size)"),
                text("precision", "float32", {"float32", "float64", "float16"}, "float32, float64, float16"),
                text("method", "plain", {"plain", "bicgstab", "dsa"}, kSolverMethodNames),
                text("state", "auto", {"auto", "two-levels", "in-place"}, "auto, two-levels, in-place"),
                text("model", kDefaultLbModel, {"paper", "calibrated"}, "paper, calibrated"),
                custom("calibration", ref("solver.calibration"), "the calibrated model's corrections, each on or off")}});
  ObjectSpec calibration{"solver.calibration", "Corrections of the calibrated LB model (docs/model.md).", {}};
  for (const char* name : kCalibrationNames) calibration.fields.push_back(boolean(name, nullptr, "true or false"));
  t.push_back(calibration);
  t.push_back({"output", "What a bake writes (docs/output-format.md).",
               {boolean("vdb", true, "write one .vdb per model"),
                custom("lbh", {{"oneOf", {{{"type", "boolean"}}, ref("output.lbh")}}},
                       "true, false or {threshold, relative, coefficients}"),
                boolean("full_box", false, "light grids active over the whole lattice box"),
                boolean("half", false, "light grids as 16-bit floats"),
                boolean("moments", true, "the flux vector of every light grid as well (phase-aware rendering)"),
                boolean("nanovdb", false, "each model's grids also as NanoVDB (<model>.nvdb)")}});
  t.push_back({"output.lbh", "Haar-compressed sub-block streams (docs/lbh-format.md).",
               {number("threshold", 0.0, 1e30, 0.01, "threshold >= 0 (<= 1 when relative)"),
                boolean("relative", true, "threshold as a fraction of each solution's maximum"),
                text("coefficients", "auto", {"auto", "f32", "q8"}, "auto, f32, q8")}});
  t.push_back({"forest", "Instances of the scene's models (docs/forest.md).",
               {custom("instances", array_of(ref("forest.instance")), "a list of instances"),
                custom("generator", ref("forest.generator"), "a seeded placement generator"),
                custom("coarse", {{"oneOf", {{{"type", "boolean"}}, ref("forest.coarse")}}},
                       "false (no coarse grid) or {cell_size, tolerance}"),
                comment()}});
  t.push_back({"forest.coarse", "The coarse forest grid.",
               {number("cell_size", 1e-4, 1e6, 0.0,
                       "1e-4..1e6 world units (or leave it out: 2 x the coarsest model voxel x the largest scale)"),
                number("tolerance", 1e-8, 0.5, 1e-3, "1e-8..0.5"), comment()}});
  t.push_back({"forest.instance", "One placed instance.",
               {required(text("model", nullptr, {}, "one of the scene's models")),
                required(custom("position", numbers(3, -1e9, 1e9), "[x, y, z] within -1e9..1e9 world units")),
                number("yaw_degrees", -3600.0, 3600.0, 0.0, "-3600..3600 degrees"),
                number("scale", 1e-3, 1e3, 1.0, "1e-3..1e3")}});
  t.push_back({"forest.generator", "Seeded placement over an area: count or density, minimum spacing, ranges.",
               {required(custom("area", numbers(4, -1e9, 1e9), "[x_min, y_min, x_max, y_max]")),
                number("height", -1e9, 1e9, 0.0, "-1e9..1e9 world units"),
                integer("count", 1, kMaxForestInstances, nullptr, "1.." + std::to_string(kMaxForestInstances)),
                number("density", 1e-12, 1e9, nullptr, "> 0 instances per unit area"),
                number("min_spacing", 0.0, 1e9, 0.0, ">= 0 world units"),
                custom("yaw_degrees", numbers(2, -3600, 3600), "[low, high] within -3600..3600 degrees"),
                custom("scale", numbers(2, 1e-3, 1e3), "[low, high] within 1e-3..1e3"),
                required(custom("models", array_of(ref("forest.model_weight"), 1), "a non-empty list of {model, weight}")),
                integer("seed", 0, 4611686018427387904.0, 1, "0..2^62")}});
  t.push_back({"forest.model_weight", "A model of the generator's mix.",
               {required(text("model", nullptr, {}, "one of the scene's models")),
                number("weight", 1e-12, 1e12, 1.0, "> 0")}});
  return t;
}

json field_schema(const FieldSpec& f) {
  json s;
  switch (f.kind) {
    case FieldKind::Number:
    case FieldKind::Integer:
      s = {{"type", f.kind == FieldKind::Number ? "number" : "integer"}, {"minimum", f.lo}, {"maximum", f.hi}};
      if (f.fallback.is_number() && f.fallback.get<double>() >= f.lo && f.fallback.get<double>() <= f.hi)
        s["default"] = f.fallback;
      break;
    case FieldKind::Boolean:
      s = {{"type", "boolean"}};
      if (!f.fallback.is_null()) s["default"] = f.fallback;
      break;
    case FieldKind::String:
      s = {{"type", "string"}};
      if (!f.choices.empty()) s["enum"] = f.choices;
      if (!f.fallback.is_null()) s["default"] = f.fallback;
      break;
    case FieldKind::Custom: s = f.schema; break;
  }
  if (!f.allowed.empty()) s["description"] = f.allowed;
  return s;
}

json object_schema(const ObjectSpec& o) {
  json s = {{"type", "object"}, {"description", o.description}, {"additionalProperties", false}};
  json props = json::object(), req = json::array();
  for (const FieldSpec& f : o.fields) {
    props[f.key] = field_schema(f);
    if (f.required) req.push_back(f.key);
  }
  s["properties"] = props;
  if (!req.empty()) s["required"] = req;
  return s;
}

}  // namespace

const std::vector<ObjectSpec>& scene_objects() {
  static const std::vector<ObjectSpec> table = build();
  return table;
}

const ObjectSpec& scene_object(const std::string& id) {
  for (const ObjectSpec& o : scene_objects())
    if (o.id == id) return o;
  throw std::logic_error("no scene object table '" + id + "'");
}

const FieldSpec& ObjectSpec::field(const std::string& key) const {
  for (const FieldSpec& f : fields)
    if (f.key == key) return f;
  throw std::logic_error("no field '" + key + "' in the scene object table '" + id + "'");
}

void check_fields(const JsonReader& r, const ObjectSpec& o) {
  r.expect_object();
  for (auto it = r.json().begin(); it != r.json().end(); ++it) {
    bool ok = false;
    for (const FieldSpec& f : o.fields) ok = ok || it.key() == f.key;
    if (ok) continue;
    std::string list;
    for (const FieldSpec& f : o.fields) list += (list.empty() ? "" : ", ") + f.key;
    r.fail("unknown field '" + it.key() + "'; allowed fields here: " + list, it.key());
  }
}

double number_field(const JsonReader& r, const ObjectSpec& o, const std::string& key) {
  const FieldSpec& f = o.field(key);
  if (f.fallback.is_null()) return r.number(key, f.lo, f.hi, f.allowed);
  return r.number_or(key, f.fallback.get<double>(), f.lo, f.hi, f.allowed);
}

long long integer_field(const JsonReader& r, const ObjectSpec& o, const std::string& key) {
  const FieldSpec& f = o.field(key);
  const long long fallback = f.fallback.is_null() ? 0 : f.fallback.get<long long>();
  if (f.fallback.is_null() && !r.has(key)) r.fail("required field '" + key + "' is missing; allowed: " + f.allowed, key);
  return r.integer_or(key, fallback, static_cast<long long>(f.lo), static_cast<long long>(f.hi));
}

bool boolean_field(const JsonReader& r, const ObjectSpec& o, const std::string& key) {
  const FieldSpec& f = o.field(key);
  return r.boolean_or(key, f.fallback.is_boolean() && f.fallback.get<bool>());
}

std::string string_field(const JsonReader& r, const ObjectSpec& o, const std::string& key) {
  const FieldSpec& f = o.field(key);
  if (f.fallback.is_null()) return r.string(key);
  return r.string_or(key, f.fallback.get<std::string>());
}

json scene_json_schema() {
  json defs = json::object();
  for (const ObjectSpec& o : scene_objects())
    if (o.id != "scene") defs[o.id] = object_schema(o);
  json s = object_schema(scene_object("scene"));
  s["$schema"] = "https://json-schema.org/draft/2020-12/schema";
  s["title"] = "lblight scene file, version 1";
  s["$comment"] = "Generated by `lblight schema` from the parser's field tables (lblight/scene/scene_fields.h). "
                  "Checks fields, types, ranges and choices; the parser also checks what a schema cannot (model "
                  "names unique and referred to, count or density, stability rules).";
  s["$defs"] = defs;
  return s;
}

}  // namespace lblight
