#include "lblight/solve/dsa.h"

#include <cmath>

namespace lblight {

using d3q19::kQ;

DiffusionCorrection::DiffusionCorrection(const LatticeGeometry& g, const ChannelMaterials& ch, const DsaSettings& st)
    : dims_(g.dims), interior_{g.dims.nx - 2, g.dims.ny - 2, g.dims.nz - 2}, settings_(st) {
  std::array<DiffusionMode, kMaxMaterials> modes{};
  std::array<CollisionOp<double>, kMaxMaterials> ops{};
  for (int k = 0; k < g.material_count; ++k) {
    if (k == kMaterialGround) continue;  // no equilibrium: shape 0, handled per node below
    modes[k] = diffusion_mode(ch.omega[k], ch.absorbs[k]);
    shapes_[k] = modes[k].shape;
    ops[k] = channel_op(ch, k);
  }
  const std::size_t n = interior_.count();
  std::vector<double> a(n), D(n);
  source_per_total_.resize(n);
  total_per_phi_.resize(n);
  for (int z = 0; z < interior_.nz; ++z)
    for (int y = 0; y < interior_.ny; ++y)
      for (int x = 0; x < interior_.nx; ++x) {
        const std::size_t i = interior_.index(x, y, z);
        const std::size_t node = dims_.index(x + 1, y + 1, z + 1);
        const int k = g.material[node];
        if (k == kMaterialGround) {
          // The ground as the diffusion equation sees it: a sink with no correction of its own
          // (like the vacuum outside); the LB steps carry what it reflects.
          a[i] = 1.0;
          D[i] = st.min_diffusion;
          source_per_total_[i] = 0.0;
          total_per_phi_[i] = 0.0;
          continue;
        }
        const double rho = g.density[node];
        const DiffusionMode& m = modes[k];
        a[i] = rho * m.loss;
        D[i] = m.diffusion(rho, st.min_diffusion, st.max_diffusion);
        // The stored total of the equilibrium (node_rules.h: f_0 + sum_m (1 + rho gain_m) f_m; an
        // absorbing node's f_0 holds what its last collision absorbed) against its kept sum.
        double total = 0, kept = m.keeps_f0 ? m.shape[0] : 0.0;
        for (int q = 1; q < kQ; ++q) {
          total += (1.0 + rho * ops[k].total_gain[(q - 1) / 2]) * m.shape[q];
          kept += m.shape[q];
        }
        if (m.keeps_f0) {
          total += m.shape[0];
        } else {
          double absorbed = 0;
          for (int j = 1; j < kQ; ++j) absorbed += ch.omega[k][j] * m.shape[j];
          total += rho * absorbed;
        }
        total_per_phi_[i] = total;
        // Where the first moment overshoots each step (relaxation above max_relaxation: strong
        // backscatter such as bark's g = -1), light oscillates between opposite directions and
        // the change per step is no diffusion residual; those nodes give no source.
        const bool diffusive = !(rho > 0) || m.relaxation(rho) <= st.max_relaxation;
        source_per_total_[i] = total > 0 && diffusive ? kept / total : 0.0;
      }
  mg_ = std::make_unique<MultigridSolver>(diffusion_problem(interior_, std::move(a), D));
  rhs_.resize(n);
}

DiffusionSolveStats DiffusionCorrection::solve(const std::vector<float>& before, const std::vector<float>& after,
                                               int steps, std::vector<double>& phi, std::vector<double>* added) {
  for (int z = 0; z < interior_.nz; ++z)
    for (int y = 0; y < interior_.ny; ++y)
      for (int x = 0; x < interior_.nx; ++x) {
        const std::size_t i = interior_.index(x, y, z), node = dims_.index(x + 1, y + 1, z + 1);
        rhs_[i] = (static_cast<double>(after[node]) - static_cast<double>(before[node])) * source_per_total_[i] / steps;
      }
  const DiffusionSolveStats stats = mg_->solve(rhs_, sol_, settings_.solve_tolerance, settings_.max_solve_iterations);
  phi.assign(dims_.count(), 0.0);
  if (added) added->assign(dims_.count(), 0.0);
  for (int z = 0; z < interior_.nz; ++z)
    for (int y = 0; y < interior_.ny; ++y)
      for (int x = 0; x < interior_.nx; ++x) {
        const std::size_t i = interior_.index(x, y, z), node = dims_.index(x + 1, y + 1, z + 1);
        phi[node] = sol_[i];
        if (added) (*added)[node] = sol_[i] * total_per_phi_[i];
      }
  return stats;
}

}  // namespace lblight
