#include "lblight/lattice/diffusion_limit.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace lblight {

using namespace d3q19;

double DiffusionMode::diffusion(double rho, double min_d, double max_d) const {
  if (!(rho > 0) || !std::isfinite(flux)) return max_d;
  return std::clamp(flux / rho - streaming, min_d, max_d);
}

double chapman_enskog_flux(const OmegaMatrix& om, const std::array<double, kQ>& e) {
  // y is odd (y_b = -y_a over antipodal pairs a, b), where Omega acts as the 9x9 block of a_m
  // rows and columns minus b_m columns: nonsingular even without absorption.
  constexpr int n = kQ / 2;
  double a[n][n + 1];
  for (int m = 0; m < n; ++m) {
    const int am = 2 * m + 1;
    for (int k = 0; k < n; ++k) a[m][k] = -(om[am * kQ + 2 * k + 1] - om[am * kQ + 2 * k + 2]);
    a[m][n] = cx(am) * e[am];
  }
  for (int c = 0; c < n; ++c) {  // Gauss-Jordan with partial pivoting
    int piv = c;
    for (int r = c + 1; r < n; ++r)
      if (std::abs(a[r][c]) > std::abs(a[piv][c])) piv = r;
    for (int k = 0; k <= n; ++k) std::swap(a[c][k], a[piv][k]);
    if (a[c][c] == 0.0) return std::numeric_limits<double>::infinity();
    for (int r = 0; r < n; ++r)
      if (r != c) {
        const double f = a[r][c] / a[c][c];
        for (int k = c; k <= n; ++k) a[r][k] -= f * a[c][k];
      }
  }
  double d = 0;
  for (int m = 0; m < n; ++m) d += 2.0 * cx(2 * m + 1) * a[m][n] / a[m][m];
  return d;
}

DiffusionMode diffusion_mode(const OmegaMatrix& om, bool absorbs) {
  DiffusionMode mode;
  mode.keeps_f0 = !absorbs;
  // The equilibrium has the lattice's cubic symmetry: one value for f_0, one for the 6 axial and
  // one for the 12 diagonal directions. Omega maps that 3-dimensional space onto itself; the
  // equilibrium is its eigenvector with the largest (least negative) eigenvalue, found by power
  // iteration on I + B / s with s large enough that every eigenvalue of B / s lies in [-1, 0].
  double b[3][3] = {};
  const int rep[3] = {0, 1, 7};
  for (int k = 0; k < 3; ++k)
    for (int l = 0; l < 3; ++l) {
      if (absorbs && (k == 0 || l == 0)) continue;  // f_0 is dropped: not part of the state
      for (int j = 0; j < kQ; ++j) {
        const int cls = j == 0 ? 0 : (is_axial(j) ? 1 : 2);
        if (cls == l) b[k][l] += om[rep[k] * kQ + j];
      }
    }
  double s = 1e-300;
  for (auto& row : b)
    for (double v : row) s += std::abs(v);
  double v[3] = {absorbs ? 0.0 : 1.0, 1.0, 1.0};
  for (int it = 0; it < 1000000; ++it) {
    double w[3], norm = 0, change = 0;
    for (int k = 0; k < 3; ++k) {
      w[k] = v[k];
      for (int l = 0; l < 3; ++l) w[k] += b[k][l] * v[l] / s;
      norm = std::max(norm, std::abs(w[k]));
    }
    for (int k = 0; k < 3; ++k) {
      w[k] /= norm;
      change = std::max(change, std::abs(w[k] - v[k]));
      v[k] = w[k];
    }
    if (change < 1e-15) break;
  }
  double moving = 0;
  for (int i = 1; i < kQ; ++i) moving += v[is_axial(i) ? 1 : 2];
  for (int i = 0; i < kQ; ++i) mode.shape[i] = (i == 0 ? (absorbs ? 0.0 : v[0]) : v[is_axial(i) ? 1 : 2]) / moving;
  // loss: minus the change of the kept entries' sum under one collision at density 1
  double change = 0;
  for (int i = absorbs ? 1 : 0; i < kQ; ++i)
    for (int j = absorbs ? 1 : 0; j < kQ; ++j) change += om[i * kQ + j] * mode.shape[j];
  mode.loss = std::max(0.0, -change);
  std::array<double, kQ> e = mode.shape;
  e[0] = 0;
  mode.flux = chapman_enskog_flux(om, e);
  for (int i = 1; i < kQ; ++i) mode.streaming += 0.5 * cx(i) * cx(i) * e[i];
  return mode;
}

}  // namespace lblight
