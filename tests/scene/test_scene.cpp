// Scene file v1: what parses, and how bad input is named.
#include <catch2/catch.hpp>

#include <algorithm>

#include "lblight/core/error.h"
#include "lblight/lattice/omega.h"
#include "lblight/scene/load_model.h"
#include "lblight/scene/scene.h"
#include "lblight/solve/plan.h"
#include "tests/support/expect_error.h"
#include "tests/support/test_support.h"

using namespace lblight;
using lblight::test::expect_invalid_input;

namespace {
const char* kMinimal = R"({
  "version": 1,
  "models": [{"name": "c", "density": {"type": "procedural", "shape": "cloud", "resolution": 12}, "material": "cloud"}]
})";

// Parses `text`, which must fail as input naming scene.json, and returns the error's JSON path
// ("" when the error names the file only).
std::string error_path(const std::string& text) {
  const Error e = expect_invalid_input([&] { parse_scene(text, "scene.json"); }, "");
  CHECK(e.where().file == "scene.json");
  return e.where().json_path;
}

std::string with_model_field(const std::string& field) {
  return std::string(R"({"version": 1, "models": [{"name": "c", "density": {"type": "procedural"}, )") + field + "}]}";
}
}  // namespace

TEST_CASE("A minimal scene parses with documented defaults", "[scene]") {
  const Scene s = parse_scene(kMinimal, "dir/scene.json");
  REQUIRE(s.models.size() == 1);
  CHECK(s.name == "scene");
  CHECK(s.dir == "dir");
  CHECK(s.models[0].margin == 1);
  CHECK(s.models[0].material.name == "cloud");
  CHECK(s.solver.model.calibrated);  // physical light by default (docs/scene-format.md, "model")
  CHECK(s.models[0].wood_material.name == "bark");
  CHECK(s.models[0].wood_material.absorbs);
  // the papers' model keeps the papers' wood: the medium's sigmas, g = -1, nothing absorbed
  const Scene paper = parse_scene(std::string(kMinimal).insert(1, R"("solver": {"model": "paper"},)"), "scene.json");
  CHECK_FALSE(paper.solver.model.calibrated);
  CHECK(paper.models[0].wood_material.channel[0].g == -1.0);
  CHECK(paper.models[0].wood_material.channel[0].sigma_s == paper.models[0].material.channel[0].sigma_s);
  CHECK_FALSE(paper.models[0].wood_material.absorbs);
  CHECK(s.lighting.mode == LightingMode::Base);
  CHECK(s.lighting.solutions.size() == 19);
  CHECK(s.solver.mode == IterationMode::Auto);
  CHECK(s.solver.tolerance == 1e-4);
  CHECK(s.hash.rfind("fnv1a64:", 0) == 0);
}

TEST_CASE("Material objects override presets per channel", "[scene]") {
  const Scene s = parse_scene(with_model_field(R"("material": {"preset": "leaf", "g": [0.1, 0.2, 0.3], "absorb": false})"),
                              "s.json");
  CHECK(s.models[0].material.channel[2].g == 0.3);
  CHECK(s.models[0].material.channel[0].sigma_a == 0.109);
  CHECK_FALSE(s.models[0].material.absorbs);
}

