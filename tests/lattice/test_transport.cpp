// The update rule (docs/model.md sec. 3) and boundary conditions (sec. 4) on small lattices: the CPU
// backend against the literal reference, and the properties docs/model.md promises.
#include <catch2/catch.hpp>

#include <cmath>

#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/sun.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {
std::array<double, 19> base(int j) { return base_boundary(j); }
}  // namespace

TEST_CASE("Conformance catches a wrong update (the comparison can fail)", "[transport]") {
  const LatticeGeometry g = random_lattice({12, 12, 12}, 0.9f, 0.0, 4);
  const OpticalParams p{0.1, 0.8, 0.3};
  ReferenceLattice ref(g, {build_omega(p)}, {false}, base(1));
  ref.step(10);
  // same scene, one step more: must differ well beyond the tolerance used above
  const auto off = solve_totals(*cpu_backend(), g, {channel(p, false)}, system_for(0, base(1)), 11);
  CHECK(max_relative_difference(ref.totals(), off, 1e-3) > 1e-3);
}

TEST_CASE("g = 1 with sigma_a = 0 is a pass-through", "[transport]") {
  const Dims d{16, 12, 10};
  const auto backend = cpu_backend();
  const OpticalParams forward{0.0, 0.9, 1.0};
  for (int sol : {1, 8, 17, 0}) {
    const auto dense = solve_totals(*backend, uniform_lattice(d, 1.0f), {channel(forward, false)}, system_for(0, base(sol)), 20);
    const auto empty = solve_totals(*backend, uniform_lattice(d, 0.0f), {channel(forward, false)}, system_for(0, base(sol)), 20);
    INFO("solution " << sol);
    CHECK(dense == empty);
  }
  // and a medium that scatters differently does change the result
  const auto scattering = solve_totals(*backend, uniform_lattice(d, 1.0f), {channel({0.0, 0.9, 0.5}, false)},
                                       system_for(0, base(1)), 20);
  const auto empty = solve_totals(*backend, uniform_lattice(d, 0.0f), {channel({0.0, 0.9, 0.5}, false)},
                                  system_for(0, base(1)), 20);
  CHECK(scattering != empty);
}

TEST_CASE("A density-0 lattice transports boundary values exactly", "[transport]") {
  const Dims d{9, 7, 8};
  const auto backend = cpu_backend();
  const LatticeGeometry g = uniform_lattice(d, 0.0f);
  for (int sol = 0; sol < 19; ++sol) {
    const auto t = solve_totals(*backend, g, {channel({0.2, 0.7, 0.4}, true)}, system_for(0, base(sol)), 12);
    for (int z = 0; z < d.nz; ++z)
      for (int y = 0; y < d.ny; ++y)
        for (int x = 0; x < d.nx; ++x) {
          // interior: every moving direction carries its boundary value unchanged; f_0 stays 0
          const float want = d.is_boundary(x, y, z) ? (sol == 0 ? 19.0f : 1.0f) : (sol == 0 ? 18.0f : 1.0f);
          REQUIRE(t[d.index(x, y, z)] == want);
        }
  }
}

TEST_CASE("Light arrives one node per step (t = 0 interior is empty)", "[transport]") {
  const Dims d{12, 5, 5};
  const auto t3 = solve_totals(*cpu_backend(), uniform_lattice(d, 0.0f), {channel({0, 0.5, 0}, false)},
                               system_for(0, base(1)), 3);
  // +x light from the x = 0 boundary reaches x = 3 after 3 steps, not x = 4
  CHECK(t3[d.index(3, 2, 2)] == 1.0f);
  CHECK(t3[d.index(4, 2, 2)] == 0.0f);
}

TEST_CASE("B_0 equals the sum of B_1..B_18 in the interior", "[transport]") {
  const Dims d{14, 11, 13};
  const LatticeGeometry g = random_lattice(d, 0.9f, 0.1, 7);
  const auto backend = cpu_backend();
  const auto ch = channel({0.109, 0.891, 0.091}, true);
  const auto b0 = solve_totals(*backend, g, {ch}, system_for(0, base(0)), 30, Precision::Float64);
  std::vector<double> sum(d.count(), 0.0);
  for (int j = 1; j < 19; ++j) {
    const auto bj = solve_totals(*backend, g, {ch}, system_for(0, base(j)), 30, Precision::Float64);
    for (std::size_t i = 0; i < sum.size(); ++i) sum[i] += bj[i];
  }
  for (int z = 1; z < d.nz - 1; ++z)
    for (int y = 1; y < d.ny - 1; ++y)
      for (int x = 1; x < d.nx - 1; ++x) {
        const std::size_t i = d.index(x, y, z);
        REQUIRE(b0[i] == Approx(sum[i]).epsilon(1e-6));
      }
}

TEST_CASE("Relighting from base solutions equals a static bake", "[transport]") {
  const Dims d{15, 13, 12};
  const LatticeGeometry g = random_lattice(d, 0.8f, 0.1, 9);
  const auto backend = cpu_backend();
  const auto ch = channel({0.109, 0.891, -0.12}, true, {0.109, 0.891, -1.0}, false);
  const Vec3d toward = toward_sun_from_angles(35.0, 120.0);
  const SunWeights w = decompose_direction({-toward.x, -toward.y, -toward.z});
  const double s = 1.7, a = 0.3;
  const int steps = 40;
  const auto stat = solve_totals(*backend, g, {ch}, system_for(0, static_boundary(w, s, a)), steps);
  std::vector<double> relit(d.count(), 0.0);
  const auto amb = solve_totals(*backend, g, {ch}, system_for(0, base(0)), steps);
  for (std::size_t i = 0; i < relit.size(); ++i) relit[i] = a * amb[i];
  for (int k = 0; k < 3; ++k) {
    const auto bk = solve_totals(*backend, g, {ch}, system_for(0, base(w.direction[k])), steps);
    for (std::size_t i = 0; i < relit.size(); ++i) relit[i] += s * w.weight[k] * bk[i];
  }
  CHECK(max_relative_difference(relit, stat, 1e-3) < 2e-6);
}

TEST_CASE("Mass is conserved away from the boundary and lost only through it", "[transport]") {
  const Dims d{21, 21, 21};
  const LatticeGeometry g = uniform_lattice(d, 0.8f);
  const auto backend = cpu_backend();
  SolverOptions so;
  so.precision = Precision::Float64;
  so.max_systems = 1;
  auto solver = backend->create(g, {channel({0.05, 0.7, 0.4}, false)}, so);
  solver->reset({system_for(0, std::array<double, 19>{})});
  std::vector<double> f(19 * d.count(), 0.0);
  const std::size_t centre = d.index(10, 10, 10);
  for (int m = 0; m < 19; ++m) f[m * d.count() + centre] = 1.0 + m;  // arbitrary, unbalanced pulse
  state_of(*solver).write_state(0, f);
  auto mass = [&] {
    std::vector<double> s;
    state_of(*solver).read_state(0, s);
    double t = 0;
    for (double v : s) t += v;
    return t;
  };
  const double m0 = mass();
  solver->step(8);  // the pulse spreads at most 8 nodes: still inside
  CHECK(mass() == Approx(m0).epsilon(1e-13));
  solver->step(40);  // now light has left through the boundary
  CHECK(mass() < 0.99 * m0);
}
