// Which base solutions a relighting can ever select (docs/model.md sec. 4, [Steele2009] sec. 4.1), given what a
// scene declares about its sun and how its instances may be rotated. Base solution j (1..18) is
// needed when some allowed sun puts a non-zero weight on lattice direction j; B_0 when ambient
// light is wanted.
#pragma once

#include <array>
#include <optional>

#include "lblight/lattice/sun.h"

namespace lblight {

enum class InstanceRotation {
  Any,   // instances may be rotated freely: every direction can face the sun
  Yaw,   // about the vertical (z) axis only: the sun's elevation is kept, its azimuth is free
  None,  // instances keep the model's frame
};

struct SunConstraints {
  double min_elevation = -90.0;  // degrees; the toward-sun vector's elevation range
  double max_elevation = 90.0;
  std::optional<Vec3d> fixed_toward_sun;  // one sun (unit vector toward it)
  InstanceRotation rotation = InstanceRotation::None;
  bool ambient = true;  // relighting adds a * B_0
};

// needed[j] for j = 0..18.
std::array<bool, 19> needed_base_solutions(const SunConstraints& c);

// Elevation (degrees) of a toward-sun vector.
double elevation_deg(const Vec3d& toward_sun);

}  // namespace lblight
