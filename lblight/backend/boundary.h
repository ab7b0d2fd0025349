// Boundary handling shared by backends. Boundary nodes have density 0 (margin >= 1), so what
// they push into the lattice every step is their fixed value: interior node q receives
// f_m(q) = boundary_m whenever q - c_m is a boundary node, and nobody else ever writes that
// entry. Backends therefore store those "inflow" entries once and only update interior nodes.
#pragma once

#include <array>

#include "lblight/core/hostdev.h"
#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/lattice.h"

namespace lblight {

// True when interior node (x, y, z) takes direction m from a boundary node.
LBL_HOSTDEV inline bool fed_by_boundary(const Dims& d, int x, int y, int z, int m) {
  return m != 0 && d.is_boundary(x - d3q19::cx(m), y - d3q19::cy(m), z - d3q19::cz(m));
}

// Linear offset of the neighbour p + c_m.
LBL_HOSTDEV inline long long neighbour_offset(const Dims& d, int m) {
  return static_cast<long long>(d3q19::cx(m)) +
         static_cast<long long>(d3q19::cy(m)) * d.nx +
         static_cast<long long>(d3q19::cz(m)) * static_cast<long long>(d.nx) * d.ny;
}

// What a boundary node's stored total (sum_m f_m) is: its fixed values added in double and
// rounded once by the caller, so every backend and storage precision stores the same number.
inline double boundary_total(const std::array<double, 19>& boundary) {
  double t = 0.0;
  for (double v : boundary) t += v;
  return t;
}

}  // namespace lblight
