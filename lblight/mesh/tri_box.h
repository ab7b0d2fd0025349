// Exact triangle / axis-aligned box overlap by the separating axis theorem (Akenine-Moller,
// "Fast 3D triangle-box overlap testing", 2001): 3 box normals, the triangle normal and the 9
// cross products of box axes with triangle edges. Boxes are closed: touching counts as overlap.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

namespace lblight {

using Vec3 = std::array<double, 3>;

inline Vec3 sub3(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline Vec3 cross3(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline double dot3(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// True when triangle (a, b, c) and the box centre +- half overlap (boundaries included).
inline bool triangle_box_overlap(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& centre, const Vec3& half) {
  const Vec3 v[3] = {sub3(a, centre), sub3(b, centre), sub3(c, centre)};
  // Box normals: the triangle's bounding box against the box.
  for (int i = 0; i < 3; ++i) {
    const double lo = std::min({v[0][i], v[1][i], v[2][i]}), hi = std::max({v[0][i], v[1][i], v[2][i]});
    if (lo > half[i] || hi < -half[i]) return false;
  }
  const Vec3 e[3] = {sub3(v[1], v[0]), sub3(v[2], v[1]), sub3(v[0], v[2])};
  auto separated = [&](const Vec3& axis) {
    const double p0 = dot3(axis, v[0]), p1 = dot3(axis, v[1]), p2 = dot3(axis, v[2]);
    const double r = half[0] * std::abs(axis[0]) + half[1] * std::abs(axis[1]) + half[2] * std::abs(axis[2]);
    return std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r;
  };
  // Triangle normal: the plane against the box.
  if (separated(cross3(e[0], e[1]))) return false;
  // Box axis x edge.
  for (const Vec3& ed : e) {
    if (separated({0.0, -ed[2], ed[1]})) return false;
    if (separated({ed[2], 0.0, -ed[0]})) return false;
    if (separated({-ed[1], ed[0], 0.0})) return false;
  }
  return true;
}

}  // namespace lblight
