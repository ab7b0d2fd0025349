#include "lblight/diffusion/multigrid.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace lblight {

DiffusionProblem diffusion_problem(const Dims& d, std::vector<double> a, const std::vector<double>& D, FaceMean mean) {
  const std::size_t n = d.count();
  if (a.size() != n || D.size() != n) throw std::invalid_argument("diffusion_problem: one a and D per node");
  DiffusionProblem p;
  p.dims = d;
  p.a = std::move(a);
  p.cx.assign(n, 0.0);
  p.cy.assign(n, 0.0);
  p.cz.assign(n, 0.0);
  p.boundary.assign(n, 0.0);
  auto face = [&](std::size_t i, std::size_t j) {
    const double s = D[i] + D[j];
    if (mean == FaceMean::Arithmetic) return 0.5 * s;
    return s > 0 ? 2.0 * D[i] * D[j] / s : 0.0;
  };
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x) {
        const std::size_t i = d.index(x, y, z);
        if (x + 1 < d.nx) p.cx[i] = face(i, d.index(x + 1, y, z));
        if (y + 1 < d.ny) p.cy[i] = face(i, d.index(x, y + 1, z));
        if (z + 1 < d.nz) p.cz[i] = face(i, d.index(x, y, z + 1));
        const int walls = (x == 0) + (x == d.nx - 1) + (y == 0) + (y == d.ny - 1) + (z == 0) + (z == d.nz - 1);
        p.boundary[i] = walls * D[i];
      }
  return p;
}

struct MultigridSolver::Level {
  Dims d;
  std::vector<double> a, cx, cy, cz, boundary, diag;
  std::vector<double> x, b, r;  // work: solution, right-hand side, residual
  std::vector<double> dense;    // coarsest level: Cholesky factor (row-major lower triangle)

  explicit Level(const DiffusionProblem& p)
      : d(p.dims), a(p.a), cx(p.cx), cy(p.cy), cz(p.cz), boundary(p.boundary) {
    const std::size_t n = d.count();
    diag.resize(n);
    for (int z = 0; z < d.nz; ++z)
      for (int y = 0; y < d.ny; ++y)
        for (int xx = 0; xx < d.nx; ++xx) {
          const std::size_t i = d.index(xx, y, z);
          double s = a[i] + boundary[i] + cx[i] + cy[i] + cz[i];
          if (xx > 0) s += cx[i - 1];
          if (y > 0) s += cy[i - static_cast<std::size_t>(d.nx)];
          if (z > 0) s += cz[i - static_cast<std::size_t>(d.nx) * static_cast<std::size_t>(d.ny)];
          diag[i] = s > 0 ? s : 1e-300;
        }
    x.assign(n, 0.0);
    b.assign(n, 0.0);
    r.assign(n, 0.0);
  }

  std::size_t sx() const { return 1; }
  std::size_t sy() const { return static_cast<std::size_t>(d.nx); }
  std::size_t sz() const { return static_cast<std::size_t>(d.nx) * static_cast<std::size_t>(d.ny); }

  // Sum over the neighbours of c * v(neighbour).
  double neighbours(const std::vector<double>& v, int xx, int y, int z, std::size_t i) const {
    double s = 0;
    if (xx > 0) s += cx[i - 1] * v[i - 1];
    if (xx + 1 < d.nx) s += cx[i] * v[i + 1];
    if (y > 0) s += cy[i - sy()] * v[i - sy()];
    if (y + 1 < d.ny) s += cy[i] * v[i + sy()];
    if (z > 0) s += cz[i - sz()] * v[i - sz()];
    if (z + 1 < d.nz) s += cz[i] * v[i + sz()];
    return s;
  }

  void apply(const std::vector<double>& v, std::vector<double>& out) const {
#pragma omp parallel for schedule(static)
    for (int z = 0; z < d.nz; ++z)
      for (int y = 0; y < d.ny; ++y)
        for (int xx = 0; xx < d.nx; ++xx) {
          const std::size_t i = d.index(xx, y, z);
          out[i] = diag[i] * v[i] - neighbours(v, xx, y, z, i);
        }
  }

  // Red-black Gauss-Seidel on x for A x = b; `reverse` visits black first (the adjoint sweep).
  void smooth(int sweeps, bool reverse) {
    for (int s = 0; s < sweeps; ++s)
      for (int c = 0; c < 2; ++c) {
        const int colour = reverse ? 1 - c : c;
#pragma omp parallel for schedule(static)
        for (int z = 0; z < d.nz; ++z)
          for (int y = 0; y < d.ny; ++y)
            for (int xx = (y + z + colour) & 1; xx < d.nx; xx += 2) {
              const std::size_t i = d.index(xx, y, z);
              x[i] = (b[i] + neighbours(x, xx, y, z, i)) / diag[i];
            }
      }
  }

