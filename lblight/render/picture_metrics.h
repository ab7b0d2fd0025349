// How a picture compares with a reference picture of the same camera (docs/rendering.md sec. 5):
// the numbers the pictures issue is judged by. Luminance is the mean of R, G and B.
#pragma once

#include <vector>

#include "lblight/lattice/sun.h"
#include "lblight/render/volume_render.h"

namespace lblight {

struct PictureMetrics {
  double mean_ratio = 0;      // mean luminance of the picture over the reference's
  double block_l1 = 0;        // sum |a - b| / sum b over 4x4 pixel blocks
  double reference_noise = 0; // the same measure expected of the reference's own noise
  double sun_shade = 0, reference_sun_shade = 0;    // sun-side half over shade-side half
  double top_bottom = 0, reference_top_bottom = 0;  // upper half over lower half
};

// The sun side is the image half the sun's direction points to (its projection on the camera's
// right axis). reference_se: the reference's standard errors, 3 per pixel (empty: no noise).
// Error(InvalidInput) when the sizes differ.
PictureMetrics compare_pictures(const Image& picture, const Image& reference, const std::vector<float>& reference_se,
                                const Camera& camera, const Vec3d& toward_sun);

}  // namespace lblight
