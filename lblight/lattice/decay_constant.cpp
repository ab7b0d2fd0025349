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
  // psi(mu) exp(-sigma_t x / nu) solves the transport equation when its Legendre moments obey
  //   (2k + 1) (1 - albedo g^k) phi_k nu = (k + 1) phi_{k+1} + k phi_{k-1},
  // a symmetric tridiagonal eigenproblem in nu once scaled by h_k^(1/2). Its largest eigenvalue
  // is Case's nu0 (above 1: the discrete mode), found by Sturm-count bisection.
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
  const double nu0 = 0.5 * (lo + hi);
  return sigma_t / std::max(nu0, 1.0);
}

double lattice_decay_constant(const OmegaMatrix& om, bool absorbs) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  const int first = absorbs ? 1 : 0;
  std::array<double, kQ * kQ> step{};  // I + Omega
  bool coupled = false;
  for (int i = first; i < kQ; ++i)
    for (int j = first; j < kQ; ++j) {
      step[i * kQ + j] = (i == j ? 1.0 : 0.0) + om[i * kQ + j];
      if (step[i * kQ + j] < 0) return kNaN;
      coupled = coupled || (i != j && step[i * kQ + j] > 0);
    }
  if (!coupled) {
    // Nothing moves light between directions: each fades on its own, and the slowest one along
    // +x sets kappa (a lossless direction across x: no decay).
    double kappa = std::numeric_limits<double>::infinity();
    for (int i = std::max(first, 1); i < kQ; ++i) {
      const double keep = step[i * kQ + i];
      if (cx(i) == 0 && keep >= 1.0) return 0.0;
      if (cx(i) > 0 && keep > 0) kappa = std::min(kappa, -std::log(keep));
    }
    return kappa;
  }
  // log of the spectral radius of M = diag(exp(kappa c_ix)) (I + Omega). It is at most 1 at
  // kappa = 0 (no collision creates light), even in kappa and log-convex (Kingman), so it crosses
  // 1 once on kappa > 0. A = (M + I) / 2 has the same Perron vector and is aperiodic; power
  // iteration runs on B = A^(2^q), squared again (renormalised) whenever 64 iterations do not
  // settle (in thin media light takes ~1 / sigma_s steps to mix over the directions), and stops
  // when the Collatz-Wielandt bounds min_i and max_i of (B v)_i / v_i meet; NaN if they do not
  // by q = 30.
  std::array<double, kQ> v{};
  for (int i = first; i < kQ; ++i) v[i] = 1.0;
  // Each call starts from the previous call's vector: the modes of nearby kappa are close.
  auto log_radius = [&](double kappa) {
    std::array<double, kQ * kQ> b{}, sq{};
    for (int i = first; i < kQ; ++i)
      for (int j = first; j < kQ; ++j)
        b[i * kQ + j] = 0.5 * (std::exp(kappa * cx(i)) * step[i * kQ + j] + (i == j ? 1.0 : 0.0));
    double log_scale = 0;  // B = exp(log_scale) b = A^(2^q)
    int q = 0;
    auto square = [&] {
      double top = 0;
      for (int i = first; i < kQ; ++i)
        for (int j = first; j < kQ; ++j) {
          double s = 0;
          for (int k = first; k < kQ; ++k) s += b[i * kQ + k] * b[k * kQ + j];
          top = std::max(top, sq[i * kQ + j] = s);
        }
      for (int i = first; i < kQ; ++i)
        for (int j = first; j < kQ; ++j) b[i * kQ + j] = sq[i * kQ + j] / top;
      log_scale = 2.0 * log_scale + std::log(top);
      ++q;
      return top > 0 && std::isfinite(top);
    };
    for (int round = 0; round <= 30; ++round) {
      if (round > 0 && !square()) return kNaN;
      for (int it = 0; it < 64; ++it) {
        std::array<double, kQ> w{};
        double top = 0, lower = std::numeric_limits<double>::infinity(), upper = 0;
        for (int i = first; i < kQ; ++i) {
          double s = 0;
          for (int j = first; j < kQ; ++j) s += b[i * kQ + j] * v[j];
          w[i] = s;
          top = std::max(top, s);
          lower = std::min(lower, s / v[i]);
          upper = std::max(upper, s / v[i]);
        }
        if (!(top > 0) || !std::isfinite(top)) return kNaN;
        for (int i = first; i < kQ; ++i) v[i] = std::max(w[i] / top, 1e-300);
        if (upper - lower <= 1e-12 * upper) {
          const double log_a = (log_scale + std::log(0.5 * (lower + upper))) / std::ldexp(1.0, q);
          return std::log(std::max(2.0 * std::exp(log_a) - 1.0, 1e-300));
        }
      }
    }
    return kNaN;
  };
  double lo = 0.0, hi = 0.125, f_lo = log_radius(0.0), f_hi;
  if (std::isnan(f_lo)) return kNaN;
  if (f_lo >= -1e-12) return 0.0;  // lossless: no decay
  while ((f_hi = log_radius(hi)) < 0.0 && hi < 256.0) lo = hi, f_lo = f_hi, hi *= 2.0;
  if (!(f_hi >= 0.0)) return kNaN;  // not bracketed, or the iteration did not settle
  // Regula falsi with the Illinois step on log(radius), which is convex: superlinear, bracketed.
  int side = 0;
  for (int it = 0; it < 100 && hi - lo > 1e-13 * hi; ++it) {
    const double mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
    const double f = log_radius(mid);
    if (std::isnan(f)) return kNaN;
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
