// Collision matrix properties docs/model.md sec. 2 states and [Geist2010] sec. 7 derives.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <vector>

#include "lblight/lattice/collision_op.h"
#include "lblight/lattice/collide.h"
#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/ground.h"
#include "lblight/lattice/lb_model.h"
#include "lblight/lattice/omega.h"
#include "tests/support/test_support.h"

using namespace lblight;
using d3q19::kQ;

TEST_CASE("D3Q19 table: order, opposites and weights", "[lattice]") {
  REQUIRE(d3q19::cx(1) == 1);
  REQUIRE(d3q19::cy(4) == -1);
  REQUIRE(d3q19::cz(13) == -1);
  REQUIRE(d3q19::cx(14) == -1);
  REQUIRE(d3q19::cz(18) == 1);
  double w = 0;
  for (int m = 0; m < kQ; ++m) {
    const int o = d3q19::opposite(m);
    CHECK(d3q19::cx(o) == -d3q19::cx(m));
    CHECK(d3q19::cy(o) == -d3q19::cy(m));
    CHECK(d3q19::cz(o) == -d3q19::cz(m));
    w += d3q19::weight(m);
    CHECK(d3q19::length_sq(m) == (m == 0 ? 0 : (m <= 6 ? 1 : 2)));
  }
  CHECK(w == Approx(1.0));
}

TEST_CASE("Omega column sums vanish for every g (energy conservation)", "[omega]") {
  for (double g : {-1.0, -0.9, 0.0, 0.5, 0.9, 1.0}) {
    for (OpticalParams p : {OpticalParams{0.008, 0.792, g}, OpticalParams{0.109, 0.891, g}, OpticalParams{0.0, 1.3, g}}) {
      const OmegaMatrix om = build_omega(p);
      for (int j = 0; j < kQ; ++j) {
        double sum = 0;
        for (int i = 0; i < kQ; ++i) sum += om[i * kQ + j];
        INFO("g = " << g << ", column " << j);
        CHECK(std::fabs(sum) < 1e-14);
      }
    }
  }
}

TEST_CASE("Normalised phase function sums to one with the lattice weights", "[omega]") {
  for (double g : {-1.0, -0.999, -0.5, 0.0, 0.3, 0.999, 1.0})
    for (int j = 1; j < kQ; ++j) {
      double s = 0;
      for (int i = 1; i < kQ; ++i) s += d3q19::weight(i) * normalized_phase(g, i, j);
      CHECK(s == Approx(1.0).epsilon(1e-13));
    }
}

TEST_CASE("Isotropic null vector of Geist2010 sec. 7: Omega v = 0", "[omega]") {
  for (double sa : {0.0, 0.008, 0.109, 0.5})
    for (double ss : {0.3, 0.792, 0.9}) {
      const OmegaMatrix om = build_omega({sa, ss, 0.0});
      double v[kQ];
      v[0] = sa;
      for (int m = 1; m < kQ; ++m) v[m] = d3q19::weight(m);
      for (int i = 0; i < kQ; ++i) {
        double r = 0;
        for (int j = 0; j < kQ; ++j) r += om[i * kQ + j] * v[j];
        CHECK(std::fabs(r) < 1e-15);
      }
    }
}

TEST_CASE("Null vector fails for a non-null vector (the test can fail)", "[omega]") {
  const OmegaMatrix om = build_omega({0.1, 0.8, 0.0});
  double r = 0;
  for (int j = 0; j < kQ; ++j) r += om[1 * kQ + j] * (j == 1 ? 1.0 : 0.0);
  CHECK(std::fabs(r) > 0.1);
}

