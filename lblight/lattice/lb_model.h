// Which LB model a bake solves (docs/model.md sec. 8): the papers' update ([Geist2010] eqs. 5-9,
// bit for bit), or the same update with its collision matrix and boundary values calibrated
// against physical light (docs/truth.md measures both). Every correction lives in the
// per-material Omega and the boundary values, so the kernel and its cost are the same.
#pragma once

#include <array>
#include <string>

#include "lblight/lattice/omega.h"

namespace lblight {

struct LbModel {
  bool calibrated = false;  // false: the papers' model; the switches below then do nothing
  // Each correction of the calibrated model, separately switchable (all on by default):
  bool path_length = true;        // direction j loses 1 - exp(-sigma_t |c_j|) per step, not sigma_t
  bool phase_moment = true;       // the discrete phase function's mean cosine equals g (unless diffusion_match)
  bool delta_m = true;            // g > 0: the forward peak g^2 of sigma_s passes unscattered
  bool isotropic_ambient = true;  // B00's boundary is isotropic light: f_i = 18 w_i
  bool remove_absorbed = true;    // absorbed light leaves (f_0 stays 0, the total is the moving part)
  bool voxel_average = true;      // the stored total is the voxel's mean (entering and leaving light)
  // The discrete phase function's mean cosine chosen so that the lattice's diffusion coefficient
  // is the physical 1 / (3 sigma_tr) (replaces phase_moment's target g).
  bool diffusion_match = true;
  // With path_length, absorption acts over the step's whole path: direction j absorbs
  // 1 - exp(-sigma_a |c_j|) and scatters the rest of what it loses (instead of splitting
  // 1 - exp(-sigma_t |c_j|) by albedo).
  bool path_absorption = false;
  // With diffusion_match, where the medium absorbs and remove_absorbed is on: the mean cosine
  // chosen so that the lattice's decay constant deep inside the medium is exact transport's
  // (lattice/decay_constant.h), where the lattice can reach it.
  bool decay_match = true;
  // The uncollided light (what has not scattered) carried exactly instead of by the lattice's 18
  // directions: each stored total gets the ray-marched, voxel-averaged uncollided fluence in place
  // of the lattice's own uncollided part (solve/first_collision.h). Base solutions only.
  bool first_collision = false;

  bool first_collision_on() const { return calibrated && first_collision; }

  // "paper", "calibrated", or "calibrated (no path_length, ...; with path_absorption)": the
  // corrections that differ from the defaults
  std::string name() const;
};

// The names of the corrections, in the order above ("path_length", ...).
inline constexpr std::array<const char*, 10> kCalibrationNames{
    "path_length",   "phase_moment",    "delta_m",         "isotropic_ambient", "remove_absorbed",
    "voxel_average", "diffusion_match", "path_absorption", "decay_match",       "first_collision"};
bool* calibration_switch(LbModel& model, int k);  // the switch kCalibrationNames[k]

// Omega of one material and channel under `model` (build_omega for the papers' model).
OmegaMatrix build_model_omega(const OpticalParams& params, const LbModel& model);

// The optical parameters the lattice scatters with under `model`: delta-M scaled where that
// correction is on (sigma_s (1 - g^2), asymmetry (g - g^2) / (1 - g^2)), else as given.
OpticalParams model_params(const OpticalParams& params, const LbModel& model);

// What direction k (1..18) loses per step at density 1: 1 - exp(-sigma_t |c_k|) with path_length,
// sigma_t as in the papers (sigma_t of model_params; entry 0 is 0).
std::array<double, d3q19::kQ> model_removal(const OpticalParams& params, const LbModel& model);

// Whether nodes of a material with the given absorb flag dump f_0 under `model`.
bool model_absorbs(bool material_absorbs, const LbModel& model);

// B00's boundary values under `model`: 1 for every i (papers), or 18 w_i, f_0 = 0 (isotropic).
std::array<double, 19> ambient_boundary(const LbModel& model);

// Mean cosine sum_i w_i pn_ij(g) n_i . n_j of the discrete phase function for incoming direction j,
// and the g whose discrete phase has mean cosine `target` (axial and diagonal j differ).
double discrete_mean_cosine(double g, int j);
double moment_matched_g(double target, int j);

// The diffusion coefficient per lattice step of multiply scattered light under `omega`
// (Chapman-Enskog; removed[k]: what direction k loses per step, which sets the equilibrium
// w_k / removed[k]). The papers' isotropic model gives (1 / sigma_t - 1 / 2) / 2, [Geist2010] eq. (4).
double lattice_diffusion(const OmegaMatrix& omega, const std::array<double, d3q19::kQ>& removed);

}  // namespace lblight
