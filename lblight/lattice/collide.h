// The per-node physics of one LB step (docs/model.md sec. 3), written once for every backend:
//   post_m = f~_m + rho * sum_n Omega_mn f~_n
// with Omega applied in its reduced form (collision_op.h). Backends supply only the loop
// around it (OpenMP rows, GPU threads).
//
// Written for GCC's vectoriser as much as for GPUs: inputs are read-only arrays (copying a local
// array blocks vectorisation of the caller's loop), absorption is a factor rather than a branch,
// and material choices are value selects rather than conditional loads.
#pragma once

#include "lblight/core/hostdev.h"
#include "lblight/lattice/collision_op.h"
#include "lblight/lattice/cubic_form.h"
#include "lblight/lattice/d3q19.h"

namespace lblight {

// Sums of the rows of one antipodal pair: E (even part plus re-emitted f_0) and O (odd part).
template <typename Real, typename OpReal>
LBL_HOSTDEV LBL_FORCEINLINE void pair_rows(const CollisionOp<OpReal>& op, int m, Real f0, const Real (&e)[kPairs],
                                           const Real (&o)[kPairs], Real& E, Real& O) {
  E = static_cast<Real>(op.col0[m]) * f0;
  O = Real(0);
  LBL_UNROLL
  for (int k = 0; k < kPairs; ++k) {
    E += static_cast<Real>(op.even[m * kPairs + k]) * e[k];
    O += static_cast<Real>(op.odd[m * kPairs + k]) * o[k];
  }
}

template <typename Real>
LBL_HOSTDEV LBL_FORCEINLINE void split_pairs(const Real (&f)[d3q19::kQ], Real (&e)[kPairs], Real (&o)[kPairs]) {
  LBL_UNROLL
  for (int k = 0; k < kPairs; ++k) {
    e[k] = f[2 * k + 1] + f[2 * k + 2];
    o[k] = f[2 * k + 1] - f[2 * k + 2];
  }
}

// (Omega f)_0 = sigma_a sum_j f_j - f_0: what a node that keeps f_0 still lacks of its
// reservoir's local equilibrium (see Residual::deficit_sq).
template <typename Real, typename OpReal>
LBL_HOSTDEV LBL_FORCEINLINE Real f0_deficit(const CollisionOp<OpReal>& op, const Real (&f)[d3q19::kQ]) {
  Real s = static_cast<Real>(op.diag0) * f[0];
  LBL_UNROLL
  for (int k = 0; k < kPairs; ++k) s += static_cast<Real>(op.row0[k]) * (f[2 * k + 1] + f[2 * k + 2]);
  return s;
}

// The whole per-node update for a node of one material in the even/odd form (every centrally
// symmetric Omega); post_m goes to store(m, value) as soon as it is known. f0_keep is 0 for
// materials that absorb ("green" nodes dump what they absorbed last step, [Steele2009] Listing
// 5.1) and 1 otherwise.
template <typename Real, typename OpReal, typename Store>
LBL_HOSTDEV LBL_FORCEINLINE void collide_pairs(const CollisionOp<OpReal>& op, Real f0_keep, Real rho,
                                               const Real (&f)[d3q19::kQ], Store&& store) {
  const Real f0 = f[0] * f0_keep;
  Real e[kPairs], o[kPairs];
  split_pairs(f, e, o);
  Real s0 = static_cast<Real>(op.diag0) * f0;
  LBL_UNROLL
  for (int k = 0; k < kPairs; ++k) s0 += static_cast<Real>(op.row0[k]) * e[k];
  store(0, f0 + rho * s0);
  LBL_UNROLL
  for (int m = 0; m < kPairs; ++m) {
    Real E, O;
    pair_rows(op, m, f0, e, o, E, O);
    store(2 * m + 1, f[2 * m + 1] + rho * (E + O));
    store(2 * m + 2, f[2 * m + 2] + rho * (E - O));
  }
}

// The same update in the symmetry-adapted form (cubic_form.h), for operators with is_cubic set:
// the same result up to float rounding, in about half the arithmetic.
template <typename Real, typename OpReal, typename Store>
LBL_HOSTDEV LBL_FORCEINLINE void collide_cubic(const CollisionOp<OpReal>& op, Real f0_keep, Real rho,
                                               const Real (&f)[d3q19::kQ], Store&& store) {
  const Real f0 = f[0] * f0_keep;
  Real e[kPairs], o[kPairs], c[kCubicCoords], C[kCubicCoords], E[kPairs], O[kPairs], s0;
  split_pairs(f, e, o);
  cubic_coords(f0, e, o, c);
  cubic_blocks(op.cubic, c, C);
  cubic_rows(C, s0, E, O);
  store(0, f0 + rho * s0);
  LBL_UNROLL
  for (int m = 0; m < kPairs; ++m) {
    store(2 * m + 1, f[2 * m + 1] + rho * (E[m] + O[m]));
    store(2 * m + 2, f[2 * m + 2] + rho * (E[m] - O[m]));
  }
}

// One node of one material, in the cheaper form its operator allows. CPU loops pick the form
// once per row instead (a branch inside the SIMD loop would stop GCC's vectoriser).
template <typename Real, typename OpReal, typename Store>
LBL_HOSTDEV LBL_FORCEINLINE void collide_node(const CollisionOp<OpReal>& op, Real f0_keep, Real rho,
                                              const Real (&f)[d3q19::kQ], Store&& store) {
  if (op.is_cubic) collide_cubic(op, f0_keep, rho, f, store);
  else collide_pairs(op, f0_keep, rho, f, store);
}

}  // namespace lblight
