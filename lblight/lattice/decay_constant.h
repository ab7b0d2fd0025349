// How fast light fades deep inside a uniform medium (docs/model.md sec. 8): far from sources and
// boundaries the light of a half-space falls as exp(-kappa x) with one shape over directions,
// the slowest-decaying planar mode. The calibrated model chooses its phase function so that the
// lattice's kappa equals exact transport's (decay_match), which holds where diffusion theory
// does not (albedo well below 1).
#pragma once

#include "lblight/lattice/omega.h"

namespace lblight {

// Exact transport's kappa per unit length for a Henyey-Greenstein medium: sigma_t / nu0 with
// nu0 Case's discrete eigenvalue of the planar mode exp(-x / (nu0 mfp)), from P_256 (converged
// to 1e-7 for albedo >= 0.4 and |g| <= 0.99). Capped at sigma_t (the uncollided light's own
// decay); 0 for a lossless medium.
double transport_decay_constant(double sigma_a, double sigma_s, double g);

// The lattice's kappa per node along an axis under `omega` at density 1: the f_i(x) = a_i
// exp(-kappa x) that one collision and one streaming step leave unchanged, the Perron root of
// diag(exp(kappa c_ix)) (I + Omega) equal to 1 (f_0 left out where the material absorbs).
// NaN when I + Omega has a negative entry (the mode is then not the Perron one) or the power
// iteration does not settle (light that takes more than ~1e5 collisions to mix over directions).
double lattice_decay_constant(const OmegaMatrix& omega, bool absorbs);

}  // namespace lblight
