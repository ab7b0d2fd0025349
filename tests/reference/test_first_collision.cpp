// The calibrated model's first_collision correction (solve/first_collision.h, docs/model.md sec. 8):
// its exact uncollided light against the empty lattice, against the Monte Carlo reference of a pure
// absorber, its first-collision source against the exact first-collision share, and B00 against
// physical light on a sparse plant, where it is meant to help.
#include <catch2/catch.hpp>

#include <cmath>
#include <map>

#include "lblight/core/error.h"
#include "lblight/lattice/d3q19.h"
#include "lblight/reference/truth.h"
#include "lblight/solve/first_collision.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {

double relative_l2(const LatticeGeometry& g, const std::vector<double>& got, const std::vector<double>& want) {
  double d = 0, n = 0;
  for (std::size_t i = 0; i < got.size(); ++i)
    if (g.density[i] > 0) {
      d += (got[i] - want[i]) * (got[i] - want[i]);
      n += want[i] * want[i];
    }
  return std::sqrt(d / n);
}

std::array<OpticalParams, kMaxMaterials> one_material(const OpticalParams& p) {
  std::array<OpticalParams, kMaxMaterials> o{};
  o.fill(p);
  return o;
}

}  // namespace

TEST_CASE("first_collision: the exact uncollided light of an empty lattice is the incident fluence", "[truth]") {
  const LatticeGeometry g = uniform_lattice({7, 6, 8}, 0.0f);
  std::array<double, kMaxMaterials> sigma_t{};
  sigma_t.fill(1.0);
  const std::vector<double> iso = exact_uncollided(g, sigma_t, base_solution_uncollided(0), 64);
  const std::vector<double> beam = exact_uncollided(g, sigma_t, base_solution_uncollided(11));
  const Dims& d = g.dims;
  for (int z = 1; z < d.nz - 1; ++z)
    for (int y = 1; y < d.ny - 1; ++y)
      for (int x = 1; x < d.nx - 1; ++x) {
        CHECK(iso[d.index(x, y, z)] == Approx(18.0).epsilon(1e-12));
        CHECK(beam[d.index(x, y, z)] == Approx(1.0).epsilon(1e-12));
      }
  CHECK(iso[d.index(0, 3, 3)] == 0.0);  // the boundary layer is not the medium's
}

TEST_CASE("first_collision: a beam's exact uncollided light is the voxel mean of Beer-Lambert", "[truth]") {
  // Axial beam through a uniform absorber: the voxel k voxels below the surface holds
  // exp(-sigma k) (1 - exp(-sigma)) / sigma, averaged at 16 points of the voxel.
  const LatticeGeometry g = uniform_lattice({12, 5, 5}, 1.0f);
  std::array<double, kMaxMaterials> sigma_t{};
  sigma_t.fill(0.3);
  const int j = lattice_direction(1, 0, 0);
  const std::vector<double> u = exact_uncollided(g, sigma_t, base_solution_uncollided(j));
  for (int x = 1; x < 11; ++x) {
    const double want = std::exp(-0.3 * (x - 1)) * -std::expm1(-0.3) / 0.3;
    CAPTURE(x);
    CHECK(u[g.dims.index(x, 2, 2)] == Approx(want).epsilon(2e-3));
  }
}

TEST_CASE("first_collision: exact uncollided light agrees with the Monte Carlo reference of a pure absorber",
          "[truth]") {
  // A 10^3 cube, extinction 0.3 per voxel: the reference's fluence is all uncollided light.
  const LatticeGeometry g = uniform_lattice({12, 12, 12}, 1.0f);
  ChannelOptics optics{};
  optics.fill({0.3, 0.0, 0.0});
  std::array<double, kMaxMaterials> sigma_t{};
  sigma_t.fill(0.3);
  MonteCarloOptions mc;
  mc.target_error = 0.01;
  mc.photons_per_batch = 8192;
  for (int index : {0, 6, 11}) {
    const FluenceEstimate truth = trace_fluence(g, optics, base_solution_light(index), mc, 3);
    const std::vector<double> exact = exact_uncollided(g, sigma_t, base_solution_uncollided(index));
    const double e = relative_l2(g, exact, truth.mean);
    CAPTURE(index, e, truth.relative_error);
    CHECK(e < 2.5 * truth.relative_error);
  }
}

