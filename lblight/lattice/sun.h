// Sun decomposition on the 32-face polyhedron of the 18 unit lattice directions ([Steele2009] sec. 4.1,
// docs/model.md sec. 4): a direction is written as barycentric weights on the three lattice directions of
// the face its ray hits.
#pragma once

#include <array>
#include <vector>

namespace lblight {

struct Vec3d {
  double x = 0, y = 0, z = 0;
};

// Weights below this are rounding residue and set to 0 (the .lbh reader does the same).
inline constexpr double kNegligibleSunWeight = 1e-9;

struct SunWeights {
  std::array<int, 3> direction{};  // lattice directions a, b, c (1..18)
  std::array<double, 3> weight{};  // barycentric weights, >= 0, summing to 1
};

// The 32 triangular faces as triples of direction indices (1..18), outward-oriented.
const std::vector<std::array<int, 3>>& polyhedron_faces();

// Weights for light travelling along d (need not be unit length, must be non-zero).
SunWeights decompose_direction(const Vec3d& travel);

// Unit vector pointing toward the sun: elevation 90 = zenith (+z), azimuth 0 = +x, 90 = +y.
Vec3d toward_sun_from_angles(double elevation_deg, double azimuth_deg);

// Boundary values of a static bake: f_i = s * (w_a d_ia + w_b d_ib + w_c d_ic) + a, i = 0..18.
std::array<double, 19> static_boundary(const SunWeights& sun, double intensity, double ambient);

// Boundary values of base solution j: ambient (all ones) for j = 0, delta_ij otherwise.
std::array<double, 19> base_boundary(int solution);

}  // namespace lblight
