// Diffusion synthetic acceleration of the LB iteration (docs/model.md sec. 9). Plain iteration
// needs ~R^2 steps in thick scattering media because its slowest errors are smooth and nearly in
// equilibrium over the directions: they only diffuse, one node per step. After a step, the change
// of the stored totals is (for those errors) the residual of a diffusion equation for the
// remaining error (lattice/diffusion_limit.h); one multigrid-preconditioned solve of it
// (diffusion/multigrid.h) estimates that error and the state is corrected by it, in the
// equilibrium's shape. What the diffusion picture misses (light not yet in equilibrium) the LB
// steps themselves damp within a few steps.
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "lblight/backend/backend.h"
#include "lblight/diffusion/multigrid.h"
#include "lblight/lattice/diffusion_limit.h"

namespace lblight {

struct DsaSettings {
  int steps_per_correction = 4;  // LB steps between corrections
  int span = 2;                  // the last steps of a cycle whose mean change is the residual
  double min_diffusion = 1e-3;   // per-node D range (lattice units per step)
  double max_diffusion = 4.0;
  double max_relaxation = 1.2;   // nodes whose first moment relaxes faster give no source (dsa.cpp)
  double solve_tolerance = 1e-2; // relative residual of each diffusion solve
  int max_solve_iterations = 20;
  // Per-step contraction assumed for the rounding floor until the cycles show their own
  // (convergence.h); measured cycles contract by ~0.15 per 4 steps on the dense cube.
  double expected_contraction = 0.7;
};

// One channel's correction on one lattice: coefficients and multigrid built once.
class DiffusionCorrection {
 public:
  DiffusionCorrection(const LatticeGeometry& geometry, const ChannelMaterials& channel, const DsaSettings& settings);

  // The equilibrium per material, as StateAccess::add_mode applies it.
  const std::array<std::array<double, d3q19::kQ>, kMaxMaterials>& shapes() const { return shapes_; }

  // From the stored totals before and after `steps` LB steps (dims.count() values each; their
  // mean change per step is the residual), the correction phi (dims.count(), 0 on the boundary
  // layer). `added` (optional) receives what the correction adds to each node's stored total.
  DiffusionSolveStats solve(const std::vector<float>& before, const std::vector<float>& after, int steps,
                            std::vector<double>& phi, std::vector<double>* added = nullptr);

 private:
  Dims dims_, interior_;
  std::array<std::array<double, d3q19::kQ>, kMaxMaterials> shapes_{};
  std::vector<double> source_per_total_;  // kept-entry sum per unit of stored total, per interior node
  std::vector<double> total_per_phi_;     // stored total per unit of phi, per interior node
  std::unique_ptr<MultigridSolver> mg_;
  DsaSettings settings_;
  std::vector<double> rhs_, sol_;
};

}  // namespace lblight
