#include "lblight/lattice/sun.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "lblight/lattice/d3q19.h"

namespace lblight {

using namespace d3q19;

namespace {
Vec3d unit_dir(int m) {
  const double len = std::sqrt(static_cast<double>(length_sq(m)));
  return {cx(m) / len, cy(m) / len, cz(m) / len};
}
Vec3d sub(Vec3d a, Vec3d b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3d cross(Vec3d a, Vec3d b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
double dot(Vec3d a, Vec3d b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// Convex hull of the 18 unit directions by brute force: a triple is a face when every other
// point lies strictly inside its plane. No four of these points are coplanar on the hull, so the
// result is exactly the 32 triangles (8 at the cube corners, 4 around each axial vertex).
std::vector<std::array<int, 3>> compute_faces() {
  std::vector<std::array<int, 3>> faces;
  for (int a = 1; a < kQ; ++a)
    for (int b = a + 1; b < kQ; ++b)
      for (int c = b + 1; c < kQ; ++c) {
        const Vec3d pa = unit_dir(a), pb = unit_dir(b), pc = unit_dir(c);
        Vec3d n = cross(sub(pb, pa), sub(pc, pa));
        if (dot(n, n) < 1e-12) continue;
        if (dot(n, pa) < 0) n = {-n.x, -n.y, -n.z};
        const double d = dot(n, pa);
        bool hull = d > 1e-12;
        for (int o = 1; o < kQ && hull; ++o) {
          if (o == a || o == b || o == c) continue;
          if (dot(n, unit_dir(o)) >= d - 1e-12) hull = false;
        }
        if (!hull) continue;
        // orient counter-clockwise seen from outside
        if (dot(cross(sub(pb, pa), sub(pc, pa)), pa) < 0) faces.push_back({a, c, b});
        else faces.push_back({a, b, c});
      }
  if (faces.size() != 32) throw std::logic_error("lattice polyhedron does not have 32 faces");
  return faces;
}
}  // namespace

const std::vector<std::array<int, 3>>& polyhedron_faces() {
  static const std::vector<std::array<int, 3>> faces = compute_faces();
  return faces;
}

SunWeights decompose_direction(const Vec3d& d) {
  if (!(std::isfinite(d.x) && std::isfinite(d.y) && std::isfinite(d.z)) || dot(d, d) == 0.0)
    throw std::invalid_argument("sun direction must be a finite, non-zero vector");
  // Solve d = alpha n_a + beta n_b + gamma n_c; the face whose coefficients are all >= 0 is the
  // one the ray hits, and the normalised coefficients are the barycentric weights of the hit.
  SunWeights best;
  double best_min = -1e300;
  for (const auto& f : polyhedron_faces()) {
    const Vec3d a = unit_dir(f[0]), b = unit_dir(f[1]), c = unit_dir(f[2]);
    const double det = dot(a, cross(b, c));
    const double alpha = dot(d, cross(b, c)) / det;
    const double beta = dot(a, cross(d, c)) / det;
    const double gamma = dot(a, cross(b, d)) / det;
    const double lo = std::min(alpha, std::min(beta, gamma));
    // Keep the face with the largest smallest coefficient: exact ties on shared edges pick one
    // face deterministically, and rounding can never leave us without a face.
    if (lo > best_min + 1e-15) {
      best_min = lo;
      const double sum = alpha + beta + gamma;
      best.direction = f;
      best.weight = {std::max(0.0, alpha / sum), std::max(0.0, beta / sum), std::max(0.0, gamma / sum)};
    }
  }
  // A weight left by rounding (a sun along a lattice direction or face edge: 1e-17) is 0, so
  // that it asks for no base solution; kNegligibleSunWeight is far below float precision.
  for (double& w : best.weight)
    if (w < kNegligibleSunWeight) w = 0.0;
  const double s = best.weight[0] + best.weight[1] + best.weight[2];
  for (double& w : best.weight) w /= s;
  return best;
}

namespace {
// sin and cos of an angle in degrees, exact at multiples of 90: in radians cos(90 deg) is 6e-17,
// which gives a zenith sun a 1e-16 weight on a second direction (one more base solution to bake).
void sincos_deg(double deg, double& s, double& c) {
  double r = std::fmod(deg, 360.0);
  if (r < 0) r += 360.0;
  if (r == 0.0 || r == 90.0 || r == 180.0 || r == 270.0) {
    const int q = static_cast<int>(r) / 90;
    s = q == 1 ? 1.0 : q == 3 ? -1.0 : 0.0;
    c = q == 0 ? 1.0 : q == 2 ? -1.0 : 0.0;
    return;
  }
  const double rad = deg * (3.14159265358979323846 / 180.0);
  s = std::sin(rad);
  c = std::cos(rad);
}
}  // namespace

Vec3d toward_sun_from_angles(double elevation_deg, double azimuth_deg) {
  double se, ce, sa, ca;
  sincos_deg(elevation_deg, se, ce);
  sincos_deg(azimuth_deg, sa, ca);
  return {ce * ca, ce * sa, se};
}

std::array<double, 19> static_boundary(const SunWeights& sun, double intensity, double ambient) {
  std::array<double, 19> f{};
  f.fill(ambient);
  for (int k = 0; k < 3; ++k) f[sun.direction[k]] += intensity * sun.weight[k];
  return f;
}

std::array<double, 19> base_boundary(int solution) {
  std::array<double, 19> f{};
  if (solution == 0) f.fill(1.0);
  else f[solution] = 1.0;
  return f;
}

}  // namespace lblight
