// Classical (CDA) and flux-limited (FLD) diffusion of multiply scattered light, [Koerner2014]
// eqs. (12)-(37) (docs/model.md sec. 10): on a voxel grid with spacing dl,
//   -div(D grad phi) + (1 - albedo) sigma_t phi = j,   D = F(R) / sigma_t,
//   R = |grad phi| / (sigma_t phi)  (the Knudsen number, eq. 16)
// with F = 1/3 for CDA and Levermore-Pomraning's F(R) = (coth R - 1/R) / R for FLD (Table 2),
// phi given on the grid's outer layer (0 by default). Two solvers for the same discrete equations (eq. 31, face
// coefficients (D_p + D_s) / 2): the paper's Algorithm 1 (red-black Gauss-Seidel with
// over-relaxation, D updated in the sweep) and Picard iterations whose linear solves are
// multigrid-preconditioned conjugate gradients (diffusion/multigrid.h).
#pragma once

#include <vector>

#include "lblight/lattice/lattice.h"

namespace lblight {

enum class FluxLimiter { Classical, LevermorePomraning };
enum class DiffusionSolver { GaussSeidel, Multigrid };

struct RadiativeMedium {
  Dims dims;                    // every node; the outer layer holds phi = 0
  double voxel = 1.0;           // dl, world units
  std::vector<double> sigma_t;  // per node, 1 / world units
  std::vector<double> albedo;   // per node, in [0, 1]
  std::vector<double> emission; // j per node: power per unit volume
  // Fluence held on the outer layer (every node; only the outer layer is read); empty: phi = 0
  // there, as [Koerner2014] does. An analytic solution there tests the discretisation alone
  // (its Fig. 5(a)).
  std::vector<double> boundary;
  // Vacuum by Marshak's condition instead: the flux leaving through the medium's surface, half a
  // voxel beyond the last node, is phi / 2 there (no light comes back in); ignores `boundary`.
  bool marshak = false;
};

struct RadiativeDiffusionOptions {
  FluxLimiter limiter = FluxLimiter::LevermorePomraning;
  DiffusionSolver solver = DiffusionSolver::Multigrid;
  double tolerance = 1e-6;         // RMS residual of eq. (31) over RMS emission, as Algorithm 1
  int max_iterations = 100000;     // Gauss-Seidel sweeps, or Picard iterations
  double over_relaxation = 1.5;    // Algorithm 1's SOR factor (1.8 stalled FLD on 21^3)
  double sigma_floor_per_extent = 1e-3;  // sigma_eps = this / grid extent (sec. 5)
};

struct RadiativeDiffusionResult {
  std::vector<double> phi;       // fluence per node
  int iterations = 0;            // Gauss-Seidel sweeps, or Picard iterations
  int linear_iterations = 0;     // multigrid: CG iterations over all Picard steps
  double residual = 0;           // RMS residual / RMS emission at the end
  double seconds = 0;
  bool converged = false;
};

// Levermore-Pomraning's limiter, with its series near R = 0 (1/3 - R^2/45).
double levermore_pomraning(double knudsen);

RadiativeDiffusionResult solve_radiative_diffusion(const RadiativeMedium& medium,
                                                   const RadiativeDiffusionOptions& options);

}  // namespace lblight
