#include "lblight/lattice/dense_grid.h"

#include <cmath>

namespace lblight {

void check_index_box(const std::array<std::int64_t, 3>& lo, const std::array<std::int64_t, 3>& hi,
                     const std::string& what, const Location& where) {
  const auto box = [&] {
    std::string s;
    for (int a = 0; a < 3; ++a) s += (a ? ", " : "") + std::to_string(lo[a]) + ".." + std::to_string(hi[a]);
    return "(" + s + ")";
  };
  for (int a = 0; a < 3; ++a) {
    if (hi[a] < lo[a]) throw_invalid(what + " is empty " + box(), where);
    if (lo[a] < -kMaxIndexCoord || hi[a] > kMaxIndexCoord)
      throw_invalid(what + " lies too far out: it spans index coordinates " + box() + "; allowed: within -" +
                        std::to_string(kMaxIndexCoord) + ".." + std::to_string(kMaxIndexCoord),
                    where);
    if (hi[a] - lo[a] + 1 > kMaxNodesPerAxis)
      throw_invalid(what + " is too large: it spans " + std::to_string(hi[a] - lo[a] + 1) + " nodes along axis " +
                        "xyz"[a] + " " + box() + "; allowed: at most " + std::to_string(kMaxNodesPerAxis) +
                        " (a dense lattice that size does not fit in memory)",
                    where);
  }
}

void DenseFrame::check(const std::string& what, const Location& where) const {
  const int n[3] = {dims.nx, dims.ny, dims.nz};
  std::array<std::int64_t, 3> lo{}, hi{};
  for (int a = 0; a < 3; ++a) {
    lo[a] = index_min[a];
    hi[a] = static_cast<std::int64_t>(index_min[a]) + n[a] - 1;
  }
  check_index_box(lo, hi, what, where);
}

std::size_t ModelGrid::wood_nodes() const {
  std::size_t n = 0;
  for (std::size_t i = 0; i < material.size(); ++i) n += (material[i] == kMaterialWood && density[i] > 0.0f);
  return n;
}

std::size_t ModelGrid::occupied_nodes() const {
  std::size_t n = 0;
  for (float d : density) n += d > 0.0f;
  return n;
}

std::array<double, 3> ModelGrid::voxel_size() const {
  std::array<double, 3> s{};
  for (int c = 0; c < 3; ++c) {
    const double a = index_to_world[0 * 4 + c], b = index_to_world[1 * 4 + c], d = index_to_world[2 * 4 + c];
    s[c] = std::sqrt(a * a + b * b + d * d);
  }
  return s;
}

std::vector<std::uint8_t> near_medium(const Dims& d, const std::vector<float>& density, int rings, bool outer_layer) {
  std::vector<std::uint8_t> mask(d.count(), 0);
  for (std::size_t i = 0; i < mask.size(); ++i) mask[i] = density[i] > 0.0f;
  const int e = outer_layer ? 0 : 1;
  for (int r = 0; r < rings; ++r) {
    std::vector<std::uint8_t> grown(mask.size(), 0);
    for (int z = e; z < d.nz - e; ++z)
      for (int y = e; y < d.ny - e; ++y)
        for (int x = e; x < d.nx - e; ++x) {
          bool near = false;
          for (int dz = -1; dz <= 1 && !near; ++dz)
            for (int dy = -1; dy <= 1 && !near; ++dy)
              for (int dx = -1; dx <= 1 && !near; ++dx) {
                const int i = x + dx, j = y + dy, k = z + dz;
                near = i >= 0 && j >= 0 && k >= 0 && i < d.nx && j < d.ny && k < d.nz && mask[d.index(i, j, k)] != 0;
              }
          grown[d.index(x, y, z)] = near;
        }
    mask.swap(grown);
  }
  return mask;
}

}  // namespace lblight
