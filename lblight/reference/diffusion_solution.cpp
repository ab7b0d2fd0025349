#include "lblight/reference/diffusion_solution.h"

#include <chrono>
#include <cmath>

#include "lblight/lattice/d3q19.h"
#include "lblight/reference/truth.h"

namespace lblight {

namespace {

// exp(-optical depth) from the centre of node (x, y, z) back against `travel` until the ray leaves
// the lattice, in steps of half a voxel sampled at their midpoints (exact along the axes).
double transmittance(const LatticeGeometry& g, const std::vector<double>& sigma, int x, int y, int z,
                     const std::array<double, 3>& travel) {
  const Dims& d = g.dims;
  constexpr double h = 0.5;
  double tau = 0;
  for (int k = 0;; ++k) {
    const double s = (k + 0.5) * h;
    const long xi = std::lround(x - travel[0] * s), yi = std::lround(y - travel[1] * s), zi = std::lround(z - travel[2] * s);
    if (xi < 0 || yi < 0 || zi < 0 || xi >= d.nx || yi >= d.ny || zi >= d.nz) break;
    tau += h * sigma[d.index(static_cast<int>(xi), static_cast<int>(yi), static_cast<int>(zi))];
  }
  return std::exp(-tau);
}

}  // namespace

std::vector<double> uncollided_fluence(const LatticeGeometry& g, const ChannelOptics& optics, const Illumination& light) {
  const Dims& d = g.dims;
  std::vector<double> sigma(d.count());
  for (std::size_t i = 0; i < sigma.size(); ++i) sigma[i] = g.density[i] * optics[g.material[i]].sigma_t();
  // (direction, weight x fluence) of every beam the illumination is made of
  std::vector<std::pair<std::array<double, 3>, double>> beams;
  for (const LightSource& s : light) {
    if (s.kind == LightSource::Kind::Collimated) {
      beams.push_back({s.direction, s.fluence});
      continue;
    }
    for (int m = 1; m < d3q19::kQ; ++m) {
      const double len = std::sqrt(static_cast<double>(d3q19::length_sq(m)));
      beams.push_back({{d3q19::cx(m) / len, d3q19::cy(m) / len, d3q19::cz(m) / len}, d3q19::weight(m) * s.fluence});
    }
  }
  std::vector<double> phi(d.count(), 0.0);
#pragma omp parallel for schedule(dynamic)
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x) {
        double v = 0;
        for (const auto& b : beams)
          v += b.second * (d.is_boundary(x, y, z) ? 1.0 : transmittance(g, sigma, x, y, z, b.first));
        phi[d.index(x, y, z)] = v;
      }
  return phi;
}

SolutionResult diffuse_solution(const ModelPlan& mp, const Scene& scene, const SolutionPlan& s,
                                const DiffusionRunOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  SolutionResult r;
  r.plan = s;
  r.plan.derived = false;
  r.converged = true;
  const Illumination light = solution_light(scene, s);
  const LatticeGeometry& g = mp.lattice;
  const std::size_t n = g.dims.count();
  std::array<std::vector<float>, 3> fluence;
  for (int ch = 0; ch < static_cast<int>(mp.channels.size()); ++ch) {
    ChannelOptics optics = channel_optics(mp, ch);
    // Delta-M: the forward peak f = g^2 of a forward-peaked phase function is light that goes on
    // as if unscattered (it stays in the uncollided beam); the rest scatters with asymmetry
    // (g - f) / (1 - f). Without it a g = 0.9 cloud's diffuse field was 40% off the reference.
    for (OpticalParams& p : optics)
      if (options.delta_m && p.g > 0.0 && p.g < 1.0) {
        const double f = p.g * p.g;
        p.sigma_s *= 1.0 - f;
        p.g = (p.g - f) / (1.0 - f);
      }
    const std::vector<double> uncollided = uncollided_fluence(g, optics, light);
    RadiativeMedium medium;
    medium.dims = g.dims;
    medium.voxel = 1.0;  // lattice units: extinction per voxel length, as the Monte Carlo reference
    medium.marshak = options.marshak;
    medium.sigma_t.resize(n);
    medium.albedo.resize(n);
    medium.emission.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const OpticalParams& p = optics[g.material[i]];
      const double rho = g.density[i], reduced = p.sigma_s * (1.0 - p.g);
      medium.sigma_t[i] = rho * (p.sigma_a + reduced);
      medium.albedo[i] = p.sigma_a + reduced > 0 ? reduced / (p.sigma_a + reduced) : 0.0;
      medium.emission[i] = rho * p.sigma_s * uncollided[i];  // first scattering feeds the diffuse field
    }
    RadiativeDiffusionOptions o;
    o.limiter = options.limiter;
    o.solver = options.solver;
    o.tolerance = options.tolerance;
    const RadiativeDiffusionResult d = solve_radiative_diffusion(medium, o);
    fluence[ch].resize(n);
    for (std::size_t i = 0; i < n; ++i) fluence[ch][i] = static_cast<float>(uncollided[i] + d.phi[i]);
    r.iterations = std::max(r.iterations, d.iterations);
    r.error_estimate = std::max(r.error_estimate, d.residual);
    r.converged = r.converged && d.converged;
  }
  for (int c = 0; c < 3; ++c) r.totals[c] = fluence[mp.channel_of[c]];
  r.error_estimate_max = r.error_estimate;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace lblight
