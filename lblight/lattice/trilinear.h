// Trilinear weights of a point in a dense box of nodes: what sampling a grid between its nodes
// reads (relight) and what depositing a point's value into a grid spreads (the coarse forest).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>

#include "lblight/lattice/lattice.h"

namespace lblight {

// The 8 nodes around index-space point u (node (i, j, k) at (i, j, k)) and their weights, which
// sum to 1; a point outside the box is clamped to it.
struct Trilinear {
  std::size_t index[8];
  double weight[8];
  Trilinear(const Dims& d, const std::array<double, 3>& u) {
    int lo[3];
    double f[3];
    const int n[3] = {d.nx, d.ny, d.nz};
    for (int a = 0; a < 3; ++a) {
      const double v = std::clamp(u[a], 0.0, static_cast<double>(n[a] - 1));
      lo[a] = std::min(static_cast<int>(std::floor(v)), n[a] - 2 < 0 ? 0 : n[a] - 2);
      f[a] = v - lo[a];
    }
    for (int c = 0; c < 8; ++c) {
      const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
      index[c] = d.index(std::min(lo[0] + dx, n[0] - 1), std::min(lo[1] + dy, n[1] - 1), std::min(lo[2] + dz, n[2] - 1));
      weight[c] = (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]);
    }
  }
  template <typename V>
  double operator()(const V& v) const {
    double s = 0;
    for (int c = 0; c < 8; ++c) s += weight[c] * v[index[c]];
    return s;
  }
};

}  // namespace lblight
