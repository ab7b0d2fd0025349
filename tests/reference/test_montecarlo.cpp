// The Monte Carlo reference against what physics says without it: an empty lattice, a pure
// absorber (Beer-Lambert per layer), energy balance, and a semi-infinite slab's reflection
// (Chandrasekhar's H function). docs/truth.md.
#include <catch2/catch.hpp>

#include <cmath>
#include <numeric>

#include "lblight/reference/diffusion_solution.h"
#include "lblight/reference/montecarlo.h"

using namespace lblight;

namespace {

// A lattice of nx x ny x nz nodes whose interior holds `rho` (boundary layer empty).
LatticeGeometry filled_lattice(int nx, int ny, int nz, float rho) {
  LatticeGeometry g;
  g.dims = {nx, ny, nz};
  g.density.assign(g.dims.count(), 0.0f);
  g.material.assign(g.dims.count(), 0);
  for (int z = 1; z + 1 < nz; ++z)
    for (int y = 1; y + 1 < ny; ++y)
      for (int x = 1; x + 1 < nx; ++x) g.density[g.dims.index(x, y, z)] = rho;
  return g;
}

ChannelOptics optics(double sa, double ss, double g) {
  ChannelOptics o{};
  o[0] = {sa, ss, g};
  o[1] = {sa, ss, -1.0};
  return o;
}

MonteCarloOptions fixed_photons(std::uint64_t per_batch, int batches) {
  MonteCarloOptions o;
  o.target_error = 0;
  o.photons_per_batch = per_batch;
  o.min_batches = batches;
  o.max_photons = per_batch * static_cast<std::uint64_t>(batches);
  return o;
}

// Gauss-Legendre nodes and weights on [0, 1].
void gauss_legendre01(int n, std::vector<double>& x, std::vector<double>& w) {
  x.resize(n);
  w.resize(n);
  for (int i = 0; i < n; ++i) {
    double t = std::cos(M_PI * (i + 0.75) / (n + 0.5)), dp = 0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = t;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2 * k - 1) * t * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (t * p1 - p0) / (t * t - 1);
      const double dt = p1 / dp;
      t -= dt;
      if (std::abs(dt) < 1e-15) break;
    }
    x[i] = 0.5 * (1 - t);
    w[i] = 1.0 / ((1 - t * t) * dp * dp);  // (2 / ((1 - t^2) P'^2)) / 2 for [0, 1]
  }
}

// Chandrasekhar's H function of isotropic scattering with single-scattering albedo `omega`, at
// mu (Radiative Transfer, ch. V, eq. (3) with characteristic function omega / 2), by iterating
// H(mu) = 1 / (1 - (omega / 2) mu int_0^1 H(mu') / (mu + mu') dmu') on 48 Gauss points (slow but
// sure at omega = 1).
double chandrasekhar_h(double omega, double mu) {
  std::vector<double> x, w;
  gauss_legendre01(48, x, w);
  std::vector<double> h(x.size(), 1.0), next(x.size());
  auto at = [&](double m) {
    double s = 0;
    for (std::size_t k = 0; k < x.size(); ++k) s += w[k] * h[k] / (m + x[k]);
    return 1.0 / (1.0 - 0.5 * omega * m * s);
  };
  for (int it = 0; it < 20000; ++it) {
    for (std::size_t k = 0; k < x.size(); ++k) next[k] = at(x[k]);
    h.swap(next);
  }
  return at(mu);
}

double interior_mean(const LatticeGeometry& g, const std::vector<double>& v) {
  double s = 0;
  std::size_t n = 0;
  for (int z = 1; z + 1 < g.dims.nz; ++z)
    for (int y = 1; y + 1 < g.dims.ny; ++y)
      for (int x = 1; x + 1 < g.dims.nx; ++x) s += v[g.dims.index(x, y, z)], ++n;
  return s / static_cast<double>(n);
}

}  // namespace

