// The collision matrix Omega of [Geist2010] eqs. (5)-(9), built in double precision on the host.
#pragma once

#include <array>

#include "lblight/lattice/d3q19.h"

namespace lblight {

// Optical parameters of one material in one colour channel.
struct OpticalParams {
  double sigma_a = 0.0;  // absorption, >= 0
  double sigma_s = 0.0;  // scattering, >= 0
  double g = 0.0;        // Henyey-Greenstein asymmetry, in [-1, 1]
  double sigma_t() const { return sigma_a + sigma_s; }
};

// Row-major 19x19: entry (m, n) = omega[m * 19 + n] scatters from direction n into direction m.
using OmegaMatrix = std::array<double, d3q19::kQ * d3q19::kQ>;

// Discrete Henyey-Greenstein value p_ij(g) of eq. (9) for moving directions i, j >= 1.
// |g| = 1 is the limit: 1 where n_i . n_j = sign(g), else 0 (never evaluated as 0/0).
double hg_phase(double g, int i, int j);
// n_i . n_j of two moving directions.
double cos_between(int i, int j);

// Normalised phase pn_ij(g) of eq. (8); for every j, sum_i w_i pn_ij = 1.
double normalized_phase(double g, int i, int j);

// Omega of one material and channel (docs/model.md sec. 2).
OmegaMatrix build_omega(const OpticalParams& params);

// LB diffusion coefficient of [Geist2010] eq. (4) with lambda = tau = 1 for a node of density rho:
// ((2 / (rho sigma_t)) - 1) / (4 (1 + sigma_a)). The density scales f_0's release (Omega_00 = -1)
// as much as what feeds it (sigma_a), so f_0 holds sigma_a times the moving mass at any rho and
// light rests there a fraction sigma_a / (1 + sigma_a) of the time: 1 + sigma_a, not
// 1 + rho sigma_a (measured, tests/lattice/test_diffusion.cpp). A material that absorbs (dumps f_0)
// has no resting light: ((2 / (rho sigma_t)) - 1) / 4. Infinite for rho sigma_t = 0.
double diffusion_coefficient(const OpticalParams& params, double rho = 1.0, bool absorbs = false);

// Smallest diagonal entry 1 + rho * Omega_mm over m; negative values mean transients can go
// negative (docs/model.md sec. 6 asks for a warning, not a rejection).
double min_diagonal_gain(const OmegaMatrix& omega, double rho);

// Spectral radius of one node's update f -> f~ + rho Omega f~ (f~_0 = 0 when the material
// absorbs): the factor by which a uniform region of density rho amplifies its worst pattern of
// directions per step. Above 1 the scheme diverges there. rho sigma_t < 2 (docs/model.md sec. 6) keeps it
// at 1 for g >= 0, but with backscattering the odd patterns (f_m = -f_opp(m)) are multiplied by
// 1 - rho (sigma_t - sigma_s lambda), lambda down to -1 at g = -1: e.g. sigma_a 0.2,
// sigma_s 1.7, g = -1 at rho 1 gives -2.6 although rho sigma_t = 1.9. Computed in double as
// lim ||A^n||^(1/n) with n = 2^40 (repeated squaring), accurate to about 1e-12.
double collision_spectral_radius(const OmegaMatrix& omega, double rho, bool absorbs);

}  // namespace lblight
