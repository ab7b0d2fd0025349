#include "lblight/lattice/decay_constant.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "lblight/lattice/d3q19.h"

namespace lblight {

using namespace d3q19;

double transport_decay_constant(double sigma_a, double sigma_s, double g) {
  const double sigma_t = sigma_a + sigma_s;
  if (!(sigma_t > 0)) return 0.0;
  const double albedo = sigma_s / sigma_t;
  if (!(albedo > 0)) return sigma_t;
  if (albedo >= 1.0) return 0.0;
  // psi(mu) exp(-nu sigma_t x) solves the transport equation when its Legendre moments phi_k obey
  //   (2k + 1) (1 - albedo g^k) phi_k = nu ((k + 1) phi_{k+1} + k phi_{k-1}),
  // a symmetric tridiagonal eigenproblem in 1 / nu once scaled by h_k^(1/2); 1 / nu0 is its
  // largest eigenvalue (the discrete mode, above 1), found by Sturm-count bisection.
  constexpr int n = 257;
  std::array<double, n> h{}, off{};
  double gk = 1.0;
  for (int k = 0; k < n; ++k, gk *= g) h[k] = (2.0 * k + 1.0) * (1.0 - albedo * gk);
  double bound = 0;
  for (int k = 0; k + 1 < n; ++k) bound = std::max(bound, 2.0 * (off[k] = (k + 1.0) / std::sqrt(h[k] * h[k + 1])));
  auto below = [&](double x) {  // eigenvalues below x: negative pivots of T - x I
    int count = 0;
    double d = -x;
    for (int k = 0; k < n; ++k) {
      if (k > 0) d = -x - off[k - 1] * off[k - 1] / d;
      if (d == 0.0) d = -1e-300;
      count += d < 0;
    }
    return count;
  };
  double lo = 0.0, hi = bound + 1.0;
  for (int it = 0; it < 100; ++it) {
    const double mid = 0.5 * (lo + hi);
    (below(mid) < n ? lo : hi) = mid;
  }
  const double nu = 1.0 / (0.5 * (lo + hi));
  return std::min(nu, 1.0) * sigma_t;
}

double lattice_decay_constant(const OmegaMatrix& om, bool absorbs) {
  const int first = absorbs ? 1 : 0;
  std::array<double, kQ * kQ> step{};  // I + Omega
  for (int i = first; i < kQ; ++i)
    for (int j = first; j < kQ; ++j) {
      step[i * kQ + j] = (i == j ? 1.0 : 0.0) + om[i * kQ + j];
      if (step[i * kQ + j] < 0) return std::numeric_limits<double>::quiet_NaN();
    }
  // Spectral radius of diag(exp(kappa c_ix)) (I + Omega) by power iteration from a positive start.
  // It is at most 1 at kappa = 0 (no collision creates light), even in kappa, and log-convex
  // (Kingman), so it crosses 1 once on kappa > 0.
  std::array<double, kQ> v{};
  for (int i = first; i < kQ; ++i) v[i] = 1.0;
  // Each call starts from the previous call's vector: the modes of nearby kappa are close.
  auto radius = [&](double kappa) {
    std::array<double, kQ> scale{};
    for (int i = first; i < kQ; ++i) scale[i] = std::exp(kappa * cx(i));
    double estimate = 0;
    for (int it = 0; it < 100000; ++it) {
      std::array<double, kQ> w{};
      double top = 0;
      for (int i = first; i < kQ; ++i) {
        double s = 0;
        for (int j = first; j < kQ; ++j) s += step[i * kQ + j] * v[j];
        top = std::max(top, w[i] = scale[i] * s);
      }
      if (!(top > 0)) return 0.0;
      for (int i = first; i < kQ; ++i) v[i] = w[i] / top;
      // v is normalised to a largest entry of 1, so top is the growth of the largest entry.
      if (std::abs(top - estimate) <= 1e-14 * top) return top;
      estimate = top;
    }
    return estimate;
  };
  if (radius(0.0) >= 1.0 - 1e-12) return 0.0;  // lossless: no decay
  double lo = 0.0, hi = 0.125, f_lo = std::log(radius(0.0)), f_hi;
  while ((f_hi = std::log(radius(hi))) < 0.0 && hi < 1e3) lo = hi, f_lo = f_hi, hi *= 2.0;
  // Regula falsi with the Illinois step on log(radius), which is convex: superlinear, bracketed.
  int side = 0;
  for (int it = 0; it < 100 && hi - lo > 1e-13 * hi; ++it) {
    const double mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
    const double f = std::log(radius(mid));
    if (f == 0.0) return mid;
    if (f < 0.0) {
      lo = mid, f_lo = f;
      if (side == -1) f_hi *= 0.5;
      side = -1;
    } else {
      hi = mid, f_hi = f;
      if (side == 1) f_lo *= 0.5;
      side = 1;
    }
  }
  return 0.5 * (lo + hi);
}

}  // namespace lblight