TEST_CASE("Monte Carlo: an empty lattice holds the incident fluence (1 for a beam, 18 for B00) at every node") {
  const LatticeGeometry g = filled_lattice(9, 8, 7, 0.0f);
  const ChannelOptics o = optics(0.1, 0.5, 0.0);
  for (int j : {6, 1, 7, 0}) {
    CAPTURE(j);
    const double expected = j == 0 ? 18.0 : 1.0;
    const FluenceEstimate e = trace_fluence(g, o, base_solution_light(j), fixed_photons(2048, 16), 7);
    REQUIRE(e.power.lost == 0.0);
    // Along an axis every photon crosses the whole box: its track adds up to the volume exactly.
    if (j == 6 || j == 1) REQUIRE(interior_mean(g, e.mean) == Approx(expected).epsilon(1e-8));
    for (int z = 1; z + 1 < g.dims.nz; ++z)
      for (int y = 1; y + 1 < g.dims.ny; ++y)
        for (int x = 1; x + 1 < g.dims.nx; ++x) {
          const std::size_t i = g.dims.index(x, y, z);
          REQUIRE(e.std_error[i] > 0);
          REQUIRE(std::abs(e.mean[i] - expected) < 5 * e.std_error[i]);
        }
    // Nothing is absorbed; what came in leaves.
    const double out = std::accumulate(e.power.escaped.begin(), e.power.escaped.end(), 0.0);
    REQUIRE(out == Approx(e.power.incident).epsilon(1e-8));
    REQUIRE(e.mean[0] == expected);  // boundary nodes: the incident value
  }
}

TEST_CASE("Monte Carlo over a Lambertian ground: an empty box holds the light from above + 2 A E, and power balance closes",
          "[ground]") {
  // A ground layer at z = 1 (docs/truth.md sec. 8): the open ground around the box and the ground
  // inside it send up radiance A E / pi, whose fluence is 2 A E (E: the irradiance from above);
  // the ground hides a beam going up and the lower half of isotropic light.
  LatticeGeometry g = filled_lattice(9, 8, 8, 0.0f);
  for (int y = 1; y < 7; ++y)
    for (int x = 1; x < 8; ++x) {
      g.density[g.dims.index(x, y, 1)] = 1.0f;
      g.material[g.dims.index(x, y, 1)] = kMaterialGround;
    }
  g.material_count = 3;
  const double albedo = 0.4;
  MonteCarloOptions o = fixed_photons(4096, 16);
  o.ground_albedo = albedo;
  for (int j : {6, 12, 1, 0, 5, 11}) {
    CAPTURE(j);
    const Illumination light = base_solution_light(j);
    double expected;
    if (j == 0) {
      expected = 9.0 + 2.0 * albedo * 18.0 / 4.0;  // half of 18, and E = 18 / 4
    } else {
      const double dz = light[0].direction[2];
      expected = dz > 0 ? 0.0 : 1.0 + 2.0 * albedo * -dz;
    }
    const FluenceEstimate e = trace_fluence(g, optics(0.1, 0.5, 0.0), light, o, 9);
    REQUIRE(e.power.lost == 0.0);
    double worst = 0;
    for (int z = 2; z + 1 < g.dims.nz; ++z)
      for (int y = 1; y + 1 < g.dims.ny; ++y)
        for (int x = 1; x + 1 < g.dims.nx; ++x) {
          const std::size_t i = g.dims.index(x, y, z);
          worst = std::max(worst, expected == 0.0 ? e.mean[i] : std::abs(e.mean[i] - expected) / e.std_error[i]);
        }
    CHECK(worst < 5.0);
    // what came in left through the faces or stayed in the ground (tallied on the -z face)
    // (roulette keeps it in expectation only)
    double out = 0, out_var = 0;
    for (int f = 0; f < 6; ++f) out += e.power.escaped[f], out_var += e.power.escaped_se[f] * e.power.escaped_se[f];
    CHECK(std::abs(out - e.power.incident) <= 5 * std::sqrt(out_var) + 1e-9 * e.power.incident);
    CHECK(e.mean[0] == Approx(expected));  // boundary nodes: the open-air value
  }
}