TEST_CASE("Every bad field is named by its JSON path", "[scene]") {
  CHECK(error_path("{") == "");  // not JSON: file only
  CHECK(error_path(R"({"version": 2, "models": []})") == "/version");
  CHECK(error_path(R"({"version": 1, "models": []})") == "/models");
  CHECK(error_path(R"({"version": 1, "model": []})") == "/model");
  CHECK(error_path(with_model_field(R"("material": {"sigma_a": -0.1, "sigma_s": 0.5, "g": 0})")) ==
        "/models/0/material/sigma_a");
  CHECK(error_path(with_model_field(R"("material": {"sigma_a": 0.1, "sigma_s": [0.5, -1, 0.5], "g": 0})")) ==
        "/models/0/material/sigma_s/1");
  CHECK(error_path(with_model_field(R"("material": {"sigma_a": 0.1, "sigma_s": 0.5, "g": 1.5})")) ==
        "/models/0/material/g");
  // JSON has no Inf: an overflowing number is rejected by the parser, naming the text and the field
  CHECK(error_path(with_model_field(R"("material": {"sigma_a": 0.1, "sigma_s": 0.5, "g": 1e999})")) ==
        "/models/0/material/g");
  // a key given twice is an error at the second one (the parser alone keeps the last silently)
  CHECK(error_path(with_model_field(R"("material": "cloud", "material": "leaf")")) == "/models/0/material");
  CHECK(error_path(R"({"version": 1, "version": 1, "models": []})") == "/version");
  // so is nesting deeper than any scene needs (printing such a value recursed off the stack)
  CHECK(error_path(std::string(100000, '[') + std::string(100000, ']')).rfind("/0/0/0/", 0) == 0);
  CHECK(error_path(with_model_field(R"("material": "granite")")) == "/models/0/material");
  CHECK(error_path(R"({"version": 1, "models": [{"name": "c", "material": "cloud",
      "density": {"type": "procedural", "size": 1e-4, "resolution": 48}}]})") == "/models/0/density/size");
  CHECK(error_path(with_model_field(R"("material": "cloud", "margin": 0)")) == "/models/0/margin");
  CHECK(error_path(with_model_field(R"("material": "cloud", "colour": 1)")) == "/models/0/colour");
  CHECK(error_path(R"({"version": 1, "models": [{"name": "c", "density": {"type": "procedural", "resolution": 2},
      "material": "cloud"}]})") == "/models/0/density/resolution");
  CHECK(error_path(R"({"version": 1, "models": [{"name": "a/b", "density": {"type": "procedural"},
      "material": "cloud"}]})") == "/models/0/name");
  CHECK(error_path(std::string(kMinimal).insert(1, R"("solver": {"iterations": "forever"},)")) ==
        "/solver/iterations");
  CHECK(error_path(std::string(kMinimal).insert(1, R"("lighting": {"mode": "base", "solutions": "0,19"},)")) ==
        "/lighting/solutions");
  CHECK(error_path(std::string(kMinimal).insert(1, R"("solver": {"model": "exact"},)")) == "/solver/model");
  CHECK(error_path(std::string(kMinimal).insert(1, R"("solver": {"model": "paper", "calibration": {"delta_m": false}},)")) ==
        "/solver/calibration");
  CHECK(error_path(std::string(kMinimal).insert(
            1, R"("solver": {"model": "calibrated", "calibration": {"delta": false}},)")) == "/solver/calibration/delta");
  CHECK(error_path(std::string(kMinimal).insert(
            1, R"("solver": {"model": "calibrated", "calibration": {"delta_m": 0}},)")) == "/solver/calibration/delta_m");
  const Scene s = parse_scene(std::string(kMinimal).insert(
                                  1, R"("solver": {"model": "calibrated", "calibration": {"delta_m": false}},)"),
                              "s.json");
  CHECK(s.solver.model.calibrated);
  CHECK_FALSE(s.solver.model.delta_m);
  CHECK(s.solver.model.path_length);
}

TEST_CASE("Error messages name the value and what is allowed", "[scene]") {
  const Error e = expect_invalid_input(
      [] { parse_scene(with_model_field(R"("material": {"sigma_a": 0.1, "sigma_s": 0.5, "g": -1.25})"), "x.json"); },
      "-1 <= g <= 1");
  const std::string what = e.what();
  CHECK(what.find("x.json") != std::string::npos);
  CHECK(what.find("-1.25") != std::string::npos);
}

TEST_CASE("Solution lists: all, indices and ranges", "[scene]") {
  CHECK(parse_solution_list("all", {}).size() == 19);
  CHECK(parse_solution_list("0,1,5-7", {}) == std::vector<int>{0, 1, 5, 6, 7});
  CHECK(parse_solution_list("[3, 3, 2]", {}) == std::vector<int>{2, 3});
  CHECK_THROWS_AS(parse_solution_list("7-5", {}), Error);
  CHECK_THROWS_AS(parse_solution_list("x", {}), Error);
  CHECK_THROWS_AS(parse_solution_list("-1", {}), Error);
}

