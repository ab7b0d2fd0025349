// Where light can be yet, row by row, so that the CPU sweep skips what is exactly dark.
//
// After reset the interior is 0 and light enters only through the faces whose fixed values point
// inwards; the LB step moves it at most one node per step (c_m has components -1, 0, 1). So a
// row of a step's output can be nonzero only within one node along x of where its 3 x 3
// neighbouring rows (y +- 1, z +- 1) of the step's input were nonzero, plus where a lit face
// feeds it. Outside that span a node's inputs are all 0 and its collision gives 0: skipping it
// leaves the 0 already stored, the same bits as computing it. A directional solution spends its
// first crossing of the lattice (about N of the paper's 2N steps) with part of the lattice dark.
//
// Spans only grow (each includes the row's own span of the step before, widened), and a state of
// unknown content (written, added to, a slab's ghost layers) makes every row lit.
#pragma once

#include <algorithm>
#include <array>
#include <limits>
#include <vector>

#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/lattice.h"

namespace lblight {

// Interior nodes lo..hi of one row (empty when lo > hi).
struct Span {
  int lo = 1, hi = 0;
  bool empty() const { return lo > hi; }
  void include(int a, int b) {
    if (empty()) {
      lo = a;
      hi = b;
    } else {
      lo = std::min(lo, a);
      hi = std::max(hi, b);
    }
  }
};

// Every node of every row (sweeps of Krylov vectors, whose content is arbitrary).
struct WholeRows {
  Span operator()(int, int) const { return {1, std::numeric_limits<int>::max()}; }
};

class LitSpans {
 public:
  // Both time levels dark; the faces lit by `boundary` (fixed values f_m of the boundary nodes).
  void reset(const Dims& d, const std::array<double, d3q19::kQ>& boundary) {
    d_ = d;
    all_ = false;
    feed_ = {};
    for (int m = 1; m < d3q19::kQ; ++m) {
      if (boundary[static_cast<std::size_t>(m)] == 0.0) continue;
      // a face node feeds the interior along c_m when c_m points away from its face
      if (d3q19::cx(m) == 1) feed_[0] = true;
      if (d3q19::cx(m) == -1) feed_[1] = true;
      if (d3q19::cy(m) == 1) feed_[2] = true;
      if (d3q19::cy(m) == -1) feed_[3] = true;
      if (d3q19::cz(m) == 1) feed_[4] = true;
      if (d3q19::cz(m) == -1) feed_[5] = true;
    }
    for (auto& level : spans_) level.assign(static_cast<std::size_t>(d.ny - 2) * (d.nz - 2), Span{});
  }

  // Every node may hold light from now on (until the next reset).
  void light_all() { all_ = true; }

  // The span of row (y, z) in the output of a step that reads level `from` and writes the other
  // level, recorded for that level. Rows of one step may run in parallel: each writes its own
  // entry of the output level and reads only the input level's.
  Span advance(int from, int y, int z) {
    if (all_) return WholeRows{}(y, z);
    const Span full{1, d_.nx - 2};
    Span s;
    if ((y == 1 && feed_[2]) || (y == d_.ny - 2 && feed_[3]) || (z == 1 && feed_[4]) || (z == d_.nz - 2 && feed_[5])) {
      s = full;
    } else {
      const std::vector<Span>& in = spans_[static_cast<std::size_t>(from)];
      for (int zz = std::max(1, z - 1); zz <= std::min(d_.nz - 2, z + 1); ++zz)
        for (int yy = std::max(1, y - 1); yy <= std::min(d_.ny - 2, y + 1); ++yy) {
          const Span& n = in[row(yy, zz)];
          if (!n.empty()) s.include(std::max(1, n.lo - 1), std::min(d_.nx - 2, n.hi + 1));
        }
      if (feed_[0]) s.include(1, 1);
      if (feed_[1]) s.include(d_.nx - 2, d_.nx - 2);
    }
    Span& out = spans_[static_cast<std::size_t>(1 - from)][row(y, z)];
    // what the level held before (two steps ago) must be overwritten too: never shrink
    if (!out.empty()) s.include(out.lo, out.hi);
    out = s;
    return s;
  }

 private:
  std::size_t row(int y, int z) const {
    return static_cast<std::size_t>(z - 1) * static_cast<std::size_t>(d_.ny - 2) + static_cast<std::size_t>(y - 1);
  }

  Dims d_;
  bool all_ = true;
  std::array<bool, 6> feed_{};  // faces x = 0, x = nx - 1, y = 0, y = ny - 1, z = 0, z = nz - 1
  std::array<std::vector<Span>, 2> spans_;  // per time level, per interior row
};

}  // namespace lblight
