// The accelerated solver (solve/dsa.h, docs/model.md sec. 9): the same fixed point as plain
// iteration, an error estimate that bounds the true error, steps that do not grow with the
// lattice, plain iteration where DSA would not pay, and the same bits for any thread count.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <map>

#include "lblight/lattice/diffusion_limit.h"
#include "lblight/lattice/lb_model.h"
#include "lblight/scene/scene.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {

std::string number(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

// A cube filling the lattice (the dense cloud of docs/accuracy.md unless told otherwise).
std::string cube_scene(int r, const std::string& method, double tolerance, const std::string& extra = "",
                       const std::string& material = R"({"sigma_a": 0.008, "sigma_s": 0.792, "g": 0.0, "absorb": false})") {
  return R"({"version": 1, "models": [{"name": "cube", "density": {"type": "procedural", "shape": "box",
             "resolution": )" + std::to_string(r) + R"(, "size": )" + std::to_string(r) + R"(.0}, "material": )" + material +
         R"(}], "lighting": {"mode": "base", "solutions": "6"}, "solver": {"iterations": "auto", "tolerance": )" +
         number(tolerance) + R"(, "method": ")" + method + "\"" + extra + "}}";
}

struct Baked {
  SolutionResult result;
  ModelPlan plan;
};

SolutionResult bake_one(const std::string& text, int threads = 0, SolverMethod* method_used = nullptr) {
  static std::vector<std::unique_ptr<Scene>> keep;  // plans point into their scene
  keep.push_back(std::make_unique<Scene>(parse_scene(text, "dsa.json")));
  const BakePlan plan = make_plan(*keep.back());
  if (method_used) *method_used = plan.models[0].steps.method;
  std::map<int, SolutionResult> out;
  KeepSolutions keep_solutions(out);
  auto backend = cpu_backend(threads);
  bake_model(plan.models[0], *backend, {}, keep_solutions);
  return out.at(6);
}

double rel_l2(const std::vector<float>& a, const std::vector<float>& ref) {
  double d = 0, n = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    d += (static_cast<double>(a[i]) - ref[i]) * (static_cast<double>(a[i]) - ref[i]);
    n += static_cast<double>(ref[i]) * ref[i];
  }
  return std::sqrt(d / n);
}

}  // namespace

TEST_CASE("The diffusion limit of the papers' isotropic collision is eq. (4)", "[dsa]") {
  for (double st : {0.3, 0.8, 1.5}) {
    const OmegaMatrix om = build_omega({0.2 * st, 0.8 * st, 0.0});
    const DiffusionMode lossless = diffusion_mode(om, false), absorbing = diffusion_mode(om, true);
    CAPTURE(st);
    CHECK(lossless.diffusion(1.0, 0.0, 1e9) == Approx((1.0 / st - 0.5) / 2.0).epsilon(1e-9));
    CHECK(lossless.diffusion(0.5, 0.0, 1e9) == Approx((1.0 / (0.5 * st) - 0.5) / 2.0).epsilon(1e-9));
    CHECK(lossless.loss == Approx(0.0).margin(1e-12));  // f_0 re-emits what it absorbed
    CHECK(lossless.shape[0] == Approx(0.2 * st).epsilon(1e-9));  // the reservoir's equilibrium
    CHECK(absorbing.loss == Approx(0.2 * st).epsilon(1e-9));
    CHECK(absorbing.shape[0] == 0.0);
    for (int i = 1; i < 19; ++i) CHECK(lossless.shape[i] == Approx(d3q19::weight(i)).epsilon(1e-9));
    CHECK(lossless.relaxation(1.0) == Approx(st).epsilon(1e-9));  // BGK: omega = sigma_t
  }
}

TEST_CASE("DSA reaches the plain fixed point on a dense cube, within its estimate, in few steps", "[dsa]") {
  const SolutionResult ref = bake_one(cube_scene(20, "bicgstab", 1e-9, R"(, "precision": "float64")"));
  const SolutionResult plain = bake_one(cube_scene(20, "plain", 1e-4));
  const SolutionResult dsa = bake_one(cube_scene(20, "dsa", 1e-4));
  const double err = rel_l2(dsa.totals[0], ref.totals[0]);
  CAPTURE(dsa.iterations, plain.iterations, dsa.error_estimate, err);
  CHECK(dsa.converged);
  CHECK(err <= dsa.error_estimate);
  CHECK(err < 1e-4);
  CHECK(dsa.iterations * 8 < plain.iterations);
}

TEST_CASE("DSA steps do not grow with the lattice", "[dsa]") {
  const SolutionResult small = bake_one(cube_scene(12, "dsa", 1e-4));
  const SolutionResult large = bake_one(cube_scene(36, "dsa", 1e-4));
  CAPTURE(small.iterations, large.iterations);
  CHECK(small.converged);
  CHECK(large.converged);
  CHECK(large.iterations <= 2 * small.iterations);
}

TEST_CASE("DSA converges on absorbing media of the calibrated model and on backscattering wood", "[dsa]") {
  // the calibrated model removes absorbed light and stores voxel averages (total_gain)
  const std::string calibrated = R"(, "model": "calibrated")";
  const std::string medium = R"({"sigma_a": 0.05, "sigma_s": 0.75, "g": 0.3, "absorb": false})";
  const SolutionResult ref = bake_one(cube_scene(18, "bicgstab", 1e-9, calibrated + R"(, "precision": "float64")", medium));
  const SolutionResult dsa = bake_one(cube_scene(18, "dsa", 1e-4, calibrated, medium));
  const double err = rel_l2(dsa.totals[0], ref.totals[0]);
  CAPTURE(dsa.iterations, dsa.error_estimate, err);
  CHECK(dsa.converged);
  CHECK(err <= dsa.error_estimate);

  // bark (g = -1) reverses the flux every step: such nodes give no diffusion source (dsa.cpp),
  // and DSA, which diverged there before that rule, now does no worse than plain iteration
  // (neither converges in this budget: lossless backscatter diffuses very slowly)
  const std::string bark = R"({"preset": "bark"})", budget = R"(, "max_iterations": 400)";
  const SolutionResult bref = bake_one(cube_scene(12, "bicgstab", 1e-9, R"(, "precision": "float64")", bark));
  const SolutionResult bplain = bake_one(cube_scene(12, "plain", 1e-4, budget, bark));
  const SolutionResult bdsa = bake_one(cube_scene(12, "dsa", 1e-4, budget, bark));
  const double e_plain = rel_l2(bplain.totals[0], bref.totals[0]), e_dsa = rel_l2(bdsa.totals[0], bref.totals[0]);
  CAPTURE(bdsa.iterations, e_plain, e_dsa);
  CHECK(std::isfinite(e_dsa));
  CHECK(e_dsa <= 1.05 * e_plain);
}

TEST_CASE("DSA leaves absorbing plants to plain iteration, and gives the same bits for any thread count", "[dsa]") {
  SolverMethod used = SolverMethod::Dsa;
  bake_one(cube_scene(12, "dsa", 1e-4, "", R"({"sigma_a": 0.5, "sigma_s": 0.5, "g": 0.0, "absorb": true})"), 0, &used);
  CHECK(used == SolverMethod::Plain);

  const SolutionResult one = bake_one(cube_scene(16, "dsa", 1e-4), 1);
  const SolutionResult two = bake_one(cube_scene(16, "dsa", 1e-4), 2);
  CHECK(one.iterations == two.iterations);
  CHECK(one.totals[0] == two.totals[0]);
}
