// The gas solver (lblight/fluid, docs/fluid.md): the collision conserves mass and momentum (the
// force adds exactly F), a force-driven channel between bounce-back walls reaches Poiseuille's
// parabola, a shear wave decays at the viscosity (tau - 1/2)/3, a hot blob rises and a cold one
// sinks, walls and obstacles pass no smoke, unstable settings are refused up front, and results
// do not depend on the thread count.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "lblight/core/error.h"
#include "lblight/fluid/bgk.h"
#include "lblight/fluid/gas_solver.h"

using namespace lblight;
using namespace lblight::fluid;

namespace {

constexpr double kPi = 3.14159265358979323846;

// Height of the scalar's centre of mass.
double centroid_z(const GasSolver& g, const std::vector<double>& s) {
  const Dims& d = g.settings().dims;
  double w = 0, wz = 0;
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x) {
        const double v = s[d.index(x, y, z)];
        w += v;
        wz += v * z;
      }
  return wz / w;
}

}  // namespace

TEST_CASE("gas: the equilibrium has the node's density and momentum, and the collision conserves both (force adds F)",
          "[fluid]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.01, 0.1);
  for (int trial = 0; trial < 20; ++trial) {
    const double rho = 0.8 + 0.4 * u(rng) * 10, ux = u(rng) - 0.05, uy = u(rng) - 0.05, uz = u(rng) - 0.05;
    double r = 0, jx = 0, jy = 0, jz = 0;
    for (int m = 0; m < d3q19::kQ; ++m) {
      const double f = equilibrium<double>(m, rho, ux, uy, uz);
      r += f;
      jx += f * d3q19::cx(m);
      jy += f * d3q19::cy(m);
      jz += f * d3q19::cz(m);
    }
    CHECK(r == Approx(rho).epsilon(1e-13));
    CHECK(jx == Approx(rho * ux).margin(1e-14));
    CHECK(jy == Approx(rho * uy).margin(1e-14));
    CHECK(jz == Approx(rho * uz).margin(1e-14));
    double f[d3q19::kQ];
    for (double& v : f) v = u(rng);
    const Moments before = moments(f, 0, 0, 0);
    const double fx = 1e-3 * trial, fz = -2e-3;
    collide(f, 0.7, fx, 0.0, fz);
    const Moments after = moments(f, 0, 0, 0);
    CHECK(after.rho == Approx(before.rho).epsilon(1e-13));
    CHECK(after.rho * after.ux == Approx(before.rho * before.ux + fx).margin(1e-13));
    CHECK(after.rho * after.uy == Approx(before.rho * before.uy).margin(1e-13));
    CHECK(after.rho * after.uz == Approx(before.rho * before.uz + fz).margin(1e-13));
  }
}

TEST_CASE("gas: a force-driven channel between bounce-back walls reaches Poiseuille's parabola within 2%", "[fluid]") {
  // Walls half-way outside nodes 0 and H-1 (y), periodic x and z: u(y) = F / (2 nu) (y + 1/2) (H - 1/2 - y).
  GasSettings s;
  const int h = 16;
  s.dims = {4, h, 4};
  s.tau = 1.0;
  s.force = {1e-6, 0, 0};
  s.faces = {FaceType::Periodic, FaceType::Periodic, FaceType::Wall, FaceType::Wall, FaceType::Periodic, FaceType::Periodic};
  GasSolver g(s);
  const double nu = (s.tau - 0.5) / 3;
  g.step(static_cast<int>(4 * h * h / nu));  // several diffusion times
  const auto u = g.velocity();
  double worst = 0, peak = 0;
  for (int y = 0; y < h; ++y) {
    const double exact = s.force[0] / (2 * nu) * (y + 0.5) * (h - 0.5 - y);
    peak = std::max(peak, exact);
    worst = std::max(worst, std::fabs(u[0][s.dims.index(1, y, 1)] - exact));
  }
  INFO("largest deviation " << worst << " of the peak " << peak);
  CHECK(worst < 0.02 * peak);
}

TEST_CASE("gas: a shear wave decays at the viscosity (tau - 1/2)/3", "[fluid]") {
  for (const double tau : {0.6, 0.9}) {
    GasSettings s;
    const int l = 32;
    s.dims = {2, l, 2};
    s.tau = tau;
    GasSolver g(s);
    std::array<std::vector<double>, 3> u;
    for (auto& c : u) c.assign(s.dims.count(), 0.0);
    const double amp = 1e-3, k = 2 * kPi / l;
    for (int z = 0; z < 2; ++z)
      for (int y = 0; y < l; ++y)
        for (int x = 0; x < 2; ++x) u[0][s.dims.index(x, y, z)] = amp * std::sin(k * y);
    g.set_state(std::vector<double>(s.dims.count(), 1.0), u, {}, {});
    const int t = 400;
    g.step(t);
    // Amplitude by projection on the sine.
    const auto v = g.velocity();
    double a = 0;
    for (int y = 0; y < l; ++y) a += v[0][s.dims.index(0, y, 0)] * std::sin(k * y);
    a *= 2.0 / l;
    const double nu = -std::log(a / amp) / (k * k * t);
    INFO("tau " << tau);
    CHECK(nu == Approx((tau - 0.5) / 3).epsilon(0.01));
  }
}

