// Lattice dimensions and the linear node index shared by every backend.
// Layout: x varies fastest, then y, then z ("structure of arrays": one array per direction,
// each node-contiguous along x, which is what SIMD lanes on the CPU and GPU warps walk).
#pragma once

#include <cstddef>
#include <cstdint>

#include "lblight/core/hostdev.h"

namespace lblight {

struct Dims {
  int nx = 0, ny = 0, nz = 0;

  LBL_HOSTDEV std::size_t count() const {
    return static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny) * static_cast<std::size_t>(nz);
  }
  LBL_HOSTDEV std::size_t index(int x, int y, int z) const {
    return (static_cast<std::size_t>(z) * static_cast<std::size_t>(ny) + static_cast<std::size_t>(y)) *
               static_cast<std::size_t>(nx) +
           static_cast<std::size_t>(x);
  }
  // Boundary nodes are the outermost layer (docs/model.md sec. 4).
  LBL_HOSTDEV bool is_boundary(int x, int y, int z) const {
    return x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1;
  }
  LBL_HOSTDEV int longest() const {
    int m = nx > ny ? nx : ny;
    return m > nz ? m : nz;
  }
  std::size_t interior_count() const {
    if (nx < 3 || ny < 3 || nz < 3) return 0;
    return static_cast<std::size_t>(nx - 2) * static_cast<std::size_t>(ny - 2) * static_cast<std::size_t>(nz - 2);
  }
  bool operator==(const Dims& o) const { return nx == o.nx && ny == o.ny && nz == o.nz; }
  bool operator!=(const Dims& o) const { return !(*this == o); }
};

}  // namespace lblight
