#include "tests/support/reference_lattice.h"

#include "lblight/lattice/d3q19.h"

namespace lblight::test {

using d3q19::kQ;

ReferenceLattice::ReferenceLattice(const LatticeGeometry& g, const std::vector<OmegaMatrix>& omega,
                                   const std::vector<bool>& absorbs, const std::array<double, 19>& boundary)
    : g_(g), omega_(omega), absorbs_(absorbs), f_(kQ * g.dims.count(), 0.0) {
  const Dims& d = g_.dims;
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x)
        if (d.is_boundary(x, y, z))
          for (int m = 0; m < kQ; ++m) f_[m * d.count() + d.index(x, y, z)] = boundary[m];
}

void ReferenceLattice::step(int n) {
  const Dims& d = g_.dims;
  const std::size_t count = d.count();
  for (int t = 0; t < n; ++t) {
    std::vector<double> next = f_;  // boundary nodes keep their values
    for (int z = 0; z < d.nz; ++z)
      for (int y = 0; y < d.ny; ++y)
        for (int x = 0; x < d.nx; ++x) {
          const std::size_t p = d.index(x, y, z);
          const int mat = g_.material[p];
          double ft[kQ];
          for (int m = 0; m < kQ; ++m) ft[m] = f_[m * count + p];
          if (absorbs_[static_cast<std::size_t>(mat)]) ft[0] = 0.0;
          const OmegaMatrix& om = omega_[static_cast<std::size_t>(mat)];
          for (int m = 0; m < kQ; ++m) {
            double s = 0;
            for (int k = 0; k < kQ; ++k) s += om[m * kQ + k] * ft[k];
            const double post = ft[m] + g_.density[p] * s;
            const int qx = x + d3q19::cx(m), qy = y + d3q19::cy(m), qz = z + d3q19::cz(m);
            if (qx <= 0 || qy <= 0 || qz <= 0 || qx >= d.nx - 1 || qy >= d.ny - 1 || qz >= d.nz - 1) continue;
            next[m * count + d.index(qx, qy, qz)] = post;
          }
        }
    f_.swap(next);
  }
}

std::vector<double> ReferenceLattice::totals() const {
  const std::size_t count = g_.dims.count();
  std::vector<double> t(count, 0.0);
  for (int m = 0; m < kQ; ++m)
    for (std::size_t i = 0; i < count; ++i) t[i] += f_[m * count + i];
  return t;
}

StepBalance step_balance(const LatticeGeometry& g, const std::vector<OmegaMatrix>& omega,
                         const std::vector<bool>& absorbs, const std::vector<double>& f) {
  const Dims& d = g.dims;
  const std::size_t count = d.count();
  auto interior = [&](int x, int y, int z) {
    return x > 0 && y > 0 && z > 0 && x < d.nx - 1 && y < d.ny - 1 && z < d.nz - 1;
  };
  StepBalance b;
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x) {
        const std::size_t p = d.index(x, y, z);
        const bool inside = interior(x, y, z);
        const int mat = g.material[p];
        double ft[kQ];
        for (int m = 0; m < kQ; ++m) ft[m] = f[m * count + p];
        if (inside) {
          for (int m = 0; m < kQ; ++m) b.stored += ft[m];
        }
        if (absorbs[static_cast<std::size_t>(mat)]) {
          if (inside) b.absorbed += ft[0];
          ft[0] = 0.0;
        }
        const OmegaMatrix& om = omega[static_cast<std::size_t>(mat)];
        if (inside && mat == kMaterialGround)
          for (int m = 0; m < kQ; ++m) {
            double s = 0;
            for (int k = 0; k < kQ; ++k) s += om[m * kQ + k] * ft[k];
            b.ground -= g.density[p] * s;  // sum of post minus sum of f~
          }
        for (int m = 0; m < kQ; ++m) {
          const int qx = x + d3q19::cx(m), qy = y + d3q19::cy(m), qz = z + d3q19::cz(m);
          const bool on_lattice = qx >= 0 && qy >= 0 && qz >= 0 && qx < d.nx && qy < d.ny && qz < d.nz;
          if (!on_lattice || inside == interior(qx, qy, qz)) continue;  // neither inflow nor outflow
          double s = 0;
          for (int k = 0; k < kQ; ++k) s += om[m * kQ + k] * ft[k];
          const double post = ft[m] + g.density[p] * s;
          (inside ? b.outflow : b.inflow) += post;
        }
      }
  return b;
}

double interior_sum(const Dims& d, const std::vector<double>& f) {
  const std::size_t count = d.count();
  double s = 0;
  for (int z = 1; z < d.nz - 1; ++z)
    for (int y = 1; y < d.ny - 1; ++y)
      for (int x = 1; x < d.nx - 1; ++x)
        for (int m = 0; m < kQ; ++m) s += f[m * count + d.index(x, y, z)];
  return s;
}

}  // namespace lblight::test
