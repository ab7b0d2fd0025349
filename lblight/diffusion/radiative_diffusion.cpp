#include "lblight/diffusion/radiative_diffusion.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "lblight/diffusion/multigrid.h"

namespace lblight {

double levermore_pomraning(double r) {
  if (r < 1e-3) return 1.0 / 3.0 - r * r / 45.0;
  return (1.0 / std::tanh(r) - 1.0 / r) / r;
}

namespace {

constexpr double kEpsilon = 1e-20;  // Algorithm 1's epsilon

// The fields Algorithm 1 and the Picard solver share, on the whole grid (outer layer phi = 0).
class Fields {
 public:
  Fields(const RadiativeMedium& m, const RadiativeDiffusionOptions& o) : m_(m), o_(o), d_(m.dims) {
    const std::size_t n = d_.count();
    if (m.sigma_t.size() != n || m.albedo.size() != n || m.emission.size() != n)
      throw std::invalid_argument("solve_radiative_diffusion: one sigma_t, albedo and emission per node");
    if (d_.nx < 3 || d_.ny < 3 || d_.nz < 3) throw std::invalid_argument("solve_radiative_diffusion: grid below 3^3");
    const double floor = o.sigma_floor_per_extent / (m.voxel * d_.longest());
    // A diffusion length beyond the grid's extent changes nothing in it (phi is flat on that
    // scale either way) but makes the coefficients of near-empty voxels 1e4 times those of the
    // medium, which the multigrid solves badly (a void-heavy cloud: 35 s instead of 2 s).
    max_d_ = m.voxel * d_.longest();
    sigma_.resize(n);
    for (std::size_t i = 0; i < n; ++i) sigma_[i] = std::max(m.sigma_t[i], floor);
    double j2 = 0;
    std::size_t count = 0;
    for_interior([&](int, int, int, std::size_t i) {
      j2 += m.emission[i] * m.emission[i];
      ++count;
    });
    j_rms_ = std::sqrt(j2 / static_cast<double>(count));
    if (!m.boundary.empty() && m.boundary.size() != n)
      throw std::invalid_argument("solve_radiative_diffusion: boundary fluence for every node, or none");
    phi = m.boundary.empty() ? std::vector<double>(n, 0.0) : m.boundary;
    D.assign(n, 0.0);
  }

  template <typename F>
  void for_interior(F&& f) const {
    for (int z = 1; z < d_.nz - 1; ++z)
      for (int y = 1; y < d_.ny - 1; ++y)
        for (int x = 1; x < d_.nx - 1; ++x) f(x, y, z, d_.index(x, y, z));
  }

  // D_p = F(R_p) / sigma_p with R from the central-difference gradient (eqs. 33-35).
  double coefficient(int x, int y, int z, std::size_t i) const {
    if (o_.limiter == FluxLimiter::Classical) return std::min(1.0 / (3.0 * sigma_[i]), max_d_);
    const double h = 2.0 * m_.voxel;
    const double gx = (phi[d_.index(x + 1, y, z)] - phi[d_.index(x - 1, y, z)]) / h;
    const double gy = (phi[d_.index(x, y + 1, z)] - phi[d_.index(x, y - 1, z)]) / h;
    const double gz = (phi[d_.index(x, y, z + 1)] - phi[d_.index(x, y, z - 1)]) / h;
    const double floor = kEpsilon * j_rms_;
    const double knudsen = std::max(std::sqrt(gx * gx + gy * gy + gz * gz), floor) / std::max(sigma_[i] * phi[i], floor);
    return std::min(levermore_pomraning(knudsen) / sigma_[i], max_d_);
  }

  // Numerator and denominator of eq. (32) at interior node i; the outer layer keeps its phi and
  // takes the node's own D on the face.
  void update_terms(int x, int y, int z, std::size_t i, double& num, double& den) const {
    const double dl2 = m_.voxel * m_.voxel;
    num = m_.emission[i] * dl2;
    den = (1.0 - m_.albedo[i]) * sigma_[i] * dl2;
    const std::size_t nb[6] = {d_.index(x - 1, y, z), d_.index(x + 1, y, z), d_.index(x, y - 1, z),
                               d_.index(x, y + 1, z), d_.index(x, y, z - 1), d_.index(x, y, z + 1)};
    const bool outer[6] = {x == 1, x == d_.nx - 2, y == 1, y == d_.ny - 2, z == 1, z == d_.nz - 2};
    for (int k = 0; k < 6; ++k) {
      const double dps = outer[k] ? wall(D[i]) : 0.5 * (D[i] + D[nb[k]]);
      num += dps * phi[nb[k]];
      den += dps;
    }
  }

  // RMS of eq. (31)'s residual (eq. 37) over the interior, D recomputed from phi, over RMS j.
  double residual() {
    for_interior([&](int x, int y, int z, std::size_t i) { D[i] = coefficient(x, y, z, i); });
    double r2 = 0;
    std::size_t count = 0;
    for_interior([&](int x, int y, int z, std::size_t i) {
      double num, den;
      update_terms(x, y, z, i, num, den);
      const double r = (num - phi[i] * den) / (m_.voxel * m_.voxel);
      r2 += r * r;
      ++count;
    });
    return j_rms_ > 0 ? std::sqrt(r2 / static_cast<double>(count)) / j_rms_ : 0.0;
  }

