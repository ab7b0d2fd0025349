#include "lblight/render/picture_metrics.h"

#include <cmath>

#include "lblight/render/volume_sampling.h"

namespace lblight {

using namespace render_detail;

namespace {

double luminance(const Image& img, int x, int y) {
  const float* p = &img.rgba[4 * (static_cast<std::size_t>(y) * img.width + x)];
  return (p[0] + p[1] + p[2]) / 3.0;
}

// Mean luminance of the pixels where `inside(x, y)`.
template <class F>
double mean_where(const Image& img, F inside) {
  double sum = 0;
  long n = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      if (inside(x, y)) {
        sum += luminance(img, x, y);
        ++n;
      }
  return n ? sum / n : 0.0;
}

double ratio(double a, double b) { return b > 0 ? a / b : 0.0; }

}  // namespace

PictureMetrics compare_pictures(const Image& a, const Image& b, const std::vector<float>& se, const Camera& cam,
                                const Vec3d& toward_sun) {
  if (a.width != b.width || a.height != b.height)
    throw_invalid("the pictures differ in size: " + std::to_string(a.width) + "x" + std::to_string(a.height) +
                  " against " + std::to_string(b.width) + "x" + std::to_string(b.height));
  PictureMetrics m;
  const auto all = [](int, int) { return true; };
  m.mean_ratio = ratio(mean_where(a, all), mean_where(b, all));
  double diff = 0, total = 0, noise = 0;
  for (int by = 0; by + 4 <= a.height; by += 4)
    for (int bx = 0; bx + 4 <= a.width; bx += 4) {
      double sa = 0, sb = 0, var = 0;
      for (int y = by; y < by + 4; ++y)
        for (int x = bx; x < bx + 4; ++x) {
          sa += luminance(a, x, y);
          sb += luminance(b, x, y);
          if (!se.empty()) {
            const float* s = &se[3 * (static_cast<std::size_t>(y) * a.width + x)];
            var += (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]) / 9.0;
          }
        }
      diff += std::fabs(sa - sb);
      total += std::fabs(sb);
      noise += std::sqrt(2.0 / kPi * var);  // E|N(0, var)|
    }
  m.block_l1 = ratio(diff, total);
  m.reference_noise = ratio(noise, total);
  // Which half of the image the sun lights: the sign of its direction along the camera's right.
  const Vec3d forward = unit(sub(cam.look_at, cam.position));
  Vec3d right = cross(forward, cam.up);
  if (dot(right, right) < 1e-20) right = cross(forward, Vec3d{0, 1, 0});
  const bool sun_right = dot(right, toward_sun) >= 0;
  const int half_w = a.width / 2, half_h = a.height / 2;
  const auto sun_side = [&](int x, int) { return (x >= half_w) == sun_right; };
  const auto shade_side = [&](int x, int) { return (x >= half_w) != sun_right; };
  const auto top = [&](int, int y) { return y < half_h; };
  const auto bottom = [&](int, int y) { return y >= half_h; };
  m.sun_shade = ratio(mean_where(a, sun_side), mean_where(a, shade_side));
  m.reference_sun_shade = ratio(mean_where(b, sun_side), mean_where(b, shade_side));
  m.top_bottom = ratio(mean_where(a, top), mean_where(a, bottom));
  m.reference_top_bottom = ratio(mean_where(b, top), mean_where(b, bottom));
  return m;
}

}  // namespace lblight
