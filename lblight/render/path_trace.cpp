#include "lblight/render/path_trace.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "lblight/core/random_walk.h"
#include "lblight/render/volume_sampling.h"

namespace lblight {

using namespace render_detail;

namespace {

// A delta phase function (|g| = 1) never sends the sun toward a pixel and cannot be evaluated:
// traced as this close to one.
constexpr double kMaxTracedG = 0.999;
constexpr double kRouletteWeight = 0.1;
constexpr int kMaxCollisions = 1 << 16;

std::array<double, 3> arr(const Vec3d& v) { return {v.x, v.y, v.z}; }
Vec3d vec(const std::array<double, 3>& a) { return {a[0], a[1], a[2]}; }

// One channel of the volume as a path sees it.
class ChannelMedium {
 public:
  ChannelMedium(const RenderVolume& v, int channel) : v_(v), c_(channel) {
    float rho_max = 0.0f;
    for (float r : v.density) rho_max = std::max(rho_max, r);
    for (const auto& m : v.materials) majorant_ = std::max(majorant_, m[static_cast<std::size_t>(c_)].sigma_t());
    majorant_ *= rho_max;
  }
  double majorant() const { return majorant_; }
  double sigma_t(const Vec3d& p) const {
    const double rho = sample(v_.frame.dims, v_.density, p);
    return rho > 0 ? rho * params(p).sigma_t() : 0.0;
  }
  const OpticalParams& params(const Vec3d& p) const {
    return v_.materials[static_cast<std::size_t>(material_at(v_, p))][static_cast<std::size_t>(c_)];
  }
  const Dims& dims() const { return v_.frame.dims; }

