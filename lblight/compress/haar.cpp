#include "lblight/compress/haar.h"

#include <algorithm>
#include <cmath>

namespace lblight::haar {

void gather_block(const std::array<const float*, 3>& rgb, const Dims& d, int bx, int by, int bz, Block& out) {
  int xs[4], ys[4], zs[4];
  for (int t = 0; t < 4; ++t) {
    xs[t] = std::min(3 * bx + t, d.nx - 1);
    ys[t] = std::min(3 * by + t, d.ny - 1);
    zs[t] = std::min(3 * bz + t, d.nz - 1);
  }
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 4; ++y) {
      const std::size_t row = d.index(0, ys[y], zs[z]);
      for (int x = 0; x < 4; ++x)
        for (int c = 0; c < 3; ++c) out[c][x + 4 * y + 16 * z] = rgb[c][row + xs[x]];
    }
}

void forward(Block& b) {
  for (auto& ch : b) haar_forward_block(ch.data());
}

std::uint64_t keep_mask(const Block& c, float t) {
  std::uint64_t mask = 1u;
  for (int l = 1; l < 64; ++l) {
    bool drop = true;
    for (int k = 0; k < 3 && drop; ++k) {
      const float v = c[k][l];
      drop = v == 0.0f || std::fabs(v) < t;
    }
    if (!drop) mask |= std::uint64_t{1} << l;
  }
  return mask;
}

void dropped_errors(const Block& c, std::uint64_t mask, float* drop) {
  for (int l = 0; l < 64; ++l) {
    float m = 0.0f;
    if (!(mask >> l & 1u))
      for (int k = 0; k < 3; ++k) m = std::max(m, std::fabs(c[k][l]));
    drop[l] = m;
  }
}

float dropped_path_bound(const Block& c, std::uint64_t mask) {
  float drop[64];
  dropped_errors(c, mask, drop);
  return path_error_bound(drop);
}

float path_error_bound(const float* drop) {
  // Frequencies on the path of position p along one axis: 0, 1 and 2 + p / 2.
  float worst = 0.0f;
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 4; ++x) {
        const int fx[3] = {0, 1, 2 + x / 2}, fy[3] = {0, 1, 2 + y / 2}, fz[3] = {0, 1, 2 + z / 2};
        float sum = 0.0f;
        for (int a : fz)
          for (int b : fy)
            for (int e : fx) sum += drop[e + 4 * b + 16 * a];
        worst = std::max(worst, sum);
      }
  return worst;
}

}  // namespace lblight::haar