TEST_CASE("first_collision: a beam's source scatters the exact first-collision share of the light", "[truth]") {
  // Half-density medium on a 6^3 interior, beam B01 (+x): node k along the beam receives
  // exp(-rho sigma_t k) and scatters albedo (1 - exp(-rho sigma_t)) of it; credit holds half.
  LatticeGeometry g = uniform_lattice({8, 8, 8}, 0.5f);
  const OpticalParams p{0.2, 0.6, 0.0};
  LbModel model;
  model.calibrated = true;
  ChannelMaterials cm;
  for (int k = 0; k < kMaxMaterials; ++k) {
    cm.omega[static_cast<std::size_t>(k)] = build_model_omega(p, model);
    cm.absorbs[static_cast<std::size_t>(k)] = true;
    cm.voxel_average[static_cast<std::size_t>(k)] = true;
  }
  std::array<double, 19> boundary{};
  boundary[1] = 1.0;
  const FirstCollisionSource src = first_collision_source(g, one_material(p), model, cm, boundary);
  const double rho_sigma = 0.5 * p.sigma_t(), albedo = p.sigma_s / p.sigma_t();
  double want = 0;
  for (int k = 0; k < 6; ++k) want += 36.0 * std::exp(-rho_sigma * k) * albedo * -std::expm1(-rho_sigma);
  double credit = 0, rest = 0;
  for (double c : src.credit) credit += c;
  for (std::size_t i = 0; i < g.dims.count(); ++i) rest += src.state[i];  // direction 0
  CHECK(2.0 * credit == Approx(want).epsilon(1e-12));
  CHECK(rest == 0.0);  // absorbed light leaves (remove_absorbed)

  // A diagonal beam: what node (3, 3, 3) scatters into direction m arrives at (3, 3, 3) + c_m.
  std::array<double, 19> diagonal{};
  const int jd = lattice_direction(1, 0, 1);
  diagonal[static_cast<std::size_t>(jd)] = 1.0;
  const FirstCollisionSource ds = first_collision_source(g, one_material(p), model, cm, diagonal);
  const double len = std::sqrt(2.0), r = -std::expm1(-p.sigma_t() * len);
  // two interior nodes upstream, (2, 3, 2) and (1, 3, 1); the collision at (3, 3, 3) scatters the
  // exact share of what enters it, spread as Omega's column jd
  const double entering = std::exp(-2.0 * rho_sigma * len), a = -std::expm1(-rho_sigma * len) / r * entering;
  const int m = lattice_direction(0, 1, 0);
  const std::size_t n = g.dims.count();
  const double want_entry = a * cm.omega[0][static_cast<std::size_t>(m * 19 + jd)];
  CHECK(ds.state[static_cast<std::size_t>(m) * n + g.dims.index(3, 4, 3)] == Approx(want_entry).epsilon(1e-12));
  // forward into jd itself: the scattered share only, not the beam going on
  const double want_forward = a * (cm.omega[0][static_cast<std::size_t>(jd * 19 + jd)] + r);
  CHECK(ds.state[static_cast<std::size_t>(jd) * n + g.dims.index(4, 3, 4)] == Approx(want_forward).epsilon(1e-12));
}

TEST_CASE("first_collision: a pure absorber's B00 is its exact uncollided light", "[truth]") {
  const Scene scene = parse_scene(R"({"version": 1, "models": [{"name": "cube", "density": {"type": "procedural",
      "shape": "box", "resolution": 8, "size": 8.0}, "material": {"sigma_a": 0.4, "sigma_s": 0.0, "g": 0.0,
      "absorb": true}}], "lighting": {"mode": "base", "solutions": "all"}, "solver": {"iterations": "auto",
      "tolerance": 1e-5, "model": "calibrated", "method": "bicgstab", "calibration": {"first_collision": true}}})",
                                  "absorber.json");
  const BakePlan plan = make_plan(scene);
  const ModelPlan& mp = plan.models[0];
  REQUIRE_FALSE(mp.solutions[0].derived);  // B00's uncollided light is not the sum of 18 beams
  std::map<int, SolutionResult> out;
  KeepSolutions keep(out);
  auto backend = cpu_backend(0);
  BakeOptions only;
  only.solutions = {0};
  bake_model(mp, *backend, only, keep);
  std::array<double, kMaxMaterials> sigma_t{};
  sigma_t.fill(0.4);
  const std::vector<double> exact = exact_uncollided(mp.lattice, sigma_t, base_solution_uncollided(0));
  const Dims& d = mp.lattice.dims;
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x) {
        const std::size_t i = d.index(x, y, z);
        // the boundary layer holds open air's value, as every B00's does (relighting's edges)
        REQUIRE(out.at(0).totals[0][i] == Approx(d.is_boundary(x, y, z) ? 18.0 : exact[i]).epsilon(1e-6));
      }
}

TEST_CASE("first_collision: plain iteration by pulses and BiCGStab on the source agree", "[truth]") {
  // Plain: the pulses A^k s stepped alone, their totals summed; BiCGStab: (I - A) x = s. All 19
  // solutions in plain batches: B00 runs in a batch of its own, the others as usual.
  auto scene = [](const std::string& method) {
    return parse_scene(R"({"version": 1, "models": [{"name": "tree", "density": {"type": "procedural",
        "shape": "plant", "resolution": 12, "seed": 3, "size": 3.0}, "material": "leaf", "wood_material": "bark"}],
        "lighting": {"mode": "base", "solutions": "all"}, "solver": {"iterations": "auto", "tolerance": 1e-6,
        "model": "calibrated", "precision": "float64", "method": ")" + method + R"(",
        "calibration": {"first_collision": true}}})", method + ".json");
  };
  const Scene plain = scene("plain"), krylov = scene("bicgstab");
  const BakePlan pp = make_plan(plain), kp = make_plan(krylov);
  std::map<int, SolutionResult> a, b;
  auto backend = cpu_backend(0);
  REQUIRE(solution_batches(pp.models[0], *backend, {}).front() == std::vector<int>{0});  // B00 alone
  KeepSolutions ka(a), kb(b);
  bake_model(pp.models[0], *backend, {}, ka);
  bake_model(kp.models[0], *backend, {}, kb);
  REQUIRE(a.size() == 19);
  for (int c = 0; c < 3; ++c) {
    CAPTURE(c);
    CHECK(a.at(0).converged);
    CHECK(max_relative_difference(b.at(0).totals[c], a.at(0).totals[c], 1e-6) < 2e-5);
    CHECK(max_relative_difference(b.at(6).totals[c], a.at(6).totals[c], 1e-6) < 2e-5);
  }
}