TEST_CASE("gas: a hot blob rises and a cold one sinks", "[fluid]") {
  for (const double dt : {+1.0, -1.0}) {
    GasSettings s;
    s.dims = {16, 16, 32};
    s.tau = 0.6;
    s.buoyancy = 1e-3;
    s.t_ambient = 0;
    s.tau_temperature = 0.52;
    s.faces = {FaceType::Wall, FaceType::Wall, FaceType::Wall, FaceType::Wall, FaceType::Wall, FaceType::Wall};
    GasSolver g(s);
    std::vector<double> temp(s.dims.count(), 0.0);
    for (int z = 0; z < s.dims.nz; ++z)
      for (int y = 0; y < s.dims.ny; ++y)
        for (int x = 0; x < s.dims.nx; ++x) {
          const double r2 = std::pow(x - 7.5, 2) + std::pow(y - 7.5, 2) + std::pow(z - 15.5, 2);
          temp[s.dims.index(x, y, z)] = dt * std::exp(-r2 / 8.0);
        }
    g.set_state({}, {}, temp, {});
    const double before = centroid_z(g, [&] {
      std::vector<double> a = g.temperature();
      for (double& v : a) v = std::fabs(v);
      return a;
    }());
    g.step(400);
    std::vector<double> after_t = g.temperature();
    for (double& v : after_t) v = std::fabs(v);
    const double after = centroid_z(g, after_t);
    INFO("temperature " << dt << ": centroid z " << before << " -> " << after);
    CHECK((after - before) * dt > 2.0);  // moved at least two nodes the right way
    CHECK(g.total_mass() == Approx(static_cast<double>(s.dims.count())).epsilon(1e-5));  // closed box
  }
}

TEST_CASE("gas: walls and obstacles pass no smoke and conserve it, with an inlet feeding an open top", "[fluid]") {
  GasSettings s;
  s.dims = {12, 12, 24};
  s.tau = 0.6;
  s.tau_smoke = 0.55;
  s.faces = {FaceType::Wall, FaceType::Wall, FaceType::Wall, FaceType::Wall, FaceType::Wall, FaceType::Open};
  // A solid plate at z = 12 with the left half of the box sealed off from the right by a wall x = 5.
  s.solid.assign(s.dims.count(), 0);
  for (int z = 0; z < s.dims.nz; ++z)
    for (int y = 0; y < s.dims.ny; ++y) s.solid[s.dims.index(5, y, z)] = 1;
  s.inlet.enabled = true;
  s.inlet.x0 = 1, s.inlet.x1 = 3, s.inlet.y0 = 4, s.inlet.y1 = 7;
  s.inlet.speed = 0.05;
  s.inlet.smoke = 1.0;
  GasSolver g(s);
  g.step(400);
  const auto c = g.smoke();
  double left = 0, right = 0;
  for (int z = 0; z < s.dims.nz; ++z)
    for (int y = 0; y < s.dims.ny; ++y)
      for (int x = 0; x < s.dims.nx; ++x) (x < 5 ? left : right) += c[s.dims.index(x, y, z)];
  INFO("smoke left of the wall " << left << ", right " << right);
  CHECK(left > 10);
  CHECK(right == 0.0);  // not a trace: nothing streams through a solid node
  // Closed box, no inlet: the smoke put in stays, to float rounding.
  GasSettings closed = s;
  closed.inlet.enabled = false;
  closed.faces[5] = FaceType::Wall;
  GasSolver h(closed);
  std::vector<double> puff(closed.dims.count(), 0.0);
  for (int z = 4; z < 8; ++z)
    for (int y = 4; y < 8; ++y)
      for (int x = 1; x < 4; ++x) puff[closed.dims.index(x, y, z)] = 1.0;
  h.set_state({}, {}, {}, puff);
  h.step(300);
  double total = 0;
  for (double v : h.smoke()) total += v;
  CHECK(total == Approx(48.0).epsilon(1e-5));
}

TEST_CASE("gas: unstable or out-of-model settings are refused before anything runs", "[fluid]") {
  GasSettings s;
  s.tau = 0.5005;
  CHECK_THROWS_WITH(GasSolver(s), Catch::Contains("tau = 0.5005") && Catch::Contains("allowed: 0.503 <= tau"));
  s.tau = 0.6;
  s.inlet.enabled = true;
  s.inlet.x0 = 0, s.inlet.x1 = 2, s.inlet.y0 = 0, s.inlet.y1 = 2;
  s.inlet.speed = 0.2;
  CHECK_THROWS_WITH(GasSolver(s), Catch::Contains("Mach") && Catch::Contains("allowed: Mach <= 0.3"));
  s.inlet.speed = 0.05;
  s.inlet.x1 = 99;
  CHECK_THROWS_WITH(GasSolver(s), Catch::Contains("inlet patch"));
  s.inlet.x1 = 2;
  CHECK_NOTHROW(GasSolver(s));
}

TEST_CASE("gas: the same fields for any thread count", "[fluid]") {
  GasSettings s;
  s.dims = {10, 9, 14};
  s.buoyancy = 1e-3;
  s.faces = {FaceType::Wall, FaceType::Wall, FaceType::Periodic, FaceType::Periodic, FaceType::Wall, FaceType::Open};
  s.inlet.enabled = true;
  s.inlet.x0 = 3, s.inlet.x1 = 6, s.inlet.y0 = 2, s.inlet.y1 = 5;
  s.inlet.temperature = 1;
  s.threads = 1;
  GasSolver a(s);
  s.threads = 2;
  GasSolver b(s);
  a.step(50);
  b.step(50);
  CHECK(a.smoke() == b.smoke());
  CHECK(a.velocity()[2] == b.velocity()[2]);
}
