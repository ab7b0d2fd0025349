// The diffusion limit of one material's collision (docs/model.md sec. 9): light that has
// scattered many times relaxes to an equilibrium distribution over the directions, and its
// amplitude n (the moving directions' sum) obeys, per lattice step,
//   dn/dt = div(D grad n) - a n,   D = flux / rho - streaming,   a = rho * loss
// at density rho (Chapman-Enskog, as [Geist2010] eq. (4) for the isotropic case). The
// accelerated solver (solve/dsa.h) corrects the LB iteration with this equation.
#pragma once

#include <array>
#include <cmath>

#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/omega.h"

namespace lblight {

struct DiffusionMode {
  // The equilibrium per direction, normalised to a moving sum of 1; entry 0 is the f_0 reservoir
  // that keeps pace with it (0 where the material absorbs: its f_0 is dropped every step).
  std::array<double, d3q19::kQ> shape{};
  double loss = 0;       // a at density 1: what the equilibrium loses per step (>= 0)
  double flux = 0;       // D = flux / rho - streaming (inf: the collision does not scatter)
  double streaming = 0;
  bool keeps_f0 = true;

  // D at density rho, within [min, max]: free streaming (rho = 0) is not diffusion, and a
  // correction there only needs to carry light across.
  double diffusion(double rho, double min_d, double max_d) const;
  // How much of the first moment (the flux) one step relaxes at density rho: D = c^2 (1 / omega
  // - 1/2) with c^2 = 2 streaming, as for a BGK collision. Above 1 the flux reverses every step.
  double relaxation(double rho) const { return std::isfinite(flux) && flux > 0 ? 2.0 * streaming * rho / flux : 0.0; }
};

// From the collision matrix and the material's absorb flag (absorbs: f_0 dropped each step).
DiffusionMode diffusion_mode(const OmegaMatrix& omega, bool absorbs);

// Chapman-Enskog: sum_i c_ix y_i with (-Omega) y = c_x e over the odd part of Omega, for the
// equilibrium e of the moving directions (sum 1); inf when that block is singular.
double chapman_enskog_flux(const OmegaMatrix& omega, const std::array<double, d3q19::kQ>& e);

}  // namespace lblight
