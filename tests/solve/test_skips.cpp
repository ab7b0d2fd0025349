// Leaving out what a scene does not need (docs/accuracy.md, "What a bake leaves out"): each skip
// is checked to give the same results for what is kept.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include <nlohmann/json.hpp>

#include "lblight/backend/backend.h"
#include "lblight/core/relative_gap.h"
#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/sun_coverage.h"
#include "lblight/solve/bake.h"
#include "lblight/solve/plan.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {

std::vector<int> needed_list(const SunConstraints& c) {
  const auto need = needed_base_solutions(c);
  std::vector<int> out;
  for (int j = 0; j < 19; ++j)
    if (need[static_cast<std::size_t>(j)]) out.push_back(j);
  return out;
}

// Directions that some sun in the band gets a weight from, found by brute force over suns.
std::vector<int> brute_force_band(double e0, double e1, bool ambient) {
  std::array<bool, 19> hit{};
  hit[0] = ambient;
  const int ne = e0 == e1 ? 1 : 721, na = 1440;
  for (int a = 0; a < ne; ++a) {
    const double el = ne == 1 ? e0 : e0 + (e1 - e0) * a / (ne - 1);
    for (int b = 0; b < na; ++b) {
      const Vec3d t = toward_sun_from_angles(el, 360.0 * b / na);
      const SunWeights w = decompose_direction({-t.x, -t.y, -t.z});
      for (int k = 0; k < 3; ++k)
        if (w.weight[static_cast<std::size_t>(k)] > 1e-12) hit[static_cast<std::size_t>(w.direction[static_cast<std::size_t>(k)])] = true;
    }
  }
  std::vector<int> out;
  for (int j = 0; j < 19; ++j)
    if (hit[static_cast<std::size_t>(j)]) out.push_back(j);
  return out;
}

struct BakeResult {
  BakePlan plan;
  std::map<int, SolutionResult> solutions;
};

// Scenes must outlive their plans (plans point into them).
BakeResult bake(const Scene& scene, Precision precision = Precision::Float32) {
  BakeResult r;
  PlanOverrides ov;
  ov.precision = precision;
  r.plan = make_plan(scene, ov);
  auto backend = cpu_backend(0);
  KeepSolutions keep(r.solutions);
  bake_model(r.plan.models.at(0), *backend, {}, keep);
  return r;
}

// The papers' LB model unless `solver` names one: these cases were measured on it.
std::string scene_text(const std::string& lighting, const std::string& solver, const std::string& model_extra = "") {
  std::string named = solver;
  if (solver.find("\"model\"") == std::string::npos) {
    const std::string rest = solver.substr(solver.find('{') + 1);
    named = std::string(R"({"model": "paper")") + (rest.find_first_not_of(' ') == rest.find('}') ? "" : ", ") + rest;
  }
  return R"({"version": 1, "models": [{"name": "m", "density": {"type": "procedural", "shape": "plant", "resolution": 10},
             "material": "leaf")" +
         model_extra + R"(}], "lighting": )" + lighting + R"(, "solver": )" + named + "}";
}

// Difference relative to a's peak (values in deep shadow are not compared relatively).
double max_rel(const std::vector<float>& a, const std::vector<float>& b) {
  REQUIRE(a.size() == b.size());
  return max_relative_difference(a, b, peak_magnitude(a));
}

}  // namespace

TEST_CASE("Sun above the horizon with yaw-only instances needs 13 directions and ambient", "[skips][sun]") {
  SunConstraints c;
  c.min_elevation = 0;
  c.max_elevation = 90;
  c.rotation = InstanceRotation::Yaw;
  const std::vector<int> got = needed_list(c);
  std::vector<int> expect{0};
  for (int j = 1; j < 19; ++j)
    if (d3q19::cz(j) <= 0) expect.push_back(j);  // light travelling down or level
  CHECK(got == expect);
  CHECK(got.size() == 14);
  CHECK(got == brute_force_band(0, 90, true));
}

