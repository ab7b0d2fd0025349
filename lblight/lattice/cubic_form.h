// Omega in the cube's symmetry-adapted coordinates (docs/model.md sec. 3, "Applying Omega").
//
// An isotropic material's Omega commutes with the 48 rotations and reflections of the lattice
// (the phase function depends only on the angle between two directions; weights, path lengths
// and normalisations only on a direction's orbit, axis or diagonal). By Schur's lemma it is then
// block diagonal in coordinates that transform like the group's irreducible representations:
//   the three invariant sums (f_0, the axis pairs, the diagonal pairs): a 3 x 3 block;
//   the two-dimensional even modes (like x^2 - y^2 and x^2 + y^2 - 2 z^2), once over the axis
//     pairs and once over the diagonal pairs (a diagonal plane stands for the axis normal to it):
//     a 2 x 2 block for each of the two components;
//   the even modes of the diagonal pairs within a plane (like xy): one number;
//   the vectors (sum of c_m f_m), over the axis and over the diagonal directions: a 2 x 2 block,
//     the same for x, y and z;
//   the odd modes of the diagonals (like x (y^2 - z^2)): one number.
// 23 coefficients instead of the even/odd form's 171, and the coordinates are sums and
// differences: about half the arithmetic and few enough constants to stay in registers.
// Input coordinates c and output coordinates C share one layout:
//   0 f_0 / (Omega f)_0, 1 axis sum, 2 diagonal sum,
//   3, 4  x^2 - y^2 mode (axis, diagonal), 5, 6  x^2 + y^2 - 2 z^2 mode (axis, diagonal),
//   7, 8, 9  diagonal xy, xz, yz modes,
//   10..12 axis vector, 13..15 diagonal vector, 16..18 diagonal odd modes (x, y, z).
// Pairs k = 0..8 are x, y, z, (1,1,0), (1,-1,0), (1,0,1), (1,0,-1), (0,1,1), (0,1,-1) (d3q19.h).
#pragma once

#include "lblight/core/hostdev.h"
#include "lblight/lattice/collision_op.h"  // kCubicCoeffs

namespace lblight {

inline constexpr int kCubicCoords = 19;

// c from f_0 and the pair sums e and differences o (collide.h, split_pairs).
template <typename Real>
LBL_HOSTDEV LBL_FORCEINLINE void cubic_coords(Real f0, const Real (&e)[9], const Real (&o)[9], Real (&c)[kCubicCoords]) {
  const Real sxy = e[3] + e[4], sxz = e[5] + e[6], syz = e[7] + e[8];
  c[0] = f0;
  c[1] = e[0] + e[1] + e[2];
  c[2] = sxy + sxz + syz;
  c[3] = e[0] - e[1];
  c[4] = syz - sxz;  // the yz plane stands for x, the xz plane for y, the xy plane for z
  c[5] = e[0] + e[1] - Real(2) * e[2];
  c[6] = syz + sxz - Real(2) * sxy;
  c[7] = e[3] - e[4];
  c[8] = e[5] - e[6];
  c[9] = e[7] - e[8];
  c[10] = o[0];
  c[11] = o[1];
  c[12] = o[2];
  const Real xy = o[3] + o[4], xz = o[5] + o[6], yz = o[7] + o[8];
  const Real ux = o[3] - o[4], uz = o[5] - o[6], vz = o[7] - o[8];
  c[13] = xy + xz;  // sum of c_x f over the diagonals
  c[14] = ux + yz;
  c[15] = uz + vz;
  c[16] = xy - xz;  // sum of c_x (c_y^2 - c_z^2) f, and its rotations
  c[17] = yz - ux;
  c[18] = uz - vz;
}

// C from c: the blocks, k the 23 coefficients (CollisionOp::cubic).
template <typename Real, typename OpReal>
LBL_HOSTDEV LBL_FORCEINLINE void cubic_blocks(const OpReal* k, const Real (&c)[kCubicCoords], Real (&C)[kCubicCoords]) {
#define LBL_K(i) static_cast<Real>(k[i])  // no local copy: a copied array stops GCC's vectoriser
  LBL_UNROLL
  for (int r = 0; r < 3; ++r) C[r] = LBL_K(3 * r) * c[0] + LBL_K(3 * r + 1) * c[1] + LBL_K(3 * r + 2) * c[2];
  C[3] = LBL_K(9) * c[3] + LBL_K(10) * c[4];
  C[4] = LBL_K(11) * c[3] + LBL_K(12) * c[4];
  C[5] = LBL_K(13) * c[5] + LBL_K(14) * c[6];
  C[6] = LBL_K(15) * c[5] + LBL_K(16) * c[6];
  LBL_UNROLL
  for (int i = 0; i < 3; ++i) {
    C[7 + i] = LBL_K(17) * c[7 + i];
    C[10 + i] = LBL_K(18) * c[10 + i] + LBL_K(19) * c[13 + i];
    C[13 + i] = LBL_K(20) * c[10 + i] + LBL_K(21) * c[13 + i];
    C[16 + i] = LBL_K(22) * c[16 + i];
  }
#undef LBL_K
}

// (Omega f)_0 and, per pair k, E_k and O_k ((Omega f)_a = E + O, (Omega f)_b = E - O) from C.
template <typename Real>
LBL_HOSTDEV LBL_FORCEINLINE void cubic_rows(const Real (&C)[kCubicCoords], Real& s0, Real (&E)[9], Real (&O)[9]) {
  s0 = C[0];
  E[0] = C[1] + C[3] + C[5];
  E[1] = C[1] - C[3] + C[5];
  E[2] = C[1] - Real(2) * C[5];
  const Real syz = C[2] + C[4] + C[6], sxz = C[2] - C[4] + C[6], sxy = C[2] - Real(2) * C[6];
  E[3] = sxy + C[7];
  E[4] = sxy - C[7];
  E[5] = sxz + C[8];
  E[6] = sxz - C[8];
  E[7] = syz + C[9];
  E[8] = syz - C[9];
  O[0] = C[10];
  O[1] = C[11];
  O[2] = C[12];
  const Real vx = C[13], vy = C[14], vz = C[15], wx = C[16], wy = C[17], wz = C[18];
  O[3] = vx + vy + wx - wy;
  O[4] = vx - vy + wx + wy;
  O[5] = vx + vz - wx + wz;
  O[6] = vx - vz - wx - wz;
  O[7] = vy + vz + wy - wz;
  O[8] = vy - vz + wy + wz;
}

}  // namespace lblight
