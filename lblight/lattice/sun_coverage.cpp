#include "lblight/lattice/sun_coverage.h"

#include <algorithm>
#include <cmath>

#include "lblight/lattice/d3q19.h"

namespace lblight {
namespace {

constexpr double kRadToDeg = 57.295779513082320877;

Vec3d unit_dir(int m) {
  const double len = std::sqrt(static_cast<double>(d3q19::length_sq(m)));
  return {d3q19::cx(m) / len, d3q19::cy(m) / len, d3q19::cz(m) / len};
}

// Elevation of the sun whose light travels along d.
double sun_elevation_for_travel(const Vec3d& d) { return elevation_deg({-d.x, -d.y, -d.z}); }

// The range of sun elevations over which direction v gets a non-zero weight: the star of v on
// the polyhedron (the faces around it, without the edges opposite v). Sampled on a barycentric
// grid per face; the closed star's extremes are found to ~1e-5 degrees, and an extreme counts
// as reachable only when v itself attains it (elsewhere on the rim v's weight is 0).
// Computed once per direction (a few ms).
struct StarRange {
  double lo = 1e300, hi = -1e300;
  bool lo_at_vertex = false, hi_at_vertex = false;
};

StarRange star_range(int v) {
  constexpr int kN = 256;  // midpoints and vertices are grid points
  StarRange r;
  for (const auto& f : polyhedron_faces()) {
    const int slot = f[0] == v ? 0 : f[1] == v ? 1 : f[2] == v ? 2 : -1;
    if (slot < 0) continue;
    const Vec3d a = unit_dir(f[0]), b = unit_dir(f[1]), c = unit_dir(f[2]);
    for (int i = 0; i <= kN; ++i)
      for (int j = 0; i + j <= kN; ++j) {
        const double wa = static_cast<double>(i) / kN, wb = static_cast<double>(j) / kN, wc = 1.0 - wa - wb;
        const Vec3d p{wa * a.x + wb * b.x + wc * c.x, wa * a.y + wb * b.y + wc * c.y, wa * a.z + wb * b.z + wc * c.z};
        const double e = sun_elevation_for_travel(p);
        r.lo = std::min(r.lo, e);
        r.hi = std::max(r.hi, e);
      }
  }
  const double ev = sun_elevation_for_travel(unit_dir(v));
  constexpr double kTie = 1e-9;
  r.lo_at_vertex = ev <= r.lo + kTie;
  r.hi_at_vertex = ev >= r.hi - kTie;
  return r;
}

}  // namespace

double elevation_deg(const Vec3d& t) {
  const double len = std::sqrt(t.x * t.x + t.y * t.y + t.z * t.z);
  return std::asin(std::clamp(t.z / len, -1.0, 1.0)) * kRadToDeg;
}

std::array<bool, 19> needed_base_solutions(const SunConstraints& c) {
  std::array<bool, 19> need{};
  need[0] = c.ambient;
  if (c.rotation == InstanceRotation::Any) {
    for (int j = 1; j < 19; ++j) need[j] = true;
    return need;
  }
  if (c.fixed_toward_sun && c.rotation == InstanceRotation::None) {
    const Vec3d& t = *c.fixed_toward_sun;
    const SunWeights w = decompose_direction({-t.x, -t.y, -t.z});
    for (int k = 0; k < 3; ++k)
      if (w.weight[static_cast<std::size_t>(k)] > 0.0) need[static_cast<std::size_t>(w.direction[static_cast<std::size_t>(k)])] = true;
    return need;
  }
  // An elevation band, any azimuth (yaw rotation, or a fixed frame with only the band known).
  double e0 = c.min_elevation, e1 = c.max_elevation;
  if (c.fixed_toward_sun) e0 = e1 = elevation_deg(*c.fixed_toward_sun);
  constexpr double kEps = 1e-3;  // degrees; the sampled extremes are closer than that
  for (int j = 1; j < 19; ++j) {
    static const std::array<StarRange, 19> ranges = [] {
      std::array<StarRange, 19> a{};
      for (int v = 1; v < 19; ++v) a[static_cast<std::size_t>(v)] = star_range(v);
      return a;
    }();
    const StarRange& r = ranges[static_cast<std::size_t>(j)];
    const bool above_lo = r.hi > e0 + kEps || (r.hi_at_vertex && r.hi >= e0 - kEps);
    const bool below_hi = r.lo < e1 - kEps || (r.lo_at_vertex && r.lo <= e1 + kEps);
    need[static_cast<std::size_t>(j)] = above_lo && below_hi;
  }
  return need;
}

}  // namespace lblight
