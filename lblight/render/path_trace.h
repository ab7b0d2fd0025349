// The picture a bake's pictures are judged against (`lblight render --reference`,
// docs/rendering.md sec. 4): the same volume, camera, sun, sky and ambient light as render_volume,
// with every order of scattering traced by Monte Carlo instead of taken from the LB light.
//
// The medium is the renderer's: density trilinear between nodes, the nearest node's material,
// extinction rho sigma_t per voxel length. Paths start at the camera and are tracked by delta
// tracking against a majorant (the largest rho sigma_t of the volume); at each real collision the
// weight takes the single-scattering albedo (absorption as physical), the sun is added by next-event
// estimation (Henyey-Greenstein toward the eye, transmittance by ratio tracking), and a new
// direction is drawn from Henyey-Greenstein. A path that leaves the box after scattering sees the
// sky (upper hemisphere) and the ambient light; one that leaves before sees the background. Each
// colour channel is traced on its own. Per pixel: the mean and its standard error over the samples.
//
// Deterministic for any thread count: each path draws from its own counter-based random stream
// (pixel, sample; the three channels share it), and every pixel is summed in sample order.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "lblight/core/run_context.h"
#include "lblight/render/volume_render.h"

namespace lblight {

struct PathTraceSettings {
  Vec3d toward_sun{0, 0, 1};
  double intensity = 1.0;  // irradiance of the sun's beam
  double sky = 0.0;        // relight's sky level S: radiance 9 S / (2 pi) from the upper hemisphere
  double ambient = 0.0;    // relight's ambient level a: radiance 18 a / (4 pi) from every direction
  std::array<float, 3> background{0, 0, 0};
  int samples_per_pass = 8;       // paths per pixel and channel between two checks of the error
  double target_error = 0.02;     // stop at this relative standard error of the image (see below)
  double time_budget = 0;         // or after this many seconds (0: no limit), at a pass's end
  int max_samples = 4096;         // or after this many paths per pixel and channel
  int max_scatterings = 0;        // 0: every order; k: only paths of at most k scatterings (tests)
  std::uint64_t seed = 1;
  int threads = 0;                // 0 = all cores; the image does not depend on it
  // After each pass: paths per pixel so far and the image's relative standard error.
  std::function<void(int samples, double relative_error)> progress;
};

struct ReferenceImage {
  Image image;                   // RGBA; alpha = the fraction of primary paths that met the medium
  std::vector<float> std_error;  // per pixel and channel (3 per pixel), of the mean
  int samples = 0;               // per pixel and channel
  // sqrt(sum se^2 / sum mean^2) over every pixel and channel: the image's relative standard error.
  double relative_error = 0;
  double seconds = 0;
};

ReferenceImage path_trace(const RenderVolume& volume, const Camera& camera, const PathTraceSettings& settings,
                          const RunContext& ctx = {});

}  // namespace lblight
