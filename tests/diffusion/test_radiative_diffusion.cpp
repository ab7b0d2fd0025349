// CDA and FLD (lblight/diffusion/radiative_diffusion.h) against the point-source solutions of
// [Koerner2014] sec. 4.1: classical diffusion theory (eq. 27) and Grosjean's transport
// approximation (eq. 24), on the paper's set-up (a unit point source in the centre voxel of a
// homogeneous grid that is 4 optical depths wide, phi = 0 outside), with both solvers.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "lblight/diffusion/radiative_diffusion.h"

using namespace lblight;

namespace {

constexpr double kPi = 3.14159265358979323846;

struct PointSource {
  RadiativeMedium medium;
  double sigma_t = 0;
  int centre = 0;
};

PointSource point_source(int n, double albedo) {
  PointSource p;
  p.medium.dims = {n, n, n};
  p.medium.voxel = 1.0;
  p.sigma_t = 4.0 / n;
  p.centre = n / 2;
  const std::size_t count = p.medium.dims.count();
  p.medium.sigma_t.assign(count, p.sigma_t);
  p.medium.albedo.assign(count, albedo);
  p.medium.emission.assign(count, 0.0);
  p.medium.emission[p.medium.dims.index(p.centre, p.centre, p.centre)] = 1.0;  // unit power / dl^3
  return p;
}

// Normalised fluence 4 pi phi / sigma_t^2 (eq. 25) at optical depth tau.
double grosjean(double tau, double albedo) {
  const double lambda = std::sqrt(3.0 * (1.0 - albedo) / (2.0 - albedo));
  return std::exp(-tau) / (tau * tau) + 3.0 * albedo / (2.0 - albedo) * std::exp(-lambda * tau) / tau;
}
double classical(double tau, double albedo) { return 3.0 * std::exp(-std::sqrt(3.0 * (1.0 - albedo)) * tau) / tau; }

// The numerical normalised fluence at node distance k along +x from the source.
double along_x(const PointSource& p, const RadiativeDiffusionResult& r, int k) {
  return 4.0 * kPi * r.phi[p.medium.dims.index(p.centre + k, p.centre, p.centre)] / (p.sigma_t * p.sigma_t);
}

// The outer layer held at a theory's fluence (004 Fig. 5(a)): the discretisation alone is tested.
void hold_boundary(PointSource& p, double (*theory)(double, double), double albedo) {
  const Dims& d = p.medium.dims;
  p.medium.boundary.assign(d.count(), 0.0);
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x)
        if (d.is_boundary(x, y, z)) {
          const double r = std::sqrt(double((x - p.centre) * (x - p.centre) + (y - p.centre) * (y - p.centre) +
                                            (z - p.centre) * (z - p.centre)));
          p.medium.boundary[d.index(x, y, z)] = theory(r * p.sigma_t, albedo) * p.sigma_t * p.sigma_t / (4.0 * kPi);
        }
}

}  // namespace

TEST_CASE("Levermore-Pomraning's limiter: 1/3 at R = 0, 1/R far out, continuous across the series", "[diffusion]") {
  CHECK(levermore_pomraning(0.0) == Approx(1.0 / 3.0));
  CHECK(levermore_pomraning(0.999e-3) == Approx(levermore_pomraning(1.001e-3)).epsilon(1e-6));
  CHECK(levermore_pomraning(200.0) * 200.0 == Approx(1.0).epsilon(0.01));
}

TEST_CASE("CDA matches classical diffusion theory, FLD Grosjean's transport solution, where 004 shows they do", "[diffusion]") {
  // Outer layer held at the theory's fluence (004 Fig. 5(a)): what is left is the equation and
  // its discretisation. Albedo 0.9; the point source is one voxel, so the first voxels are off.
  PointSource cdap = point_source(41, 0.9), fldp = point_source(41, 0.9);
  hold_boundary(cdap, classical, 0.9);
  hold_boundary(fldp, grosjean, 0.9);
  RadiativeDiffusionOptions cda, fld;
  cda.limiter = FluxLimiter::Classical;
  const RadiativeDiffusionResult rc = solve_radiative_diffusion(cdap.medium, cda);
  const RadiativeDiffusionResult rf = solve_radiative_diffusion(fldp.medium, fld);
  REQUIRE(rc.converged);
  REQUIRE(rf.converged);
  for (int k = 5; k < 20; ++k) {
    const double tau = k * cdap.sigma_t, c = along_x(cdap, rc, k), f = along_x(fldp, rf, k);
    CAPTURE(k, tau, c, classical(tau, 0.9), f, grosjean(tau, 0.9));
    CHECK(std::abs(c / classical(tau, 0.9) - 1.0) < 0.05);  // CDA: diffusion theory from tau 0.5
    if (tau > 0.85) CHECK(std::abs(f / grosjean(tau, 0.9) - 1.0) < 0.05);
  }
}