TEST_CASE("The needed directions match a brute-force sweep of suns", "[skips][sun][slow]") {
  for (auto [e0, e1] : {std::pair{10.0, 50.0}, {30.0, 30.0}, {45.0, 45.0}, {-20.0, 5.0}, {60.0, 90.0}, {0.0, 0.0}}) {
    SunConstraints c;
    c.min_elevation = e0;
    c.max_elevation = e1;
    c.rotation = InstanceRotation::Yaw;
    INFO("elevation " << e0 << ".." << e1);
    CHECK(needed_list(c) == brute_force_band(e0, e1, true));
  }
}

TEST_CASE("A fixed sun needs its three face directions, free rotation needs all", "[skips][sun]") {
  SunConstraints c;
  c.fixed_toward_sun = toward_sun_from_angles(35, 20);
  c.rotation = InstanceRotation::None;
  c.ambient = false;
  const Vec3d t = *c.fixed_toward_sun;
  const SunWeights w = decompose_direction({-t.x, -t.y, -t.z});
  std::vector<int> expect(w.direction.begin(), w.direction.end());
  std::sort(expect.begin(), expect.end());
  CHECK(needed_list(c) == expect);
  c.ambient = true;
  expect.insert(expect.begin(), 0);
  CHECK(needed_list(c) == expect);
  c.rotation = InstanceRotation::Any;
  CHECK(needed_list(c).size() == 19);
}

TEST_CASE("Scene lighting declarations choose the solutions, and conflicts are rejected", "[skips][scene]") {
  const Scene yaw = parse_scene(scene_text(R"({"sun_range": {"min_elevation": 0}, "instance_rotation": "yaw"})", "{}"),
                                "s.json");
  CHECK(yaw.lighting.solutions.size() == 14);
  const Scene fixed = parse_scene(scene_text(R"({"sun": {"elevation": 35, "azimuth": 20}, "ambient": false})", "{}"),
                                  "s.json");
  CHECK(fixed.lighting.solutions.size() == 3);
  CHECK(parse_scene(scene_text(R"({"mode": "base"})", "{}"), "s.json").lighting.solutions.size() == 19);
  CHECK_THROWS_WITH(parse_scene(scene_text(R"({"solutions": "all", "sun_range": {"min_elevation": 0}})", "{}"), "s.json"),
                    Catch::Contains("/lighting/solutions"));
  // instance_rotation only selects solutions: beside a listed set it would be silently ignored
  CHECK_THROWS_WITH(parse_scene(scene_text(R"({"solutions": [0, 6], "instance_rotation": "yaw"})", "{}"), "s.json"),
                    Catch::Contains("instance_rotation"));
  CHECK_THROWS_WITH(parse_scene(scene_text(R"({"instance_rotation": "roll"})", "{}"), "s.json"),
                    Catch::Contains("allowed: none, yaw"));
  CHECK_THROWS_WITH(parse_scene(scene_text(R"({"sun_range": {"min_elevation": 50, "max_elevation": 10}})", "{}"), "s.json"),
                    Catch::Contains("max_elevation"));
}

TEST_CASE("A yaw-only, sun-above-horizon bake runs 14 solutions with results identical to the full bake",
          "[skips][bake]") {
  const Scene full = parse_scene(scene_text(R"({"solutions": "all", "ambient_from_sum": false})", R"({"iterations": 24})"),
                                 "s.json");
  const Scene kept = parse_scene(
      scene_text(R"({"sun_range": {"min_elevation": 0}, "instance_rotation": "yaw", "ambient_from_sum": false})",
                 R"({"iterations": 24})"),
      "s.json");
  const BakeResult a = bake(full), b = bake(kept);
  REQUIRE(a.solutions.size() == 19);
  REQUIRE(b.solutions.size() == 14);
  CHECK(b.plan.models[0].savings.solutions_left_out.size() == 5);
  for (const auto& [idx, r] : b.solutions)
    for (int c = 0; c < 3; ++c) {
      INFO("B" << idx << " channel " << c);
      CHECK(r.totals[c] == a.solutions.at(idx).totals[c]);  // bit for bit
    }
}

