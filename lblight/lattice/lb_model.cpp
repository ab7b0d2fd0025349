#include "lblight/lattice/lb_model.h"

#include "lblight/lattice/decay_constant.h"
#include "lblight/lattice/diffusion_limit.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <tuple>

namespace lblight {

using namespace d3q19;

std::string LbModel::name() const {
  if (!calibrated) return "paper";
  // The corrections that differ from the defaults: "no" those switched off, "with" those on.
  std::string off, on;
  LbModel copy = *this, defaults;
  for (int k = 0; k < static_cast<int>(kCalibrationNames.size()); ++k) {
    const bool is = *calibration_switch(copy, k);
    if (is == *calibration_switch(defaults, k)) continue;
    std::string& list = is ? on : off;
    list += std::string(list.empty() ? "" : ", ") + kCalibrationNames[k];
  }
  std::string differs = off.empty() ? "" : "no " + off;
  if (!on.empty()) differs += (differs.empty() ? "with " : "; with ") + on;
  return differs.empty() ? "calibrated" : "calibrated (" + differs + ")";
}

bool* calibration_switch(LbModel& m, int k) {
  bool* s[] = {&m.path_length,     &m.phase_moment,  &m.delta_m,         &m.isotropic_ambient,
               &m.remove_absorbed, &m.voxel_average, &m.diffusion_match, &m.path_absorption,
               &m.decay_match,     &m.first_collision};
  return s[k];
}

double discrete_mean_cosine(double g, int j) {
  double z = 0, m = 0;  // Z_j of [Geist2010] eq. (8) once, not once per i as normalized_phase does
  for (int i = 1; i < kQ; ++i) z += weight(i) * hg_phase(g, i, j);
  for (int i = 1; i < kQ; ++i) m += weight(i) * (hg_phase(g, i, j) / z) * cos_between(i, j);
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

namespace {

std::array<double, kQ> removal(double sigma_t, bool path_length) {
  std::array<double, kQ> removed{};
  for (int k = 1; k < kQ; ++k)
    removed[k] = path_length ? -std::expm1(-sigma_t * std::sqrt(static_cast<double>(length_sq(k)))) : sigma_t;
  return removed;
}

// Omega of the calibrated model for (delta-M scaled) sigma_a, sigma_s and a phase function whose
// discrete mean cosine is `mean_cosine` (phase_moment; else HG's g = mean_cosine as printed).
OmegaMatrix assemble(double sigma_a, double sigma_s, double mean_cosine, const LbModel& model,
                     std::array<double, kQ>& removed) {
  const double sigma_t = sigma_a + sigma_s;
  const double albedo = sigma_t > 0 ? sigma_s / sigma_t : 0.0;
  // What direction k loses per step at density 1: over its path length |c_k| (path_length) or
  // sigma_t as in the papers.
  // Of that, absorbed[k] is absorbed (the albedo's complement, or over the whole path).
  std::array<double, kQ> absorbed{};
  removed = removal(sigma_t, model.path_length);
  for (int k = 1; k < kQ; ++k) {
    const double len = model.path_length ? std::sqrt(static_cast<double>(length_sq(k))) : 1.0;
    absorbed[k] = model.path_length && model.path_absorption ? -std::expm1(-sigma_a * len) : removed[k] * (1.0 - albedo);
  }
  // The matched g depends on j's class only (axial or diagonal; the lattice's symmetry): two
  // bisections, not eighteen (this runs inside diffusion_match's own bisection).
  const bool matched = model.phase_moment || model.diffusion_match;
  const double g_axial = matched ? moment_matched_g(mean_cosine, 1) : mean_cosine;
  const double g_diagonal = matched ? moment_matched_g(mean_cosine, 7) : mean_cosine;
  OmegaMatrix om{};
  om[0] = -1.0;
  for (int j = 1; j < kQ; ++j) {
    om[j] = model.remove_absorbed ? 0.0 : absorbed[j];
    const double gj = is_axial(j) ? g_axial : g_diagonal;
    double z = 0;  // Z_j of [Geist2010] eq. (8)
    for (int k = 1; k < kQ; ++k) z += weight(k) * hg_phase(gj, k, j);
    for (int i = 1; i < kQ; ++i) {
      // What j loses is scattered (the albedo's share) by the phase function: each collision keeps
      // the light it does not absorb (column sums 0 for a lossless medium). Weighting the
      // scattered light by the receiving direction's step length instead (the transport equation
      // per unit length) measured worse against the reference (docs/accuracy.md).
      const double scatter = (removed[j] - absorbed[j]) * ((weight(i) * hg_phase(gj, i, j)) / z);
      om[i * kQ + j] = (i == j ? -removed[j] : 0.0) + scatter;
    }
  }
  for (int i = 1; i < kQ; ++i) om[i * kQ] = weight(i);
  return om;
}

}  // namespace

double lattice_diffusion(const OmegaMatrix& om, const std::array<double, kQ>& removed) {
  // Equilibrium of the moving directions: each holds w_i / r_i (light that leaves a direction
  // more slowly piles up in it), normalised to unit total.
  std::array<double, kQ> e{};
  double sum = 0;
  for (int i = 1; i < kQ; ++i) sum += e[i] = removed[i] > 0 ? weight(i) / removed[i] : 0.0;
  if (!(sum > 0)) return std::numeric_limits<double>::infinity();
  for (double& v : e) v /= sum;
  // Chapman-Enskog: D = sum_i c_ix y_i - 1/2 sum_i c_ix^2 e_i with (-Omega) y = c_x e.
  double d = chapman_enskog_flux(om, e);
  for (int i = 1; i < kQ; ++i) d -= 0.5 * cx(i) * cx(i) * e[i];
  return d;
}

namespace {

OmegaMatrix build_calibrated_omega(const OpticalParams& p, const LbModel& model) {
  const OpticalParams scaled = model_params(p, model);
  const double sigma_s = scaled.sigma_s, g = scaled.g;
  std::array<double, kQ> removed{};
  if (!model.diffusion_match || !(sigma_s > 0) || std::abs(g) >= 1.0)
    return assemble(p.sigma_a, sigma_s, g, model, removed);
  // decay_match refines diffusion_match and needs absorbed light to leave (else nothing decays).
  // Below sigma_t 0.05 per node (a mean free path of 20 nodes or more) light does not reach the
  // asymptotic regime in a lattice of practical size: D is matched there, which is also cheaper.
  const bool decay = model.decay_match && model.remove_absorbed && p.sigma_a > 0 && p.sigma_a + sigma_s >= 0.05;
  auto omega_at = [&](double mean_cosine) { return assemble(p.sigma_a, sigma_s, mean_cosine, model, removed); };
  // Bisection on [lo, hi], where the lattice's value falls as the mean cosine rises, for the mean
  // cosine whose value meets the target (clamped to the interval).
  auto match = [&](auto&& lattice_value, double target, double lo, double hi) {
    for (int it = 0; it < 50; ++it) {
      const double mid = 0.5 * (lo + hi);
      (lattice_value(omega_at(mid)) > target ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
  };
  // decay_match: light deep inside fades at exact transport's rate (of the medium as given, not
  // delta-M scaled: the reference scatters by HG itself). The lattice's kappa falls with the mean
  // cosine only above a peak (a very backward lattice phase function fades more slowly again);
  // kappa is matched on that branch, and where exact transport fades faster than that peak
  // (albedo well below 1: not diffusive) diffusion_match's rule stands in.
  if (decay) {
    const double target = transport_decay_constant(p.sigma_a, p.sigma_s, p.g);
    auto kappa = [](const OmegaMatrix& om) { return lattice_decay_constant(om, true); };
    double peak = 0.95, peak_kappa = -1.0;
    for (double mc = -0.95; mc < 0.96; mc += 0.1) {
      const double k = kappa(omega_at(mc));  // NaN (no Perron mode there): skipped
      if (k > peak_kappa) peak = mc, peak_kappa = k;
    }
    if (target <= peak_kappa) {
      const OmegaMatrix om = omega_at(match(kappa, target, peak, 0.95));
      if (std::abs(kappa(om) / target - 1.0) < 1e-6) return om;  // else the branch was not monotone
    }
  }
  // diffusion_match: multiply scattered light gets the physical diffusion coefficient
  // 1 / (3 (sigma_a + sigma_s (1 - g))); the lattice's falls as the mean cosine rises.
  return omega_at(match([&](const OmegaMatrix& om) { return -lattice_diffusion(om, removed); },
                        -1.0 / (3.0 * (p.sigma_a + sigma_s * (1.0 - g))), -0.95, 0.95));
}

}  // namespace

OmegaMatrix build_model_omega(const OpticalParams& p, const LbModel& model) {
  if (!model.calibrated) return build_omega(p);
  // The matching bisections take milliseconds; validation, planning and every frame of a gas
  // sequence ask for the same few materials again, so results are kept (a pure function).
  unsigned switches = 0;
  LbModel copy = model;
  for (int k = 0; k < static_cast<int>(kCalibrationNames.size()); ++k) switches |= (*calibration_switch(copy, k) ? 1u : 0u) << k;
  const auto key = std::make_tuple(p.sigma_a, p.sigma_s, p.g, switches);
  static std::mutex mutex;
  static std::map<std::tuple<double, double, double, unsigned>, OmegaMatrix> kept;
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (auto it = kept.find(key); it != kept.end()) return it->second;
  }
  const OmegaMatrix om = build_calibrated_omega(p, model);
  std::lock_guard<std::mutex> lock(mutex);
  if (kept.size() >= 4096) kept.clear();
  kept.emplace(key, om);
  return om;
}

OpticalParams model_params(const OpticalParams& p, const LbModel& model) {
  // Delta-M: for a forward peak, the fraction f = g^2 of scattering is taken as no scattering at
  // all, leaving sigma_s (1 - f) with asymmetry (g - f) / (1 - f); sigma_s (1 - g) is kept.
  OpticalParams out = p;
  if (model.calibrated && model.delta_m && p.g > 0.0 && p.g < 1.0) {
    const double f = p.g * p.g;
    out.sigma_s *= 1.0 - f;
    out.g = (p.g - f) / (1.0 - f);
  }
  return out;
}

std::array<double, kQ> model_removal(const OpticalParams& p, const LbModel& model) {
  return removal(model_params(p, model).sigma_t(), model.calibrated && model.path_length);
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
