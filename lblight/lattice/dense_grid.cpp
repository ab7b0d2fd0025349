#include "lblight/lattice/dense_grid.h"

#include <cmath>

namespace lblight {

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

}  // namespace lblight