TEST_CASE("Calibrated model: B00 summed as sum 18 w_j B_j equals the solved isotropic B00", "[skips][bake]") {
  const Scene solved = parse_scene(
      scene_text(R"({"ambient_from_sum": false})", R"({"iterations": 30, "model": "calibrated"})"), "s.json");
  const Scene summed = parse_scene(scene_text(R"({"mode": "base"})", R"({"iterations": 30, "model": "calibrated"})"), "s.json");
  const BakeResult a = bake(solved), b = bake(summed);
  REQUIRE(b.plan.models[0].savings.ambient_from_sum);
  CHECK(a.plan.models[0].solutions[0].boundary[1] == Approx(1.5));  // 18 w_1
  for (int c = 0; c < 3; ++c) CHECK(max_rel(a.solutions.at(0).totals[c], b.solutions.at(0).totals[c]) < 2e-6);
  // and it is not the papers' B00
  const BakeResult p = bake(parse_scene(scene_text(R"({"ambient_from_sum": false})", R"({"iterations": 30})"), "s.json"));
  CHECK(max_rel(a.solutions.at(0).totals[0], p.solutions.at(0).totals[0]) > 1e-2);
}

TEST_CASE("B00 summed from the 18 directional solutions equals the solved B00", "[skips][bake]") {
  const Scene solved = parse_scene(scene_text(R"({"ambient_from_sum": false})", R"({"iterations": 30})"), "s.json");
  const Scene summed = parse_scene(scene_text(R"({"mode": "base"})", R"({"iterations": 30})"), "s.json");
  const BakeResult a = bake(solved), b = bake(summed);
  CHECK_FALSE(a.plan.models[0].savings.ambient_from_sum);
  CHECK(b.plan.models[0].savings.ambient_from_sum);
  CHECK(b.plan.models[0].solved_solutions() == 18);
  REQUIRE(b.solutions.count(0) == 1);
  for (int c = 0; c < 3; ++c) CHECK(max_rel(a.solutions.at(0).totals[c], b.solutions.at(0).totals[c]) < 2e-6);
  // The derived solution's estimate bounds its parts: auto mode, tolerance 1e-3.
  const Scene autos = parse_scene(scene_text(R"({"mode": "base"})", R"({"tolerance": 1e-3})"), "s.json");
  const BakeResult c = bake(autos);
  const SolutionResult& derived = c.solutions.at(0);
  // its iterations are the most any part ran (not their sum); converged only if every part did
  int most = 0;
  bool all = true;
  for (int j = 1; j < 19; ++j) {
    most = std::max(most, c.solutions.at(j).iterations);
    all = all && c.solutions.at(j).converged;
  }
  CHECK(derived.iterations == most);
  CHECK(derived.converged == all);
  CHECK(derived.error_estimate > 0);
  CHECK(derived.error_estimate < 1e-3);
  // ... in both norms, against B00 solved to 1e-10 in float64
  const Scene tight = parse_scene(scene_text(R"({"solutions": "0"})", R"({"tolerance": 1e-10, "precision": "float64"})"),
                                  "s.json");
  const BakeResult reference = bake(tight, Precision::Float64);
  const SolutionResult& ref = reference.solutions.at(0);
  // the true error over the three channels together
  std::vector<double> got_all, ref_all;
  for (int ch = 0; ch < 3; ++ch) {
    got_all.insert(got_all.end(), derived.totals[ch].begin(), derived.totals[ch].end());
    ref_all.insert(ref_all.end(), ref.totals[ch].begin(), ref.totals[ch].end());
  }
  const RelativeGap truth = relative_gap(got_all, ref_all);
  INFO("true error: L2 " << truth.l2 << ", max " << truth.max);
  CHECK(derived.error_estimate >= truth.l2);
  CHECK(derived.error_estimate_max > 0);
  CHECK(derived.error_estimate_max >= truth.max);
}

