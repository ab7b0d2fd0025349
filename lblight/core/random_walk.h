// What lblight's two Monte Carlo tracers share (the fluence reference, reference/montecarlo.h, and
// the path-traced picture, render/path_trace.h): counter-based random numbers, so that a path's
// numbers depend on nothing but its own counter (results identical for any thread count), and
// Henyey-Greenstein direction sampling.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace lblight {

// SplitMix64's finaliser.
inline std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// SplitMix64's Weyl sequence, seeded from (seed, stream, counter).
struct CounterRng {
  std::uint64_t state;
  CounterRng(std::uint64_t seed, std::uint64_t stream, std::uint64_t counter)
      : state(mix64(mix64(mix64(seed) ^ stream) ^ counter)) {}
  double uniform() {  // in (0, 1]
    state += 0x9E3779B97F4A7C15ull;
    return (static_cast<double>(mix64(state) >> 11) + 1.0) * 0x1.0p-53;
  }
};

// Henyey-Greenstein: a new unit direction at cos(theta) from the unit direction d with the HG
// distribution of g, from two uniform numbers.
inline std::array<double, 3> scatter_hg(const std::array<double, 3>& d, double g, double u1, double u2) {
  constexpr double kTwoPi = 6.28318530717958647692;
  double c;
  if (std::abs(g) < 1e-6) {
    c = 1.0 - 2.0 * u1;
  } else {
    const double s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1);
    c = (1.0 + g * g - s * s) / (2.0 * g);
  }
  c = std::clamp(c, -1.0, 1.0);
  const double sn = std::sqrt(std::max(0.0, 1.0 - c * c));
  const double phi = kTwoPi * u2;
  // Orthonormal basis around d (Duff et al. 2017).
  const double sign = std::copysign(1.0, d[2]);
  const double a = -1.0 / (sign + d[2]);
  const double b = d[0] * d[1] * a;
  const std::array<double, 3> t1{1.0 + sign * d[0] * d[0] * a, sign * b, -sign * d[0]};
  const std::array<double, 3> t2{b, sign + d[1] * d[1] * a, -d[1]};
  std::array<double, 3> n;
  for (int k = 0; k < 3; ++k) n[k] = sn * (std::cos(phi) * t1[k] + std::sin(phi) * t2[k]) + c * d[k];
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (double& x : n) x /= len;
  return n;
}

}  // namespace lblight