TEST_CASE("Monte Carlo: a pure absorber follows Beer-Lambert layer by layer within its standard error") {
  const double sa = 0.3;
  const LatticeGeometry g = filled_lattice(6, 6, 12, 1.0f);
  const FluenceEstimate e = trace_fluence(g, optics(sa, 0.0, 0.0), base_solution_light(6), fixed_photons(4096, 16), 3);
  const int top = g.dims.nz - 2;
  for (int z = 1; z <= top; ++z) {
    // Voxel average of exp(-sa depth) over a voxel whose top lies `k` voxels below the surface.
    const int k = top - z;
    const double expected = std::exp(-sa * k) * (1 - std::exp(-sa)) / sa;
    for (int y = 1; y <= 4; ++y)
      for (int x = 1; x <= 4; ++x) {
        const std::size_t i = g.dims.index(x, y, z);
        CAPTURE(z, x, y, e.mean[i], e.std_error[i], expected);
        REQUIRE(std::abs(e.mean[i] - expected) < 5 * e.std_error[i] + 1e-9);
      }
  }
  // Transmitted through the bottom: exp(-optical depth) of the incident power.
  const double transmitted = e.power.escaped[4] / e.power.incident;
  REQUIRE(std::abs(transmitted - std::exp(-sa * top)) < 5 * e.power.escaped_se[4] / e.power.incident);
  REQUIRE(e.power.escaped[5] == 0.0);  // nothing scatters back
}

TEST_CASE("Monte Carlo: incident power = escaped + absorbed, for absorbing and lossless media") {
  const LatticeGeometry g = filled_lattice(10, 9, 8, 0.7f);
  for (double sa : {0.0, 0.15}) {
    CAPTURE(sa);
    const FluenceEstimate e =
        trace_fluence(g, optics(sa, 0.6, 0.6), base_solution_light(11), fixed_photons(2048, 16), 5);
    double out = 0, out_var = 0;
    for (int f = 0; f < 6; ++f) out += e.power.escaped[f], out_var += e.power.escaped_se[f] * e.power.escaped_se[f];
    const double gap = e.power.incident - out - e.power.absorbed;
    if (sa == 0.0) {
      REQUIRE(e.power.absorbed == 0.0);
      REQUIRE(out == Approx(e.power.incident).epsilon(1e-8));  // weights never change
    } else {
      REQUIRE(e.power.absorbed > 0.1 * e.power.incident);
      // Escape and absorption are anticorrelated, so the gap's spread is below the sum of both.
      REQUIRE(std::abs(gap) < 5 * (std::sqrt(out_var) + e.power.absorbed_se));
    }
  }
}

TEST_CASE("Monte Carlo: a semi-infinite isotropic slab reflects 1 - H(1) sqrt(1 - omega) (Chandrasekhar)") {
  // The H function itself against Chandrasekhar's table (Radiative Transfer, Table XI): H(1) = 2.9078
  // for conservative scattering.
  REQUIRE(chandrasekhar_h(1.0, 1.0) == Approx(2.9078).margin(2e-3));
  for (double omega : {0.9, 0.5}) {
    CAPTURE(omega);
    LatticeGeometry g = filled_lattice(5, 5, 42, 1.0f);  // 40 mean free paths deep: no transmission
    MonteCarloOptions o = fixed_photons(8192, 16);
    o.periodic_xy = true;
    const FluenceEstimate e = trace_fluence(g, optics(1.0 - omega, omega, 0.0), base_solution_light(6), o, 11);
    const double reflected = e.power.escaped[5] / e.power.incident;
    const double se = e.power.escaped_se[5] / e.power.incident;
    const double expected = 1.0 - chandrasekhar_h(omega, 1.0) * std::sqrt(1.0 - omega);
    CAPTURE(reflected, se, expected);
    REQUIRE(e.power.escaped[4] < 1e-6 * e.power.incident);
    REQUIRE(se < 0.02 * expected);
    REQUIRE(std::abs(reflected - expected) < 4 * se + 1e-4);
  }
}