  void factor_dense() {
    const std::size_t n = d.count();
    dense.assign(n * n, 0.0);
    for (int z = 0; z < d.nz; ++z)
      for (int y = 0; y < d.ny; ++y)
        for (int xx = 0; xx < d.nx; ++xx) {
          const std::size_t i = d.index(xx, y, z);
          dense[i * n + i] = diag[i];
          if (xx + 1 < d.nx) dense[(i + 1) * n + i] = dense[i * n + i + 1] = -cx[i];
          if (y + 1 < d.ny) dense[(i + sy()) * n + i] = dense[i * n + i + sy()] = -cy[i];
          if (z + 1 < d.nz) dense[(i + sz()) * n + i] = dense[i * n + i + sz()] = -cz[i];
        }
    for (std::size_t j = 0; j < n; ++j) {  // Cholesky, lower triangle in place
      double s = dense[j * n + j];
      for (std::size_t k = 0; k < j; ++k) s -= dense[j * n + k] * dense[j * n + k];
      dense[j * n + j] = std::sqrt(std::max(s, 1e-300));
      for (std::size_t i = j + 1; i < n; ++i) {
        double t = dense[i * n + j];
        for (std::size_t k = 0; k < j; ++k) t -= dense[i * n + k] * dense[j * n + k];
        dense[i * n + j] = t / dense[j * n + j];
      }
    }
  }

  void solve_dense() {
    const std::size_t n = d.count();
    for (std::size_t i = 0; i < n; ++i) {
      double t = b[i];
      for (std::size_t k = 0; k < i; ++k) t -= dense[i * n + k] * x[k];
      x[i] = t / dense[i * n + i];
    }
    for (std::size_t i = n; i-- > 0;) {
      double t = x[i];
      for (std::size_t k = i + 1; k < n; ++k) t -= dense[k * n + i] * x[k];
      x[i] = t / dense[i * n + i];
    }
  }
};

namespace {

constexpr std::size_t kCoarsestNodes = 512;  // solved directly
constexpr int kSmoothingSweeps = 2;

int half(int n) { return (n + 1) / 2; }

// The next coarser problem: 2x2x2 aggregates, absorption summed, conductances between (and out
// of) aggregates summed and halved (the doubled spacing).
DiffusionProblem coarsen(const DiffusionProblem& f) {
  const Dims& fd = f.dims;
  DiffusionProblem c;
  c.dims = {half(fd.nx), half(fd.ny), half(fd.nz)};
  const std::size_t n = c.dims.count();
  c.a.assign(n, 0.0);
  c.cx.assign(n, 0.0);
  c.cy.assign(n, 0.0);
  c.cz.assign(n, 0.0);
  c.boundary.assign(n, 0.0);
  for (int z = 0; z < fd.nz; ++z)
    for (int y = 0; y < fd.ny; ++y)
      for (int x = 0; x < fd.nx; ++x) {
        const std::size_t i = fd.index(x, y, z);
        const std::size_t p = c.dims.index(x / 2, y / 2, z / 2);
        c.a[p] += f.a[i];
        c.boundary[p] += 0.5 * f.boundary[i];
        // a face leaves the aggregate when the neighbour across it belongs to the next one
        if (x + 1 < fd.nx && (x & 1)) c.cx[p] += 0.5 * f.cx[i];
        if (y + 1 < fd.ny && (y & 1)) c.cy[p] += 0.5 * f.cy[i];
        if (z + 1 < fd.nz && (z & 1)) c.cz[p] += 0.5 * f.cz[i];
      }
  return c;
}

// Sum of a[i] * b[i] per z plane in parallel, the planes added in order: the same result for any
// thread count.
double dot(const Dims& d, const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> planes(static_cast<std::size_t>(d.nz), 0.0);
  const std::size_t plane = static_cast<std::size_t>(d.nx) * static_cast<std::size_t>(d.ny);
#pragma omp parallel for schedule(static)
  for (int z = 0; z < d.nz; ++z) {
    double s = 0;
    const std::size_t o = static_cast<std::size_t>(z) * plane;
    for (std::size_t i = 0; i < plane; ++i) s += a[o + i] * b[o + i];
    planes[static_cast<std::size_t>(z)] = s;
  }
  double s = 0;
  for (double v : planes) s += v;
  return s;
}

}  // namespace

