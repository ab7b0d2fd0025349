#include "lblight/lattice/lb_model.h"

#include <cmath>

namespace lblight {

using namespace d3q19;

std::string LbModel::name() const {
  if (!calibrated) return "paper";
  std::string off;
  LbModel copy = *this;
  for (int k = 0; k < static_cast<int>(kCalibrationNames.size()); ++k)
    if (!*calibration_switch(copy, k)) off += std::string(off.empty() ? "" : ", ") + kCalibrationNames[k];
  return off.empty() ? "calibrated" : "calibrated (no " + off + ")";
}

bool* calibration_switch(LbModel& m, int k) {
  bool* s[] = {&m.path_length,       &m.phase_moment,    &m.delta_m,
               &m.isotropic_ambient, &m.remove_absorbed, &m.voxel_average};
  return s[k];
}

namespace {
double cos_between(int i, int j) {
  const int dot = cx(i) * cx(j) + cy(i) * cy(j) + cz(i) * cz(j);
  return dot / std::sqrt(static_cast<double>(length_sq(i) * length_sq(j)));
}
}  // namespace

double discrete_mean_cosine(double g, int j) {
  double m = 0;
  for (int i = 1; i < kQ; ++i) m += weight(i) * normalized_phase(g, i, j) * cos_between(i, j);
  return m;
}

double moment_matched_g(double target, int j) {
  if (target >= 1.0) return 1.0;
  if (target <= -1.0) return -1.0;
  // The discrete mean cosine rises monotonically from -1 to 1 with g: bisection.
  double lo = -1.0, hi = 1.0;
  for (int it = 0; it < 100; ++it) {
    const double mid = 0.5 * (lo + hi);
    (discrete_mean_cosine(mid, j) < target ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

OmegaMatrix build_model_omega(const OpticalParams& p, const LbModel& model) {
  if (!model.calibrated) return build_omega(p);
  // Delta-M: for a forward peak, the fraction f = g^2 of scattering is taken as no scattering at
  // all, leaving sigma_s (1 - f) with asymmetry (g - f) / (1 - f); sigma_s (1 - g) is kept.
  double sigma_s = p.sigma_s, g = p.g;
  if (model.delta_m && g > 0.0 && g < 1.0) {
    const double f = g * g;
    sigma_s *= 1.0 - f;
    g = (g - f) / (1.0 - f);
  }
  const double sigma_t = p.sigma_a + sigma_s;
  const double albedo = sigma_t > 0 ? sigma_s / sigma_t : 0.0;
  // What direction k loses per step at density 1: over its path length |c_k| (path_length) or
  // sigma_t as in the papers.
  std::array<double, kQ> removed{};
  for (int k = 1; k < kQ; ++k) {
    const double len = model.path_length ? std::sqrt(static_cast<double>(length_sq(k))) : 1.0;
    removed[k] = model.path_length ? -std::expm1(-sigma_t * len) : sigma_t;
  }
  OmegaMatrix om{};
  om[0] = -1.0;
  for (int j = 1; j < kQ; ++j) {
    om[j] = model.remove_absorbed ? 0.0 : removed[j] * (1.0 - albedo);
    const double gj = model.phase_moment ? moment_matched_g(g, j) : g;
    double z = 0;  // Z_j of [Geist2010] eq. (8)
    for (int k = 1; k < kQ; ++k) z += weight(k) * hg_phase(gj, k, j);
    for (int i = 1; i < kQ; ++i) {
      // What j loses is scattered (the albedo's share) by the phase function: each collision keeps
      // the light it does not absorb (column sums 0 for a lossless medium). Weighting the
      // scattered light by the receiving direction's step length instead (the transport equation
      // per unit length) measured worse against the reference (docs/accuracy.md).
      const double scatter = albedo * removed[j] * ((weight(i) * hg_phase(gj, i, j)) / z);
      om[i * kQ + j] = (i == j ? -removed[j] : 0.0) + scatter;
    }
  }
  for (int i = 1; i < kQ; ++i) om[i * kQ] = weight(i);
  return om;
}

bool model_absorbs(bool material_absorbs, const LbModel& model) {
  return (model.calibrated && model.remove_absorbed) || material_absorbs;
}

std::array<double, 19> ambient_boundary(const LbModel& model) {
  std::array<double, 19> f{};
  if (model.calibrated && model.isotropic_ambient) {
    for (int i = 1; i < kQ; ++i) f[i] = 18.0 * weight(i);
  } else {
    f.fill(1.0);
  }
  return f;
}

}  // namespace lblight
