// Warm starts (BakeOptions::warm, docs/fluid.md "Lighting every frame"): a frame of a moving medium
// solved from the previous frame's final state reaches the same light as one solved from zero,
// within the tolerance of a tight reference, in fewer steps; deterministic; a state of another
// lattice is not used.
#include <catch2/catch.hpp>

#include <cmath>
#include <map>
#include <string>

#include "lblight/solve/bake.h"
#include "lblight/solve/plan.h"
#include "tests/backend/emulated_gpu.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {

// A static sun and a smoke-like grey scatterer, as configs/chimney.json lights its plume.
Scene smoke_scene(const std::string& tolerance) {
  return parse_scene(R"({"version": 1, "models": [{"name": "smoke", "density": {"type": "procedural", "shape": "cloud",
    "resolution": 8}, "material": {"name": "smoke", "sigma_a": 0.1, "sigma_s": 0.9, "g": 0.3, "absorb": true}}],
    "lighting": {"mode": "static", "sun": {"elevation": 35, "azimuth": 20}, "ambient": 0.05},
    "solver": {"tolerance": )" + tolerance + "}}",
                     "warm.json");
}

// A ball of smoke (density 0.6 in the middle, falling off) centred at height `z` in a 14 x 14 x 20
// box: the frames of a rising puff.
ModelGrid puff(double z) {
  ModelGrid g;
  g.dims = {14, 14, 20};
  g.index_to_world = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  g.density.assign(g.dims.count(), 0.0f);
  g.material.assign(g.dims.count(), kMaterialMedium);
  for (int k = 0; k < g.dims.nz; ++k)
    for (int j = 0; j < g.dims.ny; ++j)
      for (int i = 0; i < g.dims.nx; ++i) {
        const double r2 = (i - 6.5) * (i - 6.5) + (j - 6.5) * (j - 6.5) + (k - z) * (k - z);
        if (r2 < 25.0) g.density[g.dims.index(i, j, k)] = static_cast<float>(0.6 * (1.0 - r2 / 25.0));
      }
  return g;
}

struct Frame {
  SolutionResult result;
  bool warm = false;
};

// One frame planned on the whole box (as a gas frame is) and baked, from `warm` when given.
Frame bake_frame(const Scene& scene, double z, WarmStart* warm, Precision p = Precision::Float32,
                 const Backend* backend = nullptr) {
  PlanOverrides ov;
  ov.precision = p;
  BakePlan plan = plan_without_models(scene, ov);
  ModelSpec spec = scene.models.at(0);
  spec.crop = false;
  const ModelPlan mp = plan_model(plan, spec, puff(z), ov);
  std::map<int, SolutionResult> out;
  KeepSolutions keep(out);
  BakeOptions options;
  options.warm = warm;
  bake_model(mp, backend ? *backend : *cpu_backend(2), options, keep);
  REQUIRE(out.size() == 1);
  return {out.begin()->second, out.begin()->second.warm_start};
}

// ||a - ref|| / ||ref|| over all nodes and channels.
double relative_l2(const SolutionResult& a, const SolutionResult& ref) {
  double diff = 0, norm = 0;
  for (int c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < ref.totals[c].size(); ++i) {
      const double d = static_cast<double>(a.totals[c][i]) - ref.totals[c][i];
      diff += d * d;
      norm += static_cast<double>(ref.totals[c][i]) * ref.totals[c][i];
    }
  return std::sqrt(diff / norm);
}

}  // namespace

TEST_CASE("A warm-started frame reaches a cold start's light within the tolerance, in fewer steps", "[bake][warm]") {
  const double tolerance = 1e-3;
  const Scene scene = smoke_scene("1e-3");
  WarmStart states;
  const Frame first = bake_frame(scene, 7.0, &states);
  CHECK_FALSE(first.warm);  // nothing kept yet: from zero, and its final state kept
  REQUIRE(states.states.size() == 1);
  CHECK(states.states[0].size() == 19 * states.dims.count());

  const Frame warm = bake_frame(scene, 8.0, &states);  // the puff rose a node
  const Frame cold = bake_frame(scene, 8.0, nullptr);
  const Frame reference = bake_frame(smoke_scene("1e-8"), 8.0, nullptr, Precision::Float64);
  CHECK(warm.warm);
  CHECK_FALSE(cold.warm);
  REQUIRE(warm.result.converged);
  REQUIRE(cold.result.converged);
  const double warm_error = relative_l2(warm.result, reference.result);
  const double cold_error = relative_l2(cold.result, reference.result);
  INFO("steps: warm " << warm.result.iterations << ", cold " << cold.result.iterations << "; error against the "
                      << "reference: warm " << warm_error << " (estimate " << warm.result.error_estimate << "), cold "
                      << cold_error << " (estimate " << cold.result.error_estimate << ")");
  CHECK(warm_error < tolerance);
  CHECK(cold_error < tolerance);
  CHECK(warm_error <= warm.result.error_estimate);  // the estimate stays a bound from a warm start
  CHECK(warm.result.iterations < cold.result.iterations);

  // The same start gives the same light, bit for bit.
  WarmStart again;
  bake_frame(scene, 7.0, &again);
  const Frame repeat = bake_frame(scene, 8.0, &again);
  CHECK(repeat.result.iterations == warm.result.iterations);
  for (int c = 0; c < 3; ++c) CHECK(repeat.result.totals[c] == warm.result.totals[c]);
}

TEST_CASE("Warm starts through the GPU solver's state access (emulated device)", "[bake][warm][emulated]") {
  const Scene scene = smoke_scene("1e-3");
  const auto gpu = make_emulated_gpu_backend();
  WarmStart states;
  bake_frame(scene, 7.0, &states, Precision::Float32, gpu.get());
  const Frame warm = bake_frame(scene, 8.0, &states, Precision::Float32, gpu.get());
  const Frame cold = bake_frame(scene, 8.0, nullptr, Precision::Float32, gpu.get());
  const Frame reference = bake_frame(smoke_scene("1e-8"), 8.0, nullptr, Precision::Float64);
  INFO("steps: warm " << warm.result.iterations << ", cold " << cold.result.iterations);
  CHECK(warm.warm);
  CHECK(warm.result.iterations < cold.result.iterations);
  CHECK(relative_l2(warm.result, reference.result) < 1e-3);
}

TEST_CASE("States of another lattice do not start a frame", "[bake][warm]") {
  const Scene scene = smoke_scene("1e-3");
  WarmStart states;
  states.dims = {3, 3, 3};
  states.states.assign(1, std::vector<float>(19 * 27, 1.0f));
  const Frame f = bake_frame(scene, 7.0, &states);
  CHECK_FALSE(f.warm);
  CHECK(f.result.converged);
  CHECK(states.dims == Dims{16, 16, 22});  // this lattice's final state kept instead
}