TEST_CASE("|g| = 1 is the limit of eq. (9), never 0/0", "[omega]") {
  for (double sign : {1.0, -1.0}) {
    const OmegaMatrix exact = build_omega({0.05, 0.9, sign});
    const OmegaMatrix near = build_omega({0.05, 0.9, sign * (1.0 - 1e-9)});
    for (std::size_t e = 0; e < exact.size(); ++e) {
      REQUIRE(std::isfinite(exact[e]));
      CHECK(exact[e] == Approx(near[e]).margin(1e-6));
    }
  }
  // g = 1, sigma_a = 0: Omega is zero on moving directions, so collision is the identity.
  const OmegaMatrix pass = build_omega({0.0, 0.7, 1.0});
  for (int i = 1; i < kQ; ++i)
    for (int j = 1; j < kQ; ++j) CHECK(pass[i * kQ + j] == 0.0);
}

TEST_CASE("Reduced even/odd operator equals the dense product", "[omega]") {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 2.0);
  for (double g : {-1.0, -0.75, 0.0, 0.103, 0.9, 1.0}) {
    const OmegaMatrix om = build_omega({0.109, 0.891, g});
    const CollisionOp<double> op = reduce_omega(om);
    for (int trial = 0; trial < 20; ++trial) {
      double f[kQ], f_copy[kQ];
      for (int m = 0; m < kQ; ++m) f[m] = f_copy[m] = u(rng);
      const double rho = 0.7;
      double post[kQ];
      collide_node(op, 1.0, rho, f, [&](int m, double v) { post[m] = v; });
      for (int m = 0; m < kQ; ++m) {
        double s = 0;
        for (int n = 0; n < kQ; ++n) s += om[m * kQ + n] * f_copy[n];
        CHECK(post[m] == Approx(f_copy[m] + rho * s).margin(1e-13));
      }
    }
  }
}

TEST_CASE("Symmetry-adapted operator equals the dense product, and only isotropic operators take it", "[omega]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 2.0);
  LbModel calibrated;
  calibrated.calibrated = true;
  std::vector<OmegaMatrix> isotropic;
  for (double g : {-1.0, -0.4, 0.0, 0.3, 0.9, 1.0}) isotropic.push_back(build_omega({0.109, 0.891, g}));
  for (const OpticalParams p : {OpticalParams{0.008, 0.792, 0.9}, OpticalParams{0.3, 0.3, 0.0},
                                OpticalParams{0.01, 0.09, 0.5}, OpticalParams{2.0, 6.0, 0.4}})
    isotropic.push_back(build_model_omega(p, calibrated));
  for (const OmegaMatrix& om : isotropic) {
    const CollisionOp<double> op = reduce_omega(om, true);
    REQUIRE(op.is_cubic == 1);
    for (int trial = 0; trial < 20; ++trial) {
      double f[kQ];
      for (int m = 0; m < kQ; ++m) f[m] = u(rng);
      const double rho = 0.7, keep = trial % 2;
      double cubic[kQ], pairs[kQ];
      collide_cubic(op, keep, rho, f, [&](int m, double v) { cubic[m] = v; });
      collide_pairs(op, keep, rho, f, [&](int m, double v) { pairs[m] = v; });
      for (int m = 0; m < kQ; ++m) {
        double s = 0;
        for (int n = 0; n < kQ; ++n) s += om[m * kQ + n] * (n == 0 ? f[0] * keep : f[n]);
        const double dense = (m == 0 ? f[0] * keep : f[m]) + rho * s;
        CHECK(cubic[m] == Approx(dense).margin(1e-13));
        CHECK(pairs[m] == Approx(dense).margin(1e-13));
      }
    }
  }
  // The ground reflects up what comes down: centrally symmetric, not cubic.
  std::array<double, kQ> share{};
  for (int m = 1; m < kQ; ++m) share[m] = d3q19::cz(m) > 0 ? 0.2 : 0.0;
  CHECK(reduce_omega(ground_omega(0.3, share)).is_cubic == 0);
  // One entry pair (and its mirror, keeping central symmetry) changed: x no longer like y.
  OmegaMatrix skewed = build_omega({0.1, 0.8, 0.3});
  skewed[1 * kQ + 3] += 1e-6;
  skewed[2 * kQ + 4] += 1e-6;
  const CollisionOp<double> op = reduce_omega(skewed);
  CHECK(op.is_cubic == 0);
  double f[kQ], post[kQ];
  for (int m = 0; m < kQ; ++m) f[m] = u(rng);
  collide_node(op, 1.0, 1.0, f, [&](int m, double v) { post[m] = v; });  // falls back to even/odd
  double s = 0;
  for (int n = 0; n < kQ; ++n) s += skewed[1 * kQ + n] * f[n];
  CHECK(post[1] == Approx(f[1] + s).margin(1e-13));
}

