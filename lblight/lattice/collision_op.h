// Omega in the form the kernels apply it. Omega is centrally symmetric (entry (-m, -n) equals
// entry (m, n): the phase function depends only on n_m . n_n, and weights and normalisation
// are the same for c and -c). Splitting f over the 9 antipodal pairs (a_k, b_k) = (2k+1, 2k+2)
// into e_k = f_a + f_b and o_k = f_a - f_b turns the 19x19 product into two 9x9 products:
//   (Omega f)_a = col0 f_0 + even e + odd o,   (Omega f)_b = col0 f_0 + even e - odd o,
//   (Omega f)_0 = diag0 f_0 + row0 e.
// About 40% fewer operations than the dense product, the same result up to float rounding.
#pragma once

#include "lblight/core/hostdev.h"
#include "lblight/lattice/omega.h"

namespace lblight {

inline constexpr int kPairs = 9;
// Coefficients of the symmetry-adapted form (cubic_form.h): 9 + 4 + 4 + 1 + 4 + 1.
inline constexpr int kCubicCoeffs = 23;


template <typename T>
struct CollisionOp {
  T even[kPairs * kPairs];  // [m][k]: coefficient of e_k in row a_m
  T odd[kPairs * kPairs];   // [m][k]: coefficient of o_k in row a_m
  T col0[kPairs];           // Omega(a_m, 0)
  T row0[kPairs];           // Omega(0, a_k) (= Omega(0, b_k))
  T diag0;                  // Omega(0, 0)
  // A node's stored total is sum_m (1 + rho total_gain_m) f_m: 0 for the papers' total sum_m f_m;
  // half of Omega's column sums for the voxel average of the calibrated model (lb_model.h), the
  // mean of the light entering a node and leaving it after the collision.
  T total_gain[kPairs];     // per pair (a_m and b_m share their column sum)
  // The same Omega in the cube's symmetry-adapted coordinates (collide.h, collide_cubic), when it
  // commutes with the 48 rotations and reflections of the lattice (every isotropic material;
  // not the ground, whose operator has an up and a down): 23 coefficients instead of 171.
  T cubic[kCubicCoeffs];
  int is_cubic;             // 1: cubic holds Omega exactly (to 1e-12 relative), 0: use even/odd
};

// Throws std::invalid_argument if omega is not centrally symmetric (to 1e-12 relative).
// voxel_average: fill total_gain from the column sums (else 0). is_cubic is set where omega
// commutes with the lattice's symmetries (cubic_form.h), to 1e-12 of its largest entry.
CollisionOp<double> reduce_omega(const OmegaMatrix& omega, bool voxel_average = false);

template <typename T>
CollisionOp<T> convert_op(const CollisionOp<double>& op) {
  CollisionOp<T> out{};
  for (int i = 0; i < kPairs * kPairs; ++i) {
    out.even[i] = static_cast<T>(op.even[i]);
    out.odd[i] = static_cast<T>(op.odd[i]);
  }
  for (int i = 0; i < kPairs; ++i) {
    out.col0[i] = static_cast<T>(op.col0[i]);
    out.row0[i] = static_cast<T>(op.row0[i]);
    out.total_gain[i] = static_cast<T>(op.total_gain[i]);
  }
  out.diag0 = static_cast<T>(op.diag0);
  for (int i = 0; i < kCubicCoeffs; ++i) out.cubic[i] = static_cast<T>(op.cubic[i]);
  out.is_cubic = op.is_cubic;
  return out;
}

}  // namespace lblight