 private:
  const RenderVolume& v_;
  int c_;
  double majorant_ = 0.0;
};

// Delta tracking from p along d: the distance to the first real collision, or < 0 when the path
// leaves the box first.
double next_collision(const ChannelMedium& m, const Vec3d& p, const Vec3d& d, CounterRng& rng) {
  double t0, t1;
  if (m.majorant() <= 0 || !clip(m.dims(), p, d, t0, t1)) return -1.0;
  double t = t0;
  for (;;) {
    t -= std::log(rng.uniform()) / m.majorant();
    if (t >= t1) return -1.0;
    if (rng.uniform() * m.majorant() < m.sigma_t(add(p, mul(d, t)))) return t;
  }
}

// Ratio tracking: an unbiased estimate of the transmittance from p out of the box along d.
double transmittance(const ChannelMedium& m, const Vec3d& p, const Vec3d& d, CounterRng& rng) {
  double t0, t1;
  if (m.majorant() <= 0 || !clip(m.dims(), p, d, t0, t1)) return 1.0;
  double tr = 1.0, t = t0;
  for (;;) {
    t -= std::log(rng.uniform()) / m.majorant();
    if (t >= t1) return tr;
    tr *= 1.0 - m.sigma_t(add(p, mul(d, t))) / m.majorant();
    if (tr < 0.05) {  // Russian roulette on small transmittances
      if (rng.uniform() > 0.5) return 0.0;
      tr *= 2.0;
    }
  }
}

double traced_g(double g) { return std::clamp(g, -kMaxTracedG, kMaxTracedG); }

// One path of one channel from the camera: its radiance, and whether it met the medium.
double trace_path(const ChannelMedium& m, const PathTraceSettings& st, int channel, const Vec3d& origin,
                  const Vec3d& dir, const Vec3d& sun, CounterRng& rng, bool& hit) {
  constexpr double kPi4 = 4.0 * kPi;
  const double sky_radiance = 9.0 * st.sky / (2.0 * kPi), ambient_radiance = 18.0 * st.ambient / kPi4;
  Vec3d p = origin, d = dir;
  double radiance = 0.0, weight = 1.0;
  hit = false;
  for (int scatterings = 0; scatterings < kMaxCollisions; ++scatterings) {
    const double t = next_collision(m, p, d, rng);
    if (t < 0) {  // leaves the box: the background, or after scattering the sky and ambient light
      if (scatterings == 0) return st.background[static_cast<std::size_t>(channel)];
      return radiance + weight * (ambient_radiance + (d.z > 0 ? sky_radiance : 0.0));
    }
    hit = true;
    p = add(p, mul(d, t));
    const OpticalParams& op = m.params(p);
    weight *= op.sigma_s / op.sigma_t();
    const double g = traced_g(op.g);
    // The sun by next-event estimation: its light travels along -sun and turns toward -d.
    if (st.intensity > 0)
      radiance += weight * henyey_greenstein_unclamped(g, dot(sun, d)) * st.intensity * transmittance(m, p, sun, rng);
    if (st.max_scatterings > 0 && scatterings + 1 >= st.max_scatterings) return radiance;
    if (weight < kRouletteWeight) {
      if (rng.uniform() * kRouletteWeight > weight) return radiance;
      weight = kRouletteWeight;
    }
    const double u1 = rng.uniform(), u2 = rng.uniform();
    d = vec(scatter_hg(arr(d), g, u1, u2));
  }
  return radiance;
}

}  // namespace

ReferenceImage path_trace(const RenderVolume& v, const Camera& cam, const PathTraceSettings& st, const RunContext& ctx) {
  if (st.samples_per_pass < 1 || st.max_samples < 2) throw_invalid("path tracing needs at least 2 samples per pixel");
  const auto start = std::chrono::steady_clock::now();
  const IndexSpace space(v.frame);
  const CameraRays rays(cam, space);
  const Vec3d sun = unit(st.toward_sun);
  const std::array<ChannelMedium, 3> media = {ChannelMedium(v, 0), ChannelMedium(v, 1), ChannelMedium(v, 2)};
  const std::size_t pixels = static_cast<std::size_t>(cam.width) * cam.height;
  std::vector<double> sum(3 * pixels, 0.0), sum_sq(3 * pixels, 0.0), hits(pixels, 0.0);
  ReferenceImage out;
  int done = 0;
  for (;;) {
    const int pass = std::min(st.samples_per_pass, st.max_samples - done);
    for_each_row(cam.height, st.threads, {}, ctx, [&](int py) {
      for (int px = 0; px < cam.width; ++px) {
        const std::size_t pixel = static_cast<std::size_t>(py) * cam.width + px;
        const Vec3d dir = rays.dir(px, py);
        for (int c = 0; c < 3; ++c)
          for (int s = done; s < done + pass; ++s) {
            // One stream per pixel and sample for all three channels: channels of equal optics
            // follow the same paths (no colour noise on a grey cloud).
            CounterRng rng(st.seed, pixel, static_cast<std::uint64_t>(s));
            bool hit = false;
            const double x = trace_path(media[static_cast<std::size_t>(c)], st, c, rays.origin, dir, sun, rng, hit);
            sum[3 * pixel + c] += x;
            sum_sq[3 * pixel + c] += x * x;
            hits[pixel] += hit ? 1.0 : 0.0;
          }
      }
    });
    done += pass;
    double se_sq = 0, mean_sq = 0;
    for (std::size_t i = 0; i < 3 * pixels; ++i) {
      const double mean = sum[i] / done;
      se_sq += std::max(0.0, sum_sq[i] / done - mean * mean) / (done - 1);
      mean_sq += mean * mean;
    }
    out.relative_error = mean_sq > 0 ? std::sqrt(se_sq / mean_sq) : 0.0;
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (st.progress) st.progress(done, out.relative_error);
    if (done < 2) continue;
    if (out.relative_error <= st.target_error || done >= st.max_samples ||
        (st.time_budget > 0 && out.seconds >= st.time_budget))
      break;
  }
  out.samples = done;
  out.image.width = cam.width;
  out.image.height = cam.height;
  out.image.rgba.assign(4 * pixels, 0.0f);
  out.std_error.assign(3 * pixels, 0.0f);
  for (std::size_t i = 0; i < pixels; ++i) {
    for (int c = 0; c < 3; ++c) {
      const double mean = sum[3 * i + c] / done;
      out.image.rgba[4 * i + c] = static_cast<float>(mean);
      out.std_error[3 * i + c] =
          static_cast<float>(std::sqrt(std::max(0.0, sum_sq[3 * i + c] / done - mean * mean) / (done - 1)));
    }
    out.image.rgba[4 * i + 3] = static_cast<float>(hits[i] / (3.0 * done));
  }
  return out;
}

}  // namespace lblight
