// The literal reference LB: docs/model.md sec. 3 written as plainly as possible, in double with
// the dense Omega of each material, against which every backend is checked
// (tests/backend/conformance.cpp), and the per-step energy balance it implies.
#pragma once

#include <array>
#include <vector>

#include "lblight/backend/backend.h"
#include "lblight/lattice/omega.h"

namespace lblight::test {

// Where the interior's light goes in one step of docs/model.md sec. 3, for a state f (19 * count values,
// direction-major, boundary nodes holding their fixed values). With S = sum of f over interior
// nodes, the update conserves sum_m f~_m at every node (the columns of Omega sum to 0), so
//   S(t+1) = S(t) + inflow - outflow - absorbed
// exactly, up to rounding.
struct StepBalance {
  double stored = 0;    // S(t): sum of f over interior nodes before the step
  double inflow = 0;    // post-collision values boundary nodes push into interior nodes
  double outflow = 0;   // post-collision values interior nodes push into boundary nodes (dropped)
  double absorbed = 0;  // f_0 that absorbing interior nodes dump (f~_0 = 0)
  double ground = 0;    // what ground nodes (kMaterialGround) keep: their columns do not sum to 0
  double predicted_next() const { return stored + inflow - outflow - absorbed - ground; }
};
// Evaluates the step in double with the dense Omega of each material.
StepBalance step_balance(const LatticeGeometry& g, const std::vector<OmegaMatrix>& omega_per_material,
                         const std::vector<bool>& absorbs, const std::vector<double>& f);
// Sum of f over interior nodes.
double interior_sum(const Dims& d, const std::vector<double>& f);

// Spec sec. 3, written as plainly as possible: dense Omega in double, every node (boundary
// included) collides and pushes, only interior targets are written, boundary values fixed.
class ReferenceLattice {
 public:
  ReferenceLattice(const LatticeGeometry& g, const std::vector<OmegaMatrix>& omega_per_material,
                   const std::vector<bool>& absorbs, const std::array<double, 19>& boundary);
  void step(int n = 1);
  std::vector<double> totals() const;
  std::vector<double>& state() { return f_; }
  const std::vector<double>& state() const { return f_; }
  StepBalance balance() const { return step_balance(g_, omega_, absorbs_, f_); }  // of the next step
  double stored() const { return interior_sum(g_.dims, f_); }

 private:
  LatticeGeometry g_;
  std::vector<OmegaMatrix> omega_;
  std::vector<bool> absorbs_;
  std::vector<double> f_;
};

}  // namespace lblight::test
