// The reflective ground (docs/model.md sec. 4.3): its operator, the energy it keeps, the open-air
// light over it, superposition of base solutions, and that a black ground (albedo 0) leaves every
// solution lit from above exactly as it was without a ground.
#include <catch2/catch.hpp>

#include <cmath>
#include <map>

#include "lblight/lattice/collision_op.h"
#include "lblight/lattice/ground.h"
#include "lblight/lattice/lb_model.h"
#include "lblight/lattice/sun.h"
#include "lblight/solve/bake.h"
#include "lblight/solve/plan.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;
using d3q19::kQ;

namespace {

const std::array<double, kQ> kPaperShare = ground_share(ambient_boundary(LbModel{}));

// An empty lattice (or `rho` everywhere) standing on a ground layer at z = 1.
LatticeGeometry on_ground(Dims d, float rho) {
  LatticeGeometry g = uniform_lattice(d, rho);
  for (int y = 1; y < d.ny - 1; ++y)
    for (int x = 1; x < d.nx - 1; ++x) {
      g.density[d.index(x, y, 1)] = 1.0f;
      g.material[d.index(x, y, 1)] = kMaterialGround;
    }
  g.material_count = 3;
  return g;
}

ChannelMaterials with_ground(ChannelMaterials ch, double albedo) {
  ch.omega[kMaterialGround] = ground_omega(albedo, kPaperShare);
  ch.absorbs[kMaterialGround] = true;
  return ch;
}

struct Baked {
  BakePlan plan;
  std::map<int, SolutionResult> solutions;
};

Baked bake_scene(const Scene& scene) {
  Baked r;
  r.plan = make_plan(scene);
  auto backend = cpu_backend(0);
  KeepSolutions keep(r.solutions);
  bake_model(r.plan.models.at(0), *backend, {}, keep);
  return r;
}

std::string plant(const std::string& ground, const std::string& lighting = R"({"mode": "base", "solutions": "all"})") {
  return R"({"version": 1, "models": [{"name": "m", "density": {"type": "procedural", "shape": "plant", "resolution": 10,
             "seed": 3}, "material": "leaf", "wood_material": "paper-bark"}], "lighting": )" + lighting +
         R"(, "solver": {"iterations": 400, "model": "paper"})" + ground +
         "}";  // fixed: the same steps with and without a ground; B00 the plain sum of the 18 (papers' model)
}

}  // namespace

TEST_CASE("Ground operator: light arriving from above goes back up with the albedo, spread by u_m", "[ground]") {
  double sum_up = 0;
  for (int m = 1; m < kQ; ++m) sum_up += kPaperShare[m] * (upward(m) ? 1 : 0);
  CHECK(sum_up == Approx(1.0).epsilon(1e-15));
  CHECK(kPaperShare[5] == Approx(0.2));  // the papers' isotropic light: the same on every direction
  const auto iso = ground_share(ambient_boundary([] {
    LbModel m;
    m.calibrated = true;
    return m;
  }()));
  CHECK(iso[5] == Approx(2.0 * iso[11]));  // calibrated: 18 w_i, axial twice a diagonal
  const OmegaMatrix o = ground_omega(0.3, kPaperShare);
  REQUIRE_NOTHROW(reduce_omega(o));  // centrally symmetric, as every kernel needs
  for (int n = 1; n < kQ; ++n) {
    // one unit of light along n at a ground node (density 1): post = f + Omega f
    std::array<double, kQ> post{};
    for (int m = 0; m < kQ; ++m) post[m] = (m == n ? 1.0 : 0.0) + o[m * kQ + n];
    double up = 0, rest = 0;
    for (int m = 0; m < kQ; ++m) (upward(m) ? up : rest) += post[m];
    if (downward(n)) {
      CHECK(up == Approx(0.3));
      CHECK(rest == Approx(0.0).margin(1e-15));
    } else {
      CHECK(up == Approx(0.0).margin(1e-15));  // from below or level: never up into the medium
    }
  }
}

TEST_CASE("Energy bookkeeping with a ground closes every step, and albedo 1 over a lossless medium loses nothing",
          "[ground][energy]") {
  const Dims d{9, 8, 10};
  const OpticalParams cloud{0.0, 0.6, 0.3};
  for (double albedo : {1.0, 0.4}) {
    INFO("albedo " << albedo);
    const LatticeGeometry g = on_ground(d, 0.0f);
    LatticeGeometry m = g;
    for (int z = 3; z < 7; ++z)
      for (int y = 2; y < 6; ++y)
        for (int x = 2; x < 7; ++x) m.density[d.index(x, y, z)] = 0.8f;
    const std::vector<OmegaMatrix> omega{build_omega(cloud), build_omega(cloud), ground_omega(albedo, kPaperShare)};
    ReferenceLattice ref(m, omega, {false, false, true}, with_open_ground(base_boundary(12), albedo, kPaperShare));
    double worst = 0;
    for (int t = 0; t < 400; ++t) {
      const StepBalance b = ref.balance();
      ref.step();
      worst = std::max(worst, std::fabs(ref.stored() - b.predicted_next()) / b.inflow);
    }
    CHECK(worst < 1e-12);
    const StepBalance b = ref.balance();
    CHECK(b.absorbed == 0.0);  // the cloud keeps its f_0
    CHECK(std::fabs(b.inflow - b.outflow - b.ground) / b.inflow < 1e-9);  // steady state
    if (albedo == 1.0) CHECK(std::fabs(b.ground) / b.inflow < 1e-12);
    else CHECK(b.ground / b.inflow > 0.05);
  }
}