TEST_CASE("Cropping to the occupied nodes keeps the steady state of every occupied node", "[skips][bake]") {
  // A plant in a grid padded with empty nodes (margin 4 around the grid, crop off) against the
  // cropped lattice; both driven to 1e-10 in float64, where transients have died out.
  const std::string lighting = R"({"solutions": "1,5,12"})";
  const std::string solver = R"({"tolerance": 1e-10, "precision": "float64"})";
  const Scene wide = parse_scene(scene_text(lighting, solver, R"(, "margin": 4, "crop": false)"), "s.json");
  const Scene tight = parse_scene(scene_text(lighting, solver, R"(, "margin": 1)"), "s.json");
  const BakeResult a = bake(wide, Precision::Float64), b = bake(tight, Precision::Float64);
  const ModelPlan& pa = a.plan.models[0];
  const ModelPlan& pb = b.plan.models[0];
  REQUIRE(pb.lattice.dims.count() < pa.lattice.dims.count());
  const Dims& da = pa.lattice.dims;
  const Dims& db = pb.lattice.dims;
  int off[3];
  for (int k = 0; k < 3; ++k) off[k] = pb.lattice_index_min[k] - pa.lattice_index_min[k];
  for (const auto& [idx, r] : b.solutions) {
    double worst = 0;
    for (int z = 1; z < db.nz - 1; ++z)
      for (int y = 1; y < db.ny - 1; ++y)
        for (int x = 1; x < db.nx - 1; ++x)
          for (int c = 0; c < 3; ++c) {
            const double vb = r.totals[c][db.index(x, y, z)];
            const double va = a.solutions.at(idx).totals[c][da.index(x + off[0], y + off[1], z + off[2])];
            keep_worst(worst, std::fabs(va - vb) / std::max(1e-3, std::fabs(va)));
          }
    INFO("B" << idx);
    CHECK(worst < 1e-6);
  }
}

TEST_CASE("Channels with equal materials are solved once and equal a separate solve", "[skips][bake]") {
  const auto cloud = [](const std::string& sigma_s) {
    return R"({"version": 1, "models": [{"name": "c", "density": {"type": "procedural", "shape": "cloud", "resolution": 12},
               "material": {"sigma_a": 0.008, "sigma_s": )" +
           sigma_s + R"(, "g": 0.9}}], "lighting": {"solutions": "1,6"}, "solver": {"iterations": 30}})";
  };
  const Scene grey = parse_scene(cloud("0.792"), "s.json");
  const Scene blue = parse_scene(cloud("[0.792, 0.792, 0.6]"), "s.json");
  const BakeResult a = bake(grey), b = bake(blue);
  CHECK(a.plan.models[0].channels.size() == 1);
  CHECK(a.plan.models[0].savings.channels_solved == 1);
  CHECK(b.plan.models[0].channels.size() == 2);
  for (int idx : {1, 6}) {
    const auto& ta = a.solutions.at(idx).totals;
    const auto& tb = b.solutions.at(idx).totals;
    CHECK(ta[0] == ta[1]);
    CHECK(ta[0] == ta[2]);
    CHECK(ta[0] == tb[0]);  // red solved with green in one system equals red solved for all three
    CHECK(tb[0] == tb[1]);
    CHECK(tb[2] != tb[0]);
  }
}