MultigridSolver::MultigridSolver(const DiffusionProblem& problem) {
  const std::size_t n = problem.dims.count();
  if (n == 0) throw std::invalid_argument("MultigridSolver: no interior nodes");
  if (problem.a.size() != n || problem.cx.size() != n || problem.cy.size() != n || problem.cz.size() != n ||
      problem.boundary.size() != n)
    throw std::invalid_argument("MultigridSolver: one coefficient per node");
  levels_.push_back(std::make_unique<Level>(problem));
  DiffusionProblem current = problem;
  while (current.dims.count() > kCoarsestNodes) {
    current = coarsen(current);
    levels_.push_back(std::make_unique<Level>(current));
  }
  levels_.back()->factor_dense();
  r_.resize(n);
  z_.resize(n);
  p_.resize(n);
  q_.resize(n);
}

MultigridSolver::~MultigridSolver() = default;

int MultigridSolver::levels() const { return static_cast<int>(levels_.size()); }

void MultigridSolver::apply(const std::vector<double>& x, std::vector<double>& y) const {
  y.resize(x.size());
  levels_.front()->apply(x, y);
}

void MultigridSolver::v_cycle(const std::vector<double>& r, std::vector<double>& z) {
  Level& top = *levels_.front();
  top.b = r;
  std::fill(top.x.begin(), top.x.end(), 0.0);
  const std::size_t last = levels_.size() - 1;
  for (std::size_t l = 0; l < last; ++l) {  // down: smooth, restrict the residual
    Level& f = *levels_[l];
    Level& c = *levels_[l + 1];
    f.smooth(kSmoothingSweeps, false);
    f.apply(f.x, f.r);
    std::fill(c.b.begin(), c.b.end(), 0.0);
    std::fill(c.x.begin(), c.x.end(), 0.0);
    for (int zz = 0; zz < f.d.nz; ++zz)
      for (int y = 0; y < f.d.ny; ++y)
        for (int x = 0; x < f.d.nx; ++x) {
          const std::size_t i = f.d.index(x, y, zz);
          c.b[c.d.index(x / 2, y / 2, zz / 2)] += f.b[i] - f.r[i];
        }
  }
  levels_[last]->solve_dense();
  for (std::size_t l = last; l-- > 0;) {  // up: prolong (constant per aggregate), smooth back
    Level& f = *levels_[l];
    const Level& c = *levels_[l + 1];
#pragma omp parallel for schedule(static)
    for (int zz = 0; zz < f.d.nz; ++zz)
      for (int y = 0; y < f.d.ny; ++y)
        for (int x = 0; x < f.d.nx; ++x) f.x[f.d.index(x, y, zz)] += c.x[c.d.index(x / 2, y / 2, zz / 2)];
    f.smooth(kSmoothingSweeps, true);
  }
  z = top.x;
}

DiffusionSolveStats MultigridSolver::solve(const std::vector<double>& s, std::vector<double>& phi, double tolerance,
                                           int max_iterations) {
  const Dims& d = levels_.front()->d;
  const std::size_t n = d.count();
  if (s.size() != n) throw std::invalid_argument("MultigridSolver::solve: one source value per node");
  phi.assign(n, 0.0);
  DiffusionSolveStats st;
  const double s_norm = std::sqrt(dot(d, s, s));
  if (!(s_norm > 0)) return st;
  r_ = s;
  v_cycle(r_, z_);
  p_ = z_;
  double rz = dot(d, r_, z_);
  for (st.iterations = 1; st.iterations <= max_iterations; ++st.iterations) {
    levels_.front()->apply(p_, q_);
    const double pq = dot(d, p_, q_);
    if (!(pq > 0)) break;
    const double alpha = rz / pq;
#pragma omp parallel for schedule(static)
    for (std::size_t i = 0; i < n; ++i) {
      phi[i] += alpha * p_[i];
      r_[i] -= alpha * q_[i];
    }
    st.residual = std::sqrt(dot(d, r_, r_)) / s_norm;
    if (st.residual <= tolerance) break;
    v_cycle(r_, z_);
    const double rz_new = dot(d, r_, z_);
    const double beta = rz_new / rz;
    rz = rz_new;
#pragma omp parallel for schedule(static)
    for (std::size_t i = 0; i < n; ++i) p_[i] = z_[i] + beta * p_[i];
  }
  st.iterations = std::min(st.iterations, max_iterations);
  return st;
}

}  // namespace lblight