TEST_CASE("FLD follows Grosjean's ballistic 1/tau^2 near the source much closer than CDA", "[diffusion]") {
  // phi = 0 outside, as 004 Fig. 5(b, c)
  for (double albedo : {0.5, 0.9, 0.99}) {
    const PointSource p = point_source(41, albedo);
    RadiativeDiffusionOptions fld, cda;
    cda.limiter = FluxLimiter::Classical;
    const RadiativeDiffusionResult rf = solve_radiative_diffusion(p.medium, fld);
    const RadiativeDiffusionResult rc = solve_radiative_diffusion(p.medium, cda);
    REQUIRE(rf.converged);
    REQUIRE(rc.converged);
    for (int k = 1; k <= 3; ++k) {  // tau < 0.3
      const double tau = k * p.sigma_t;
      const double f = along_x(p, rf, k), c = along_x(p, rc, k), g = grosjean(tau, albedo);
      CAPTURE(albedo, k, tau, f, c, g);
      CHECK(std::abs(f / g - 1.0) < 0.6 * std::abs(c / g - 1.0));
    }
  }
}

TEST_CASE("Algorithm 1 and the multigrid Picard solver reach the same fluence", "[diffusion]") {
  const PointSource p = point_source(21, 0.9);
  for (FluxLimiter limiter : {FluxLimiter::Classical, FluxLimiter::LevermorePomraning}) {
    RadiativeDiffusionOptions gs, mg;
    gs.limiter = mg.limiter = limiter;
    gs.solver = DiffusionSolver::GaussSeidel;
    gs.tolerance = mg.tolerance = 1e-6;  // Algorithm 1's criterion
    gs.max_iterations = 20000;
    const RadiativeDiffusionResult a = solve_radiative_diffusion(p.medium, gs);
    const RadiativeDiffusionResult b = solve_radiative_diffusion(p.medium, mg);
    CAPTURE(a.iterations, b.iterations, b.linear_iterations, a.seconds, b.seconds);
    REQUIRE(a.converged);
    REQUIRE(b.converged);
    double d = 0, n = 0;
    for (std::size_t i = 0; i < a.phi.size(); ++i) {
      d += (a.phi[i] - b.phi[i]) * (a.phi[i] - b.phi[i]);
      n += b.phi[i] * b.phi[i];
    }
    CHECK(std::sqrt(d / n) < 1e-4);
  }
}

// Not run by default: the profiles behind docs/accuracy.md ("Diffusion solvers").
TEST_CASE("Point-source profiles of CDA and FLD against the theories", "[.][profiles]") {
  for (int n : {41, 81})
    for (double albedo : {0.5, 0.9, 0.99}) 
    for (int held : {0, 1}) {
      PointSource p = point_source(n, albedo);
      if (held) hold_boundary(p, grosjean, albedo);
      std::printf("boundary %s\n", held ? "Grosjean" : "0");
      RadiativeDiffusionOptions fld, cda;
      cda.limiter = FluxLimiter::Classical;
      const RadiativeDiffusionResult rf = solve_radiative_diffusion(p.medium, fld);
      const RadiativeDiffusionResult rc = solve_radiative_diffusion(p.medium, cda);
      RadiativeDiffusionOptions gs = fld;
      gs.solver = DiffusionSolver::GaussSeidel;
      const RadiativeDiffusionResult rg = n <= 41 ? solve_radiative_diffusion(p.medium, gs) : RadiativeDiffusionResult{};
      std::printf("n %d albedo %.2f: FLD %d Picard (%d CG) %.2f s, Algorithm 1 %d sweeps %.2f s, CDA %.2f s\n", n, albedo,
                  rf.iterations, rf.linear_iterations, rf.seconds, rg.iterations, rg.seconds, rc.seconds);
      for (int k = 1; k < n / 2; k += std::max(1, n / 20)) {
        const double tau = k * p.sigma_t;
        std::printf("  tau %.3f  FLD %.4g  CDA %.4g  Grosjean %.4g  classical %.4g  FLD/G %.3f  CDA/G %.3f\n", tau,
                    along_x(p, rf, k), along_x(p, rc, k), grosjean(tau, albedo), classical(tau, albedo),
                    along_x(p, rf, k) / grosjean(tau, albedo), along_x(p, rc, k) / grosjean(tau, albedo));
      }
    }
}