TEST_CASE("A solution's error estimate is that of its slowest channel", "[bake][convergence]") {
  // red scatters almost without loss (slow to converge), green and blue absorb (fast): the
  // solution's estimate must be red's, not the last channel's, and bound red's true error
  const auto scene = [](const std::string& material, const std::string& solver) {
    return parse_scene(R"({"version": 1, "models": [{"name": "c", "density": {"type": "procedural",
        "resolution": 12}, "material": )" + material + R"(}], "lighting": {"solutions": "5"}, "solver": )" + solver + "}",
                       "s.json");
  };
  const std::string colour = R"({"sigma_a": [0.001, 0.3, 0.3], "sigma_s": [0.799, 0.5, 0.5], "g": 0, "absorb": true})";
  const std::string red = R"({"sigma_a": 0.001, "sigma_s": 0.799, "g": 0, "absorb": true})";
  const Scene coloured = scene(colour, R"({"tolerance": 1e-3})"), grey = scene(red, R"({"tolerance": 1e-3})");
  const Scene exact = scene(colour, R"({"tolerance": 1e-11, "precision": "float64"})");
  const BakeResult a = bake(coloured), g = bake(grey), ref = bake(exact, Precision::Float64);
  const SolutionResult& got = a.solutions.at(5);
  INFO("estimates: coloured " << got.error_estimate << " (" << got.iterations << " steps, converged " << got.converged
                                << "), red alone " << g.solutions.at(5).error_estimate << " (" << g.solutions.at(5).iterations
                                << " steps)");
  CHECK(got.error_estimate == Approx(g.solutions.at(5).error_estimate).epsilon(1e-6));
  const RelativeGap red_error = relative_gap(got.totals[0], ref.solutions.at(5).totals[0]);
  INFO("red's true error " << red_error.l2);
  CHECK(got.error_estimate >= red_error.l2);
  CHECK(got.error_estimate < 1e-3);
}

TEST_CASE("A fixed sun along a lattice direction needs that one base solution", "[skips][sun]") {
  const double h = std::sqrt(0.5);
  // toward the sun -> the direction light travels: zenith -> 6 (-z); (1, 0, 1) -> (-1, 0, -1)
  for (auto [toward, want] : {std::pair{Vec3d{0, 0, 1}, 6}, {toward_sun_from_angles(90, 0), 6},
                              {toward_sun_from_angles(90, 123), 6}, {Vec3d{h, 0, h}, lattice_direction(-1, 0, -1)},
                              {toward_sun_from_angles(45, 0), lattice_direction(-1, 0, -1)},
                              {toward_sun_from_angles(0, 90), lattice_direction(0, -1, 0)}}) {
    INFO("toward the sun (" << toward.x << ", " << toward.y << ", " << toward.z << ")");
    SunConstraints c;
    c.fixed_toward_sun = toward;
    c.ambient = false;
    CHECK(needed_list(c) == std::vector<int>{want});
  }
}

TEST_CASE("A fixed sun with yaw-rotated instances needs the directions of its elevation band", "[skips][sun]") {
  SunConstraints c;
  c.fixed_toward_sun = toward_sun_from_angles(30, 40);
  c.rotation = InstanceRotation::Yaw;
  c.ambient = false;
  CHECK(needed_list(c) == brute_force_band(30, 30, false));
  CHECK(needed_list(c).size() > 3);  // more than the three of the sun itself
}

TEST_CASE("A sun at the zenith needs the straight-down direction even at a band's lower end", "[skips][sun]") {
  // Direction 6 (0, 0, -1) is weighted only by suns near the zenith, and fully by the zenith
  // itself: a band or yaw-rotated sun that ends exactly at 90 degrees must keep it.
  SunConstraints band;
  band.min_elevation = 90;
  band.max_elevation = 90;
  band.rotation = InstanceRotation::Yaw;
  CHECK(needed_list(band) == std::vector<int>{0, 6});
  CHECK(needed_list(band) == brute_force_band(90, 90, true));
  SunConstraints fixed;
  fixed.fixed_toward_sun = Vec3d{0, 0, 1};
  fixed.rotation = InstanceRotation::Yaw;
  fixed.ambient = false;
  CHECK(needed_list(fixed) == std::vector<int>{6});
}