TEST_CASE("Monte Carlo: results are identical for any thread count and depend on the seed") {
  const LatticeGeometry g = filled_lattice(8, 8, 8, 0.5f);
  const ChannelOptics o = optics(0.05, 0.5, 0.8);
  const MonteCarloOptions mc = fixed_photons(1024, 4);
  RunContext one, two;
  one.threads = 1;
  two.threads = 2;
  const FluenceEstimate a = trace_fluence(g, o, base_solution_light(0), mc, 1, one);
  const FluenceEstimate b = trace_fluence(g, o, base_solution_light(0), mc, 1, two);
  REQUIRE(a.mean == b.mean);
  REQUIRE(a.std_error == b.std_error);
  const FluenceEstimate c = trace_fluence(g, o, base_solution_light(0), mc, 2, two);
  REQUIRE(a.mean != c.mean);
}

TEST_CASE("Monte Carlo: it stops at the target error, and its error shrinks as 1 / sqrt(photons)") {
  const LatticeGeometry g = filled_lattice(8, 8, 8, 1.0f);
  const ChannelOptics o = optics(0.1, 0.4, 0.0);
  MonteCarloOptions mc;
  mc.target_error = 0.01;
  mc.photons_per_batch = 512;
  std::vector<std::pair<double, double>> seen;  // photons, error
  const FluenceEstimate e = trace_fluence(g, o, base_solution_light(6), mc, 1, {}, [&](const FluenceEstimate& r) {
    seen.emplace_back(static_cast<double>(r.photons), r.relative_error);
  });
  REQUIRE(e.relative_error <= 0.01);
  REQUIRE(e.batches >= mc.min_batches);
  REQUIRE(static_cast<int>(seen.size()) == e.batches);
  // The previous batch was still above the target (it did not run on for nothing).
  REQUIRE(seen[seen.size() - 2].second > 0.01);
  // Four times the photons halve the error (within the noise of the error itself).
  const std::size_t q = seen.size() / 4;
  REQUIRE(seen.back().second / seen[q - 1].second == Approx(std::sqrt(seen[q - 1].first / seen.back().first)).epsilon(0.25));
}

TEST_CASE("Ray-marched uncollided light: the incident fluence on an empty lattice, exp(-tau) through an absorber",
          "[truth]") {
  const Dims d{9, 9, 12};
  LatticeGeometry empty = filled_lattice(d.nx, d.ny, d.nz, 0.0f);
  const ChannelOptics optics{OpticalParams{0.3, 0.0, 0.0}, OpticalParams{0.3, 0.0, 0.0}};
  for (int index : {0, 6, 9}) {
    const std::vector<double> phi = uncollided_fluence(empty, optics, base_solution_light(index));
    const double want = index == 0 ? 18.0 : 1.0;
    for (double v : phi) CHECK(v == Approx(want).epsilon(1e-12));
  }
  // density 1 inside: a beam down -z (B06) reaches the centre of node z through the nz - 2 - z
  // voxels above it and half of its own
  const LatticeGeometry full = filled_lattice(d.nx, d.ny, d.nz, 1.0f);
  const std::vector<double> phi = uncollided_fluence(full, optics, base_solution_light(6));
  for (int z = 1; z < d.nz - 1; ++z) {
    const double tau = 0.3 * ((d.nz - 2 - z) + 0.5);
    CHECK(phi[d.index(4, 4, z)] == Approx(std::exp(-tau)).epsilon(1e-9));
  }
}