TEST_CASE("Open air over the ground: a sun from above is 1 + albedo everywhere, a level one 1, one from below 0",
          "[ground]") {
  const Dims d{8, 7, 9};
  const LatticeGeometry g = on_ground(d, 0.0f);
  const double albedo = 0.35;
  const ChannelMaterials ch = with_ground(channel({0.1, 0.9, 0.0}, true), albedo);
  for (int j : {6, 12, 17, 1, 8, 5, 11, 0}) {
    const auto t = solve_totals(*cpu_backend(1), g, {ch}, system_for(0, with_open_ground(base_boundary(j), albedo, kPaperShare)), 40);
    // B00: the 13 directions that are not upward, and A times its 5 downward ones reflected
    const double want = j == 0 ? 13.0 + 5.0 * albedo : upward(j) ? 0.0 : downward(j) ? 1.0 + albedo : 1.0;
    double worst = 0;
    for (int z = 2; z < d.nz - 1; ++z)
      for (int y = 1; y < d.ny - 1; ++y)
        for (int x = 1; x < d.nx - 1; ++x) worst = std::max(worst, std::fabs(t[d.index(x, y, z)] - want) / std::max(1.0, want));
    INFO("B" << j);
    CHECK(worst < 1e-6);
  }
}

TEST_CASE("A black ground leaves every solution lit from above exactly as without a ground", "[ground][slow]") {
  const Scene bare = parse_scene(plant(""), "bare.json");
  const Scene black = parse_scene(plant(R"(, "ground": {"albedo": 0})"), "black.json");
  const Baked a = bake_scene(bare), b = bake_scene(black);
  const ModelPlan &pa = a.plan.models[0], &pb = b.plan.models[0];
  REQUIRE(pb.ground.on);
  REQUIRE(pb.lattice.dims.nz == pa.lattice.dims.nz + 1);  // boundary, ground, then the grid
  const int dz = pa.lattice_index_min[2] - pb.lattice_index_min[2];
  REQUIRE(dz == 1);
  const Dims &da = pa.lattice.dims, &db = pb.lattice.dims;
  for (int j = 1; j < kQ; ++j) {
    if (upward(j)) continue;
    const auto &ta = a.solutions.at(j).totals, &tb = b.solutions.at(j).totals;
    long long differ = 0, compared = 0;
    for (int z = 1; z < da.nz - 1; ++z)
      for (int y = 1; y < da.ny - 1; ++y)
        for (int x = 1; x < da.nx - 1; ++x)
          for (int c = 0; c < 3; ++c) {
            differ += ta[c][da.index(x, y, z)] != tb[c][db.index(x, y, z + dz)];
            ++compared;
          }
    INFO("B" << j);
    CHECK(compared > 1000);
    CHECK(differ == 0);
  }
  // light from below reaches the plant only without the ground
  CHECK(a.solutions.at(5).totals[1][da.index(da.nx / 2, da.ny / 2, 1)] > 0.5f);
}

TEST_CASE("Over a ground, B00 is still the sum of the 18 directional solutions, and a sunlit plant is brighter",
          "[ground][slow]") {
  Scene s = parse_scene(plant(R"(, "ground": {"albedo": [0.2, 0.3, 0.4]})"), "ground.json");
  s.lighting.ambient_from_sum = false;
  const Baked r = bake_scene(s);
  const ModelPlan& mp = r.plan.models[0];
  REQUIRE(mp.channels.size() == 3);  // the albedo differs per channel
  for (int c = 0; c < 3; ++c) {
    std::vector<float> sum(mp.lattice.dims.count(), 0.0f);
    for (int j = 1; j < kQ; ++j)
      for (std::size_t i = 0; i < sum.size(); ++i) sum[i] += r.solutions.at(j).totals[c][i];
    const auto medium = mp.lattice.medium_density();
    std::vector<float> a, b;
    for (std::size_t i = 0; i < sum.size(); ++i)
      if (medium[i] > 0) a.push_back(r.solutions.at(0).totals[c][i]), b.push_back(sum[i]);
    INFO("channel " << c);
    CHECK(max_relative_difference(a, b, 1.0) < 2e-4);
  }
  // the same plant without a ground, lit from straight above: the ground adds light from below
  const Baked bare = bake_scene(parse_scene(plant(""), "bare.json"));
  const auto medium = mp.lattice.medium_density();
  double with = 0, without = 0;
  const Dims &dg = mp.lattice.dims, &d0 = bare.plan.models[0].lattice.dims;
  for (int z = 2; z < dg.nz - 1; ++z)
    for (int y = 1; y < dg.ny - 1; ++y)
      for (int x = 1; x < dg.nx - 1; ++x)
        if (medium[dg.index(x, y, z)] > 0) {
          with += r.solutions.at(6).totals[2][dg.index(x, y, z)];
          without += bare.solutions.at(6).totals[2][d0.index(x, y, z - 1)];
        }
  CHECK(with > without * 1.05);
}