  // Conductance towards the outer layer of a node with coefficient D: D over the node spacing
  // (phi held on the layer), or half a voxel of diffusion in series with Marshak's surface
  // resistance 2 (J = phi_s / 2): D / (0.5 + 2 D).
  double wall(double D_node) const { return m_.marshak ? D_node / (0.5 * m_.voxel + 2.0 * D_node) * m_.voxel : D_node; }

  const Dims& dims() const { return d_; }
  double j_rms() const { return j_rms_; }
  double sigma(std::size_t i) const { return sigma_[i]; }

  std::vector<double> phi, D;

 private:
  const RadiativeMedium& m_;
  const RadiativeDiffusionOptions& o_;
  Dims d_;
  std::vector<double> sigma_;
  double j_rms_ = 0, max_d_ = 0;
};

// [Koerner2014] Algorithm 1: red-black Gauss-Seidel with over-relaxation, D updated at each
// node from the current phi before its phi is.
void gauss_seidel(Fields& f, const RadiativeMedium& m, const RadiativeDiffusionOptions& o, RadiativeDiffusionResult& out) {
  const Dims& d = f.dims();
  f.for_interior([&](int, int, int, std::size_t i) {
    f.phi[i] = kEpsilon * f.j_rms() * m.voxel;
    f.D[i] = kEpsilon * m.voxel;
  });
  const double w = o.over_relaxation;
  for (out.iterations = 1; out.iterations <= o.max_iterations; ++out.iterations) {
    for (int colour = 0; colour < 2; ++colour) {
#pragma omp parallel for schedule(static)
      for (int z = 1; z < d.nz - 1; ++z)
        for (int y = 1; y < d.ny - 1; ++y)
          for (int x = 1 + ((y + z + colour + 1) & 1); x < d.nx - 1; x += 2) {
            const std::size_t i = d.index(x, y, z);
            f.D[i] = f.coefficient(x, y, z, i);
            double num, den;
            f.update_terms(x, y, z, i, num, den);
            f.phi[i] = w * (num / den) + (1.0 - w) * f.phi[i];
          }
    }
    if (out.iterations % 10 == 0 || out.iterations == o.max_iterations) {
      out.residual = f.residual();
      if (out.residual < o.tolerance) {
        out.converged = true;
        break;
      }
    }
  }
  out.iterations = std::min(out.iterations, o.max_iterations);
}

// Picard iterations: D from the current phi, then the linear equations of eq. (31) for the
// correction solved by multigrid-preconditioned CG to a tenth of the current residual.
void picard_multigrid(Fields& f, const RadiativeMedium& m, const RadiativeDiffusionOptions& o,
                      RadiativeDiffusionResult& out) {
  const Dims& d = f.dims();
  const Dims in{d.nx - 2, d.ny - 2, d.nz - 2};
  const double dl2 = m.voxel * m.voxel;
  std::vector<double> a(in.count()), D(in.count()), rhs(in.count()), x(in.count()), ax, delta;
  auto interior = [&](int xx, int y, int z) { return in.index(xx - 1, y - 1, z - 1); };
  out.residual = f.residual();  // phi = 0: 1, and D at R = 0 (CDA's 1/3 for either limiter)
  for (out.iterations = 0; out.iterations < o.max_iterations && out.residual >= o.tolerance; ++out.iterations) {
    f.for_interior([&](int xx, int y, int z, std::size_t i) {
      const std::size_t k = interior(xx, y, z);
      a[k] = (1.0 - m.albedo[i]) * f.sigma(i) * dl2;
      D[k] = f.D[i];  // residual() left D(phi) there
      rhs[k] = m.emission[i] * dl2;
      x[k] = f.phi[i];
    });
    DiffusionProblem problem = diffusion_problem(in, a, D, FaceMean::Arithmetic);
    if (m.marshak)
      for (std::size_t k = 0; k < D.size(); ++k) problem.boundary[k] *= f.wall(D[k]) / D[k];
    MultigridSolver mg(problem);
    mg.apply(x, ax);
    for (std::size_t k = 0; k < rhs.size(); ++k) rhs[k] -= ax[k];
    // the outer layer's fluence enters through the faces towards it (conductance D of the node)
    f.for_interior([&](int xx, int y, int z, std::size_t i) {
      const int walls[6][3] = {{xx - 1, y, z}, {xx + 1, y, z}, {xx, y - 1, z}, {xx, y + 1, z}, {xx, y, z - 1}, {xx, y, z + 1}};
      for (const auto& w : walls)
        if (d.is_boundary(w[0], w[1], w[2])) rhs[interior(xx, y, z)] += f.wall(f.D[i]) * f.phi[d.index(w[0], w[1], w[2])];
    });
    const DiffusionSolveStats st = mg.solve(rhs, delta, std::min(0.1, 0.1 * out.residual), 200);
    out.linear_iterations += st.iterations;
    f.for_interior([&](int xx, int y, int z, std::size_t i) { f.phi[i] += delta[interior(xx, y, z)]; });
    out.residual = f.residual();
  }
  out.converged = out.residual < o.tolerance;
}

}  // namespace

RadiativeDiffusionResult solve_radiative_diffusion(const RadiativeMedium& medium, const RadiativeDiffusionOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  Fields f(medium, options);
  RadiativeDiffusionResult out;
  if (options.solver == DiffusionSolver::GaussSeidel) gauss_seidel(f, medium, options, out);
  else picard_multigrid(f, medium, options, out);
  out.phi = std::move(f.phi);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace lblight
