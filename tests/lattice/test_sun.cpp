// Sun decomposition on the 32-face polyhedron ([Steele2009] sec. 4.1, docs/model.md sec. 4).
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <set>

#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/sun.h"

using namespace lblight;

namespace {
Vec3d unit(int m) {
  const double l = std::sqrt(static_cast<double>(d3q19::length_sq(m)));
  return {d3q19::cx(m) / l, d3q19::cy(m) / l, d3q19::cz(m) / l};
}
}  // namespace

TEST_CASE("The polyhedron of the 18 unit directions has 32 faces using every direction", "[sun]") {
  const auto& faces = polyhedron_faces();
  REQUIRE(faces.size() == 32);
  std::set<int> used;
  int corner_faces = 0;
  for (const auto& f : faces) {
    int axial = 0;
    for (int m : f) {
      used.insert(m);
      axial += d3q19::is_axial(m);
    }
    CHECK(axial <= 1);
    corner_faces += axial == 0;
  }
  CHECK(used.size() == 18);
  CHECK(corner_faces == 8);  // one per cube corner, 24 around the 6 axial vertices
}

TEST_CASE("Weights are barycentric and point along the sun ray", "[sun]") {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int t = 0; t < 2000; ++t) {
    const Vec3d d{n(rng), n(rng), n(rng)};
    const SunWeights w = decompose_direction(d);
    double sum = 0;
    Vec3d p{0, 0, 0};
    for (int k = 0; k < 3; ++k) {
      REQUIRE(w.weight[k] >= 0.0);
      sum += w.weight[k];
      const Vec3d u = unit(w.direction[k]);
      p.x += w.weight[k] * u.x;
      p.y += w.weight[k] * u.y;
      p.z += w.weight[k] * u.z;
    }
    REQUIRE(sum == Approx(1.0));
    // p is the hit point on the face: parallel to d and pointing the same way
    const double cross = std::hypot(p.y * d.z - p.z * d.y, p.z * d.x - p.x * d.z, p.x * d.y - p.y * d.x);
    const double dot = p.x * d.x + p.y * d.y + p.z * d.z;
    CHECK(cross < 1e-9 * std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z));
    CHECK(dot > 0);
  }
}

TEST_CASE("A lattice direction decomposes to itself with weight one", "[sun]") {
  for (int m = 1; m < 19; ++m) {
    const SunWeights w = decompose_direction({double(d3q19::cx(m)), double(d3q19::cy(m)), double(d3q19::cz(m))});
    double on_m = 0;
    for (int k = 0; k < 3; ++k)
      if (w.direction[k] == m) on_m += w.weight[k];
    CHECK(on_m == Approx(1.0));
  }
}

TEST_CASE("Sun angles: elevation from the horizon, azimuth from +x toward +y", "[sun]") {
  const Vec3d zenith = toward_sun_from_angles(90, 0);
  CHECK(zenith.z == Approx(1.0));
  const Vec3d y = toward_sun_from_angles(0, 90);
  CHECK(y.y == Approx(1.0));
  CHECK(std::fabs(y.x) < 1e-12);
  // Noon sun: light travels straight down, along -z (direction 6).
  const SunWeights w = decompose_direction({-zenith.x, -zenith.y, -zenith.z});
  double down = 0;
  for (int k = 0; k < 3; ++k)
    if (w.direction[k] == 6) down += w.weight[k];
  CHECK(down == Approx(1.0));
}

TEST_CASE("Static boundary values add sun weights to the ambient level", "[sun]") {
  const SunWeights w = decompose_direction({0.3, -0.2, -1.0});
  const auto f = static_boundary(w, 2.0, 0.25);
  double sum = 0;
  for (double v : f) sum += v;
  CHECK(sum == Approx(2.0 + 19 * 0.25));
  CHECK(f[0] == Approx(0.25));
}