TEST_CASE("Static lighting: sun from angles or a vector", "[scene]") {
  const Scene s = parse_scene(std::string(kMinimal).insert(1, R"("lighting": {"mode": "static",
      "sun": {"direction": [0, 0, 2]}, "intensity": 2, "ambient": 0.5},)"), "s.json");
  CHECK(s.lighting.mode == LightingMode::Static);
  CHECK(s.lighting.toward_sun.z == Approx(1.0));
  CHECK(s.lighting.intensity == 2.0);
}

TEST_CASE("float16 plans: boundary values within float16's range, no bicgstab", "[scene][validate]") {
  const auto scene = [](const std::string& intensity) {
    return parse_scene(std::string(kMinimal).insert(1, R"("lighting": {"mode": "static",
        "sun": {"direction": [0, 0, 1]}, "intensity": )" + intensity + R"(, "ambient": 0},)"), "s.json");
  };
  PlanOverrides f16;
  f16.precision = Precision::Float16;
  CHECK_NOTHROW(make_plan(scene("1e4"), f16));
  CHECK_NOTHROW(make_plan(scene("1e5")));  // float32 holds it
  const Error range = expect_invalid_input([&] { make_plan(scene("1e5"), f16); }, "65504");
  CHECK(range.where().json_path == "/lighting/intensity");
  PlanOverrides krylov = f16;
  krylov.method = SolverMethod::BiCGStab;
  krylov.mode = IterationMode::Auto;
  const Error method = expect_invalid_input([&] { make_plan(scene("1"), krylov); }, "float16");
  CHECK(method.where().json_path == "/solver/method");
  krylov.precision = Precision::Float32;
  CHECK_NOTHROW(make_plan(scene("1"), krylov));
}

TEST_CASE("Grid rules: density after scale and rho * sigma_t < 2", "[scene][validate]") {
  // density_scale pushes the procedural cloud's core above 1
  Scene s = parse_scene(R"({"version": 1, "models": [{"name": "c", "density": {"type": "procedural",
      "resolution": 10, "density_scale": 1.5}, "material": "cloud"}]})", "s.json");
  CHECK_FALSE(expect_invalid_input([&] { make_plan(s); }, "after density_scale").where().voxel.empty());
  // the papers' model only (the calibrated one loses 1 - exp(-rho sigma_t |c|) < 1 per step)
  s = parse_scene(R"({"version": 1, "solver": {"model": "paper"}, "models": [{"name": "c", "density": {"type": "procedural", "resolution": 10},
      "material": {"sigma_a": 0.5, "sigma_s": [1.0, 1.6, 1.0], "g": 0}}]})", "s.json");
  const Error e = expect_invalid_input([&] { make_plan(s); }, "rho * sigma_t < 2");
  CHECK(std::string(e.what()).find("channel green") != std::string::npos);
  CHECK(e.where().json_path == "/models/0/material");
}

TEST_CASE("Procedural sources are deterministic and in range", "[scene]") {
  const Scene s = parse_scene(R"({"version": 1, "models": [
      {"name": "p", "density": {"type": "procedural", "shape": "plant", "resolution": 24, "seed": 4},
       "material": "leaf", "wood_material": "bark"}]})", "s.json");
  const ModelGrid a = load_model_grid(s.models[0], s);
  const ModelGrid b = load_model_grid(s.models[0], s);
  CHECK(a.density == b.density);
  CHECK(a.material == b.material);
  CHECK(a.wood_nodes() > 0);
  CHECK(a.occupied_nodes() > a.wood_nodes());
  for (float d : a.density) REQUIRE((d >= 0.0f && d <= 1.0f));
}