TEST_CASE("Reduction rejects a matrix without central symmetry", "[omega]") {
  OmegaMatrix om = build_omega({0.1, 0.8, 0.3});
  om[1 * kQ + 3] += 0.01;
  CHECK_THROWS_AS(reduce_omega(om), std::invalid_argument);
}

TEST_CASE("Diffusion coefficient of Geist2010 eq. (4)", "[omega]") {
  CHECK(diffusion_coefficient({0.008, 0.792, 0}) == Approx((2.0 / 0.8 - 1.0) / (4.0 * 1.008)));
  CHECK(diffusion_coefficient({0.5, 1.5, 0}) == Approx(0.0));
  CHECK(diffusion_coefficient({0.5, 1.6, 0}) < 0.0);
}

// Entries of Omega worked out from [Geist2010] eqs. (8)-(9) by hand, grouping the 18 directions by their
// cosine to the incoming one (the property tests above hold for any normalised phase; this pins
// the Henyey-Greenstein shape, its exponent 3/2 and the 2:1 axial:diagonal weighting). Incoming
// j = 1, (+1, 0, 0): axial directions at cos 1, -1 and 0 (x4); diagonal ones at cos 1/sqrt2 (x4),
// -1/sqrt2 (x4) and 0 (x4).
TEST_CASE("Omega entries equal eqs. (8)-(9) worked out by hand at g = 0.5", "[omega]") {
  const double g = 0.5, sigma_a = 0.1, sigma_s = 0.8;
  const auto p = [g](double c) { return (1 - g * g) / std::pow(1 - 2 * g * c + g * g, 1.5); };
  const double r = 1 / std::sqrt(2.0);
  const double norm = (2 * (p(1) + p(-1) + 4 * p(0)) + (4 * p(r) + 4 * p(-r) + 4 * p(0))) / 24;  // eq. (8)
  const OmegaMatrix om = build_omega({sigma_a, sigma_s, g});
  const auto dir = test::lattice_direction;
  const int j = dir(1, 0, 0);
  const auto entry = [&](int i) { return om[static_cast<std::size_t>(i * kQ + j)]; };
  const double sigma_t = sigma_a + sigma_s;
  CHECK(entry(j) == Approx(-sigma_t + sigma_s * (2.0 / 24) * p(1) / norm).epsilon(1e-12));
  CHECK(entry(dir(-1, 0, 0)) == Approx(sigma_s * (2.0 / 24) * p(-1) / norm).epsilon(1e-12));
  CHECK(entry(dir(0, 0, 1)) == Approx(sigma_s * (2.0 / 24) * p(0) / norm).epsilon(1e-12));
  CHECK(entry(dir(1, 1, 0)) == Approx(sigma_s * (1.0 / 24) * p(r) / norm).epsilon(1e-12));
  CHECK(entry(dir(-1, 0, 1)) == Approx(sigma_s * (1.0 / 24) * p(-r) / norm).epsilon(1e-12));
  CHECK(entry(dir(0, 1, -1)) == Approx(sigma_s * (1.0 / 24) * p(0) / norm).epsilon(1e-12));
  // forward scattering dominates at g = 0.5: p(1) / p(-1) = (1.5 / 0.5)^3 = 27
  CHECK(p(1) / p(-1) == Approx(27.0));
}
