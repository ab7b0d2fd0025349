// A diffusion-reaction problem on the interior nodes of a lattice and its solver:
//   a(x) phi(x) + sum over the 6 axial neighbours y of c(x, y) (phi(x) - phi(y)) = s(x)
// with phi = 0 on the boundary layer (its couplings count in the diagonal), which is
// -div(D grad phi) + a phi = s discretised with face conductances c = D on the face (lattice
// units, node spacing 1). Symmetric positive definite when a >= 0, every c >= 0 and every
// connected part of the lattice touches the boundary or absorbs.
//
// Solved by conjugate gradients preconditioned with one multigrid V-cycle (docs/model.md sec. 9):
// coarse levels aggregate 2x2x2 nodes (Galerkin sums of a, face conductances halved as a
// rediscretisation on the doubled spacing gives), red-black Gauss-Seidel smoothing. Every sum is
// taken in a fixed order, so results do not depend on the thread count.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "lblight/lattice/lattice.h"

namespace lblight {

// Coefficients on the interior nodes (dims = lattice dims - 2 per axis), x fastest.
struct DiffusionProblem {
  Dims dims;                 // interior nodes
  std::vector<double> a;     // absorption per node, >= 0
  std::vector<double> cx;    // conductance between node i and its +x neighbour (0 on the last column)
  std::vector<double> cy, cz;
  std::vector<double> boundary;  // summed conductance from node i to boundary-layer neighbours
};

// Conductances from per-node diffusion coefficients D: the harmonic mean on each face (the flux
// through a face between two media) or the arithmetic mean ([Koerner2014] eq. 31), D of the
// interior node itself towards the boundary layer.
enum class FaceMean { Harmonic, Arithmetic };
DiffusionProblem diffusion_problem(const Dims& interior, std::vector<double> a, const std::vector<double>& D,
                                   FaceMean mean = FaceMean::Harmonic);

struct DiffusionSolveStats {
  int iterations = 0;       // CG iterations (one V-cycle each)
  double residual = 0;      // final ||s - A phi|| / ||s||
};

class MultigridSolver {
 public:
  explicit MultigridSolver(const DiffusionProblem& problem);
  ~MultigridSolver();
  MultigridSolver(const MultigridSolver&) = delete;
  MultigridSolver& operator=(const MultigridSolver&) = delete;

  // Solves A phi = s to relative residual `tolerance` or `max_iterations`, from phi = 0.
  // phi and s: interior_count() values.
  DiffusionSolveStats solve(const std::vector<double>& s, std::vector<double>& phi, double tolerance,
                            int max_iterations);
  // y = A x.
  void apply(const std::vector<double>& x, std::vector<double>& y) const;
  // One V-cycle from z = 0: z ~ A^-1 r (the preconditioner; symmetric).
  void v_cycle(const std::vector<double>& r, std::vector<double>& z);
  int levels() const;

 private:
  struct Level;
  std::vector<std::unique_ptr<Level>> levels_;
  std::vector<double> r_, z_, p_, q_;
};

}  // namespace lblight