TEST_CASE("The procedural plant stands on z = 0 centred on the vertical axis", "[scene]") {
  // docs/scene-format.md: "a small tree standing on z = 0 at the origin"; voxels are cells, so
  // the lowest layer's bottom faces lie on z = 0 and the grid spans z = 0 .. size
  const Scene s = parse_scene(R"({"version": 1, "models": [
      {"name": "p", "density": {"type": "procedural", "shape": "plant", "resolution": 20, "size": 2.0},
       "material": "leaf", "wood_material": "bark"}]})", "s.json");
  const ModelGrid g = load_model_grid(s.models[0], s);
  const auto& m = g.index_to_world;
  // world coordinate along axis r of the face of index coordinate `index` (a cell centre is integral)
  const auto world = [&](int r, double index) { return m[r * 4 + r] * index + m[r * 4 + 3]; };
  CHECK(m[10] == Approx(2.0 / 20));
  CHECK(world(2, g.index_min[2] - 0.5) == Approx(0.0).margin(1e-12));
  CHECK(world(2, g.index_min[2] + g.dims.nz - 0.5) == Approx(2.0));
  CHECK(world(0, g.index_min[0] - 0.5) == Approx(-world(0, g.index_min[0] + g.dims.nx - 0.5)));
  CHECK(world(1, g.index_min[1] - 0.5) == Approx(-world(1, g.index_min[1] + g.dims.ny - 0.5)));
  // the trunk reaches the ground: the lowest layer holds wood
  std::size_t wood_on_ground = 0;
  for (int y = 0; y < g.dims.ny; ++y)
    for (int x = 0; x < g.dims.nx; ++x) {
      const std::size_t i = g.dims.index(x, y, 0);
      wood_on_ground += g.material[i] == kMaterialWood && g.density[i] > 0.0f;
    }
  CHECK(wood_on_ground > 0);
}

TEST_CASE("Auto iterations never stop before light can cross the lattice", "[scene]") {
  const Scene s = parse_scene(kMinimal, "s.json");
  const BakePlan p = make_plan(s);
  CHECK(p.models[0].steps.mode == IterationMode::Auto);
  CHECK(p.models[0].steps.min_steps == p.models[0].lattice.dims.longest());
}

TEST_CASE("Sec. 6 warning where 1 + rho * Omega_mm < 0, and none where it is not", "[scene][validate]") {
  const auto warned = [](const std::string& material) {
    const Scene s = parse_scene(R"({"version": 1, "solver": {"model": "paper"}, "models": [{"name": "b", "density": {"type": "procedural",
        "shape": "box", "resolution": 6}, "material": )" + material + "}]}",
                                "s.json");
    for (const std::string& w : make_plan(s).warnings)
      if (w.find("1 + rho * Omega_mm") != std::string::npos) return true;
    return false;
  };
  // g = 0, sigma_a = 0, density 1 (the box): smallest 1 + rho Omega_mm -0.15, and 0 (not below)
  CHECK(min_diagonal_gain(build_omega({0.0, 1.2, 0.0}), 1.0) == Approx(-0.15));
  CHECK(min_diagonal_gain(build_omega({0.0, 0.9, 0.0}), 1.0) >= 0.0);
  CHECK(warned(R"({"sigma_a": 0, "sigma_s": 1.2, "g": 0})"));
  CHECK_FALSE(warned(R"({"sigma_a": 0, "sigma_s": 0.9, "g": 0})"));
}

TEST_CASE("The density range is checked after density_scale, not before", "[scene][validate]") {
  lblight::test::TempDir tmp;
  std::vector<float> density(4 * 4 * 4, 1.8f);
  lblight::test::write_density_vdb(tmp / "d.vdb", lblight::test::cube_frame(4, 0.1), density);
  const Scene s = parse_scene(R"({"version": 1, "models": [{"name": "v", "density": {"type": "vdb", "path": ")" +
                                  (tmp / "d.vdb").string() + R"(", "density_scale": 0.5}, "material": "cloud"}]})",
                              "s.json");
  const ModelGrid g = load_model_grid(s.models[0], s);
  for (float d : g.density) CHECK(d == Approx(0.9f));
}

