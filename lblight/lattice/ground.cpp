#include "lblight/lattice/ground.h"

namespace lblight {

using d3q19::kQ;

std::array<double, kQ> ground_share(const std::array<double, kQ>& ambient) {
  std::array<double, kQ> u{};
  double sum = 0;
  for (int m = 1; m < kQ; ++m)
    if (upward(m)) sum += ambient[m];
  for (int m = 1; m < kQ; ++m)
    if (upward(m)) u[m] = sum > 0 ? ambient[m] / sum : 0.2;
  return u;
}

OmegaMatrix ground_omega(double albedo, const std::array<double, kQ>& share) {
  OmegaMatrix o{};
  for (int m = 0; m < kQ; ++m) o[m * kQ + m] = -1.0;  // nothing passes, f_0 included
  for (int m = 1; m < kQ; ++m)
    for (int n = 1; n < kQ; ++n) {
      if (upward(m) && downward(n)) o[m * kQ + n] += albedo * share[m];
      // the mirror image, which central symmetry asks for: from below back down
      if (downward(m) && upward(n)) o[m * kQ + n] += albedo * share[d3q19::opposite(m)];
    }
  return o;
}

std::array<double, kQ> with_open_ground(const std::array<double, kQ>& source, double albedo,
                                        const std::array<double, kQ>& share) {
  double down = 0;
  for (int n = 1; n < kQ; ++n)
    if (downward(n)) down += source[n];
  std::array<double, kQ> b = source;
  for (int m = 1; m < kQ; ++m)
    if (upward(m)) b[m] = albedo * share[m] * down;  // the ground hides the source's light from below
  return b;
}

}  // namespace lblight
