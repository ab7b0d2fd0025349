// A planned solution by the diffusion solvers of [Koerner2014] (diffusion/radiative_diffusion.h,
// docs/truth.md sec. 6), in the Monte Carlo reference's normalisation so that `compare` and
// `report --truth` measure both against each other: the uncollided fluence from ray-marched
// transmittance, its first scattering as the source of the diffuse fluence (CDA or FLD, with the
// transport-corrected extinction sigma_a + sigma_s (1 - g)), their sum per node.
#pragma once

#include <vector>

#include "lblight/diffusion/radiative_diffusion.h"
#include "lblight/reference/montecarlo.h"
#include "lblight/solve/bake.h"
#include "lblight/solve/plan.h"

namespace lblight {

struct DiffusionRunOptions {
  FluxLimiter limiter = FluxLimiter::LevermorePomraning;
  DiffusionSolver solver = DiffusionSolver::Multigrid;
  double tolerance = 1e-6;
  bool marshak = true;
  bool delta_m = true;  // forward peaks g^2 stay in the uncollided beam (diffusion_solution.cpp)  // vacuum by Marshak's condition; false: phi = 0 beyond the lattice ([Koerner2014])
};

// The fluence of light that has not scattered, per lattice node (boundary nodes: the empty-lattice
// value): a collimated part marched back along its direction through each voxel's extinction
// (rho sigma_t per voxel length), isotropic light over the 18 lattice directions with the
// lattice weights as the quadrature.
std::vector<double> uncollided_fluence(const LatticeGeometry& lattice, const ChannelOptics& optics,
                                       const Illumination& light);

// Every distinct channel of one solution; seconds the solver's, iterations its Picard iterations
// or sweeps, error_estimate its final residual (not an error against light).
SolutionResult diffuse_solution(const ModelPlan& model, const Scene& scene, const SolutionPlan& solution,
                                const DiffusionRunOptions& options);

}  // namespace lblight