TEST_CASE("Documented defaults (docs/scene-format.md) are the parser's", "[scene]") {
  const Scene s = parse_scene(R"({"version": 1, "models": [
      {"name": "p", "density": {"type": "procedural"}, "material": "cloud"},
      {"name": "m", "density": {"type": "mesh", "path": "x.obj"}, "material": "leaf"}],
      "output": {"lbh": true}})",
                              "s.json");
  const ModelSpec& p = s.models[0];
  CHECK(p.density.procedural.resolution == 48);
  CHECK(p.density.procedural.size == 1.0);
  CHECK(p.margin == 1);
  CHECK(p.crop);
  CHECK(s.models[1].density.mesh.resolution == 64);
  CHECK(s.models[1].density.mesh.supersample == 8);
  CHECK(s.output.lbh.enabled);
  CHECK(s.output.lbh.threshold == 0.01);
  CHECK(s.output.lbh.relative);
  CHECK(s.solver.tolerance == 1e-4);
  CHECK(s.solver.precision == Precision::Float32);
  CHECK(s.lighting.ambient_from_sum);
  // check_interval: (longest edge + 2) / 4 rounded down, clamped to 4..16
  const BakePlan plan = make_plan(parse_scene(kMinimal, "s.json"));
  const int longest = plan.models[0].lattice.dims.longest();
  CHECK(plan.models[0].steps.check_interval == std::clamp((longest + 2) / 4, 4, 16));
}

TEST_CASE("Channels are merged only when medium and wood agree", "[scene]") {
  // grey leaves, coloured wood: three distinct channels (wood tells them apart)
  const Scene s = parse_scene(R"({"version": 1, "models": [{"name": "t", "density": {"type": "procedural",
      "shape": "plant", "resolution": 16}, "material": {"sigma_a": 0.1, "sigma_s": 0.8, "g": 0.2},
      "wood_material": {"sigma_a": [0.1, 0.2, 0.3], "sigma_s": 0.8, "g": -1}}]})",
                              "s.json");
  const BakePlan plan = make_plan(s);
  REQUIRE(plan.models[0].lattice.material_count == 2);
  CHECK(plan.models[0].channels.size() == 3);
  // grey both: one
  const Scene grey = parse_scene(R"({"version": 1, "models": [{"name": "t", "density": {"type": "procedural",
      "shape": "plant", "resolution": 16}, "material": {"sigma_a": 0.1, "sigma_s": 0.8, "g": 0.2},
      "wood_material": {"sigma_a": 0.1, "sigma_s": 0.8, "g": -1}}]})",
                                 "s.json");
  CHECK(make_plan(grey).models[0].channels.size() == 1);
}

TEST_CASE("B00 is derived from the sum only when all 18 directions are baked", "[scene]") {
  const auto derived = [](const std::string& solutions) {
    const Scene s = parse_scene(R"({"version": 1, "models": [{"name": "c", "density": {"type": "procedural",
        "resolution": 8}, "material": "cloud"}], "lighting": {"solutions": ")" + solutions + R"("}})",
                                "s.json");
    const BakePlan plan = make_plan(s);
    for (const SolutionPlan& sp : plan.models[0].solutions)
      if (sp.index == 0) return sp.derived;
    return false;
  };
  CHECK(derived("all"));
  CHECK_FALSE(derived("0,2-18"));  // B01 missing
  CHECK_FALSE(derived("0-17"));    // B18 missing
}

TEST_CASE("Overrides: --iterations N and --solutions against a static scene", "[scene]") {
  const Scene fixed = parse_scene(std::string(kMinimal).insert(1, R"("solver": {"iterations": 30},)"), "s.json");
  PlanOverrides ov;
  ov.mode = IterationMode::Fixed;
  ov.iterations = 7;
  CHECK(make_plan(fixed, ov).models[0].steps.fixed_steps == 7);
  CHECK(make_plan(fixed).models[0].steps.fixed_steps == 30);
  const Scene stat = parse_scene(std::string(kMinimal).insert(1, R"("lighting": {"mode": "static",
      "sun": {"direction": [0, 0, 1]}},)"), "s.json");
  PlanOverrides sol;
  sol.solutions = std::vector<int>{1};
  expect_invalid_input([&] { make_plan(stat, sol); }, "--solutions applies to base lighting");
}
