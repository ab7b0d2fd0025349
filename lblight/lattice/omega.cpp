#include "lblight/lattice/omega.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace lblight {

using namespace d3q19;

double cos_between(int i, int j) {
  const int dot = cx(i) * cx(j) + cy(i) * cy(j) + cz(i) * cz(j);
  return dot / std::sqrt(static_cast<double>(length_sq(i) * length_sq(j)));
}

namespace {
bool same_direction(int i, int j) { return cx(i) == cx(j) && cy(i) == cy(j) && cz(i) == cz(j); }
bool opposite_direction(int i, int j) { return cx(i) == -cx(j) && cy(i) == -cy(j) && cz(i) == -cz(j); }

// Z_j = sum_i w_i p_ij, the denominator of eq. (8) (which writes it as (sum 2p + sum p) / 24).
double phase_norm(double g, int j) {
  double z = 0.0;
  for (int i = 1; i < kQ; ++i) z += weight(i) * hg_phase(g, i, j);
  return z;
}
}  // namespace

double hg_phase(double g, int i, int j) {
  if (g >= 1.0) return same_direction(i, j) ? 1.0 : 0.0;
  if (g <= -1.0) return opposite_direction(i, j) ? 1.0 : 0.0;
  // 1 - 2 g cos + g^2 written as a sum of two non-negative terms: the textbook form cancels
  // catastrophically (and can go negative) as |g| -> 1 along n_i = +-n_j.
  const double c = cos_between(i, j);
  const double denom = (1.0 - g * c) * (1.0 - g * c) + g * g * (1.0 - c * c);
  return (1.0 - g * g) / (denom * std::sqrt(denom));
}

double normalized_phase(double g, int i, int j) { return hg_phase(g, i, j) / phase_norm(g, j); }

OmegaMatrix build_omega(const OpticalParams& p) {
  OmegaMatrix om{};
  const double sigma_t = p.sigma_t();
  // Row 0 (eq. 5): f_0 loses everything, gains sigma_a of every moving direction.
  om[0] = -1.0;
  for (int j = 1; j < kQ; ++j) om[j] = p.sigma_a;
  for (int j = 1; j < kQ; ++j) {
    const double z = phase_norm(p.g, j);
    for (int i = 1; i < kQ; ++i) {
      // w_i * pn_ij computed as (w_i p_ij) / Z_j so that the |g| = 1 limit is exactly 1 on its
      // diagonal (w_j / w_j), which makes g = 1, sigma_a = 0 an exact pass-through.
      const double scatter = p.sigma_s * ((weight(i) * hg_phase(p.g, i, j)) / z);
      om[i * kQ + j] = (i == j ? -sigma_t : 0.0) + scatter;
    }
  }
  // Column 0 (eqs. 6-7): f_0 is re-emitted with the lattice weights.
  for (int i = 1; i < kQ; ++i) om[i * kQ] = weight(i);
  return om;
}

double diffusion_coefficient(const OpticalParams& p, double rho, bool absorbs) {
  const double st = rho * p.sigma_t();
  if (st <= 0.0) return std::numeric_limits<double>::infinity();
  return ((2.0 / st) - 1.0) / (4.0 * (absorbs ? 1.0 : 1.0 + p.sigma_a));
}

double min_diagonal_gain(const OmegaMatrix& omega, double rho) {
  double lo = std::numeric_limits<double>::infinity();
  for (int m = 0; m < kQ; ++m) lo = std::min(lo, 1.0 + rho * omega[m * kQ + m]);
  return lo;
}

double collision_spectral_radius(const OmegaMatrix& omega, double rho, bool absorbs) {
  // A = (I + rho Omega) K, K = diag(keep, 1, ..., 1): the update of docs/model.md sec. 3 as a matrix.
  std::array<double, kQ * kQ> a{}, b{};
  for (int m = 0; m < kQ; ++m)
    for (int n = 0; n < kQ; ++n)
      a[m * kQ + n] = (n == 0 && absorbs) ? 0.0 : (m == n ? 1.0 : 0.0) + rho * omega[m * kQ + n];
  // Gelfand: rho(A) = lim ||A^n||^(1/n). Square 40 times, rescaling each time and keeping the
  // logarithm of the scale: log ||A^(2^k)|| ~ log_scale.
  constexpr int kSquarings = 40;
  double log_scale = 0.0;
  for (int k = 0; k < kSquarings; ++k) {
    double peak = 0.0;
    for (int m = 0; m < kQ; ++m)
      for (int n = 0; n < kQ; ++n) {
        double s = 0.0;
        for (int l = 0; l < kQ; ++l) s += a[m * kQ + l] * a[l * kQ + n];
        b[m * kQ + n] = s;
        peak = std::max(peak, std::fabs(s));
      }
    if (peak == 0.0) return 0.0;  // nilpotent
    for (double& v : b) v /= peak;
    log_scale = 2.0 * log_scale + std::log(peak);
    a = b;
  }
  return std::exp(std::ldexp(log_scale, -kSquarings));
}

}  // namespace lblight