TEST_CASE("first_collision: on a sparse plant B00 comes closer to physical light", "[truth]") {
  // Measured on the 48^3 plant of configs/report: 0.106 -> 0.042 (docs/accuracy.md); this 24^3
  // one: 0.053 -> 0.037 against this 1.5% reference.
  auto scene_text = [](const std::string& extra) {
    return R"({"version": 1, "models": [{"name": "tree", "density": {"type": "procedural", "shape": "plant",
        "resolution": 24, "seed": 7, "size": 4.0}, "material": "leaf", "wood_material": "bark"}],
        "lighting": {"mode": "base", "solutions": "0"}, "solver": {"iterations": "auto", "tolerance": 1e-5,
        "model": "calibrated")" + extra + "}}";
  };
  const Scene cal = parse_scene(scene_text(""), "cal.json");
  const Scene fc = parse_scene(scene_text(R"(, "method": "bicgstab", "calibration": {"first_collision": true})"), "fc.json");
  const BakePlan cp = make_plan(cal), fp = make_plan(fc);
  std::map<int, SolutionResult> lb_cal, lb_fc;
  auto backend = cpu_backend(0);
  KeepSolutions kc(lb_cal), kf(lb_fc);
  bake_model(cp.models[0], *backend, {}, kc);
  bake_model(fp.models[0], *backend, {}, kf);
  MonteCarloOptions mc;
  mc.target_error = 0.015;
  const ModelPlan& mp = cp.models[0];
  const SolutionResult truth = trace_solution(mp, cal, mp.solutions[0], mc, 0);
  auto error = [&](const std::vector<float>& lb) {
    double d = 0, n = 0;
    for (std::size_t i = 0; i < lb.size(); ++i)
      if (mp.lattice.density[i] > 0) {
        d += (lb[i] - truth.totals[0][i]) * (lb[i] - truth.totals[0][i]);
        n += static_cast<double>(truth.totals[0][i]) * truth.totals[0][i];
      }
    return std::sqrt(d / n);
  };
  const double e_cal = error(lb_cal.at(0).totals[0]), e_fc = error(lb_fc.at(0).totals[0]);
  CAPTURE(e_cal, e_fc, truth.error_estimate);
  CHECK(e_fc < 0.8 * e_cal);
  CHECK(e_fc < 0.05);
}

TEST_CASE("first_collision is refused where it cannot apply", "[truth]") {
  const std::string head = R"({"version": 1, "models": [{"name": "cube", "density": {"type": "procedural",
      "shape": "box", "resolution": 6, "size": 6.0}, "material": "cloud"}], "lighting": {"mode": "base"},
      "solver": {"model": "calibrated", "calibration": {"first_collision": true})";
  // DSA corrects a state that light enters through the boundary
  REQUIRE_THROWS_WITH(parse_scene(head + R"(, "method": "dsa"}})", "dsa.json"),
                      Catch::Contains("first_collision") && Catch::Contains("dsa"));
  // it is built on isotropic_ambient and remove_absorbed
  REQUIRE_THROWS_WITH(parse_scene(R"({"version": 1, "models": [{"name": "cube", "density": {"type": "procedural",
      "shape": "box", "resolution": 6, "size": 6.0}, "material": "cloud"}], "lighting": {"mode": "base"},
      "solver": {"model": "calibrated", "calibration": {"first_collision": true, "isotropic_ambient": false}}})",
                                  "anisotropic.json"),
                      Catch::Contains("isotropic_ambient"));
  // the exact uncollided light has no ground
  const Scene grounded = parse_scene(head + R"(, "method": "bicgstab"}, "ground": {"albedo": 0.2}})", "ground.json");
  REQUIRE_THROWS_WITH(make_plan(grounded), Catch::Contains("ground") && Catch::Contains("first_collision"));
  // a static bake has no B00
  const Scene sunlit = parse_scene(R"({"version": 1, "models": [{"name": "cube", "density": {"type": "procedural",
      "shape": "box", "resolution": 6, "size": 6.0}, "material": "cloud"}], "lighting": {"mode": "static",
      "sun": {"elevation": 35, "azimuth": 20}}, "solver": {"model": "calibrated", "method": "bicgstab",
      "calibration": {"first_collision": true}}})", "static.json");
  REQUIRE_THROWS_WITH(make_plan(sunlit), Catch::Contains("static") && Catch::Contains("first_collision"));
}
