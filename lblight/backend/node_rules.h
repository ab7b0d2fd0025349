// The per-node rules every backend follows besides the collision (lattice/collide.h): what the
// boundary feeds, what a node stores as its total, and what an interior node contributes to
// measure(). Written once as LBL_HOSTDEV functions over plain values, as collide.h is; each
// backend supplies only the loop and its own memory layout around them (docs/architecture.md,
// "Streaming": the CPU pulls, the GPU pushes).
#pragma once

#include <array>
#include <cmath>

#include "lblight/backend/backend.h"
#include "lblight/core/hostdev.h"
#include "lblight/lattice/collide.h"
#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/lattice.h"

namespace lblight {

// ---------------------------------------------------------------------------------------------
// Boundary (docs/model.md sec. 4). Boundary nodes have density 0 (margin >= 1), so what they push
// into the lattice every step is their fixed value: interior node q receives f_m(q) =
// boundary_m whenever q - c_m is a boundary node, and nothing else ever writes that entry.
// A push backend stores those "inflow" entries once and updates interior nodes only; a pull
// backend keeps the boundary nodes' own values fixed and gathers from them.

// True when interior node (x, y, z) takes direction m from a boundary node.
LBL_HOSTDEV inline bool fed_by_boundary(const Dims& d, int x, int y, int z, int m) {
  return m != 0 && d.is_boundary(x - d3q19::cx(m), y - d3q19::cy(m), z - d3q19::cz(m));
}

// What a boundary node's stored total (sum_m f_m) is: its fixed values added in double and
// rounded once by the caller, so every backend and storage precision stores the same number.
inline double boundary_total(const std::array<double, 19>& boundary) {
  double t = 0.0;
  for (double v : boundary) t += v;
  return t;
}

// A node's total at t = 0 (reset): the boundary's fixed total, 0 on the interior.
template <typename Real>
LBL_HOSTDEV inline Real initial_total(const Dims& d, int x, int y, int z, Real boundary_total) {
  return d.is_boundary(x, y, z) ? boundary_total : Real(0);
}

// 0 for a material that dumps f_0 each step (absorb_bits: bit k set when material k absorbs), 1
// for one that keeps it: the factor collide_node takes.
template <typename Real>
LBL_HOSTDEV inline Real f0_keep(unsigned absorb_bits, unsigned material) {
  return ((absorb_bits >> material) & 1u) ? Real(0) : Real(1);
}

// ---------------------------------------------------------------------------------------------
// measure(): per interior node, its new total, the change since the last measure and, on nodes
// that keep f_0, the reservoir deficit (Residual::deficit_sq); then sums and maxima over nodes.

struct NodeResidual {
  double total = 0, diff = 0, deficit = 0;
};

// f: the node's state (its 19 values a step starts from), in the backend's arithmetic type.
// Stores the new total in `total`; `previous` is the total as of the last measure.
template <typename Real, typename OpReal>
LBL_HOSTDEV LBL_FORCEINLINE NodeResidual node_residual(const CollisionOp<OpReal>& op, bool keeps_f0, float rho,
                                                       const Real (&f)[d3q19::kQ], Real previous, Real& total) {
  // sum_m (1 + rho total_gain_m) f_m: the papers' sum_m f_m when the gains are 0 (x 1 exactly).
  Real t = f[0];
  LBL_UNROLL
  for (int m = 1; m < d3q19::kQ; ++m)
    t += f[m] * (Real(1) + static_cast<Real>(rho) * static_cast<Real>(op.total_gain[(m - 1) / 2]));
  total = t;
  NodeResidual r;
  r.total = static_cast<double>(t);
  r.diff = static_cast<double>(t) - static_cast<double>(previous);
  if (rho > 0.0f && keeps_f0) r.deficit = static_cast<double>(f0_deficit(op, f));
  return r;
}

// The seven numbers measure() reduces per system: sums first, then maxima and a non-finite flag.
enum ReduceSlot { kDiffSq, kTotalSq, kDeficitSq, kDiffMax, kTotalMax, kDeficitMax, kNonFinite, kReduceSlots };

LBL_HOSTDEV inline void accumulate(double (&acc)[kReduceSlots], const NodeResidual& r) {
  acc[kDiffSq] += r.diff * r.diff;
  acc[kTotalSq] += r.total * r.total;
  acc[kDeficitSq] += r.deficit * r.deficit;
  const double ad = r.diff < 0 ? -r.diff : r.diff, at = r.total < 0 ? -r.total : r.total;
  const double af = r.deficit < 0 ? -r.deficit : r.deficit;
  acc[kDiffMax] = acc[kDiffMax] > ad ? acc[kDiffMax] : ad;
  acc[kTotalMax] = acc[kTotalMax] > at ? acc[kTotalMax] : at;
  acc[kDeficitMax] = acc[kDeficitMax] > af ? acc[kDeficitMax] : af;
  // r.total - r.total is 0 for finite values and NaN otherwise
  if (!(r.total - r.total == 0.0)) acc[kNonFinite] = 1.0;
}

// acc += other, slot by slot. Backends combine partial results in a fixed order (rows on the
// CPU, blocks on the GPU), so the sums do not depend on the thread count.
LBL_HOSTDEV inline void combine(double (&acc)[kReduceSlots], const double* other) {
  for (int k = 0; k < kDiffMax; ++k) acc[k] += other[k];
  for (int k = kDiffMax; k < kReduceSlots; ++k) acc[k] = acc[k] > other[k] ? acc[k] : other[k];
}

inline Residual to_residual(const double* v) {
  Residual r;
  r.diff_sq = v[kDiffSq];
  r.total_sq = v[kTotalSq];
  r.deficit_sq = v[kDeficitSq];
  r.diff_max = v[kDiffMax];
  r.total_max = v[kTotalMax];
  r.deficit_max = v[kDeficitMax];
  r.finite = v[kNonFinite] == 0.0 && std::isfinite(v[kTotalSq]);
  return r;
}

}  // namespace lblight