TEST_CASE("Suns a twentieth of a degree below the zenith need the directions around straight down",
          "[skips][sun]") {
  // Tilted by 0.05 degrees, the sun puts a small but non-zero weight on the directions beside
  // (0, 0, -1) at every azimuth: the selection's slack must be far below that.
  SunConstraints c;
  c.min_elevation = 89.95;
  c.max_elevation = 89.95;
  c.rotation = InstanceRotation::Yaw;
  const std::vector<int> got = needed_list(c);
  CHECK(got == brute_force_band(89.95, 89.95, true));
  CHECK(got.size() > 2);
}

TEST_CASE("A --solutions override of a sun-derived selection reports nothing left out that a sun selects",
          "[skips][scene]") {
  // solutions_left_out lists what no allowed sun selects (docs/output-format.md); solutions the
  // user simply did not ask for on the command line are not that.
  const Scene yaw = parse_scene(scene_text(R"({"sun_range": {"min_elevation": 0}, "instance_rotation": "yaw"})", "{}"),
                                "s.json");
  CHECK(make_plan(yaw).models[0].savings.solutions_left_out.size() == 5);
  PlanOverrides ov;
  ov.solutions = std::vector<int>{1};
  const BakePlan plan = make_plan(yaw, ov);
  REQUIRE(plan.models[0].solutions.size() == 1);
  const auto need = needed_base_solutions(yaw.lighting.sun_constraints);
  for (int j : plan.models[0].savings.solutions_left_out) {
    INFO("B" << j << " reported left out");
    CHECK_FALSE(need[static_cast<std::size_t>(j)]);
  }
}

TEST_CASE("The summed B00's error estimates are the documented sums over its parts", "[skips][bake]") {
  // docs/output-format.md: sum_j eps_j ||B_j|| / ||B00|| in the L2 norm, and the same with peak
  // values in the max norm (each part's error adds up; the worst part alone does not bound it).
  const Scene s = parse_scene(scene_text(R"({"mode": "base"})", R"({"tolerance": 1e-4})"), "s.json");
  const BakeResult r = bake(s);
  REQUIRE(r.plan.models[0].savings.ambient_from_sum);
  // ||B|| over the three channels and B's peak value
  const auto norm_and_peak = [](const SolutionResult& p) {
    double norm_sq = 0, peak = 0;
    for (const auto& t : p.totals)
      for (float v : t) {
        norm_sq += static_cast<double>(v) * v;
        peak = std::max(peak, static_cast<double>(v));
      }
    return std::pair{std::sqrt(norm_sq), peak};
  };
  double l2 = 0, mx = 0;
  for (int j = 1; j < 19; ++j) {
    const SolutionResult& p = r.solutions.at(j);
    const auto [norm, peak] = norm_and_peak(p);
    l2 += p.error_estimate * norm;
    mx += p.error_estimate_max * peak;
  }
  const auto [norm, peak] = norm_and_peak(r.solutions.at(0));
  REQUIRE(std::isfinite(mx));
  REQUIRE(mx > 0);
  CHECK(r.solutions.at(0).error_estimate == Approx(l2 / norm).epsilon(1e-4));
  CHECK(r.solutions.at(0).error_estimate_max == Approx(mx / peak).epsilon(1e-4));
}

TEST_CASE("The manifest's work fraction counts lattice updates against 19 solutions x 3 channels", "[skips][io]") {
  // docs/output-format.md's example: B00 from the sum, 18 of 19 solutions solved in 3 channels
  // on the uncropped lattice, is 18 / 19 = 0.947 of the work.
  TempDir tmp;
  const Scene s = parse_scene(scene_text(R"({"mode": "base"})", R"({"iterations": 2})", R"(, "crop": false)"),
                              tmp / "s.json");
  const BakedModel baked = bake_first_model(s, tmp / "out");
  REQUIRE(baked.model().channels.size() == 3);
  const nlohmann::json m = nlohmann::json::parse(read_text(tmp / "out" / "manifest.json"));
  const nlohmann::json& savings = m["models"][0]["savings"];
  CHECK(savings["solutions_solved"] == 18);
  CHECK(savings["cropped"] == false);
  CHECK(savings["work_fraction"].get<double>() == Approx(18.0 / 19.0));
}
