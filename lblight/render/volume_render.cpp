#include "lblight/render/volume_render.h"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <functional>
#include <limits>

#include "lblight/core/error.h"
#include "lblight/lattice/lb_model.h"
#include "lblight/render/volume_sampling.h"

namespace lblight {

using namespace render_detail;

double henyey_greenstein_unclamped(double g, double c) {
  const double gg = g * g;
  const double denom = 1 + gg - 2 * g * c;
  return (1 - gg) / (4 * kPi * denom * std::sqrt(denom));
}

double henyey_greenstein(double g, double c) {
  // |g| = 1 is a delta that never points at a pixel: rendered as |g| = kMaxRenderedG instead
  // (bark's g = -1 would leave trunks black in the sun).
  return henyey_greenstein_unclamped(std::clamp(g, -kMaxRenderedG, kMaxRenderedG), c);
}

double volume_voxel_size(const DenseFrame& f) {
  const auto& m = f.index_to_world;
  const double h = m[0];
  const double tol = 1e-9 * std::fabs(h);
  if (!(h > 0) || std::fabs(m[5] - h) > tol || std::fabs(m[10] - h) > tol || std::fabs(m[1]) > tol ||
      std::fabs(m[2]) > tol || std::fabs(m[4]) > tol || std::fabs(m[6]) > tol || std::fabs(m[8]) > tol ||
      std::fabs(m[9]) > tol)
    throw_invalid("the renderer takes volumes with cubic, axis-aligned voxels (a uniform scale and a translation); "
                  "this one's transform rotates, shears or stretches");
  return h;
}

std::array<std::vector<float>, 3> sun_transmittance(const RenderVolume& v, const Vec3d& toward_sun, double step) {
  const Dims& d = v.frame.dims;
  const Vec3d dir = unit(toward_sun);
  std::array<std::vector<float>, 3> out;
  for (auto& c : out) c.assign(d.count(), 1.0f);
  // Only nodes a sample in the medium interpolates from: occupied ones and their neighbours (a
  // forest's box is mostly air).
  const std::vector<std::uint8_t> needed = near_medium(d, v.density, 1, true);
#pragma omp parallel for schedule(dynamic, 1)
  for (int k = 0; k < d.nz; ++k)
    for (int j = 0; j < d.ny; ++j)
      for (int i = 0; i < d.nx; ++i) {
        if (!needed[d.index(i, j, k)]) continue;
        const Vec3d o{static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)};
        double t0, t1;
        if (!clip(d, o, dir, t0, t1)) continue;
        double depth[3] = {0, 0, 0};
        // Midpoint rule from the node's centre out of the box.
        for (double t = 0.5 * step; t < t1; t += step) {
          const double len = std::min(step, t1 - (t - 0.5 * step));
          const Vec3d p = add(o, mul(dir, t));
          const double rho = sample(d, v.density, p);
          if (rho <= 0) continue;
          const auto& m = v.materials[static_cast<std::size_t>(material_at(v, p))];
          for (int c = 0; c < 3; ++c) depth[c] += rho * m[c].sigma_t() * len;
          if (depth[0] > 30 && depth[1] > 30 && depth[2] > 30) break;  // exp(-30): nothing gets through
        }
        for (int c = 0; c < 3; ++c) out[c][d.index(i, j, k)] = static_cast<float>(std::exp(-depth[c]));
      }
  return out;
}

Image render_volume(const RenderVolume& v, const Camera& cam, const RenderSettings& st, const RunContext& ctx) {
  if (!(st.step > 0.01 && st.step <= 2)) throw_invalid("march step must be in (0.01, 2] voxels");
  const IndexSpace space(v.frame);
  const CameraRays rays(cam, space);
  const Dims& d = v.frame.dims;
  const bool direct = st.term == RenderTerm::Direct || st.term == RenderTerm::All;
  const bool indirect = (st.term == RenderTerm::Indirect || st.term == RenderTerm::All) && !v.light[0].empty();
  const bool whole_lb = st.term == RenderTerm::Lb && !v.light[0].empty();
  const Vec3d sun = unit(st.toward_sun);
  std::array<std::vector<float>, 3> shadow, lb_shadow;
  if (direct || indirect) shadow = sun_transmittance(v, sun, st.step);
  // The medium the LB light was solved in: delta-M scaled where the bake scaled it. Its own
  // unscattered sun (E T*, which holds the light scattered into the forward peak) is what the
  // indirect term takes out of the LB light; the eye ray's extinction is the scaled one, since the
  // peak sends scattered light on along the ray.
  RenderVolume lb_medium;
  if (v.delta_m) {
    lb_medium.frame = v.frame;
    lb_medium.density = v.density;
    lb_medium.material = v.material;
    LbModel scaling;
    scaling.calibrated = true;
    for (std::size_t k = 0; k < v.materials.size(); ++k)
      for (std::size_t c = 0; c < 3; ++c) lb_medium.materials[k][c] = model_params(v.materials[k][c], scaling);
    if (indirect) lb_shadow = sun_transmittance(lb_medium, sun, st.step);
  }
  const RenderVolume& lb = v.delta_m ? lb_medium : v;
  if (!v.delta_m) lb_shadow = shadow;
  // The LB light's own unscattered sun: the lattice carries it along the three directions the sun
  // is split onto (docs/model.md sec. 4.1), each attenuated along its own path, so that is what
  // the indirect term takes out (with its flux), not the sun's beam along its true direction: in
  // a clumpy crown the split beams pass more light than the true one (docs/rendering.md sec. 1).
  const bool p1 = indirect && !v.flux[0][0].empty();
  const SunWeights split = decompose_direction({-sun.x, -sun.y, -sun.z});
  std::array<std::array<std::vector<float>, 3>, 3> beam_shadow;
  std::array<Vec3d, 3> beam_dir{};
  for (int k = 0; k < 3 && indirect; ++k) {
    const int m = split.direction[static_cast<std::size_t>(k)];
    const double len = std::sqrt(static_cast<double>(d3q19::length_sq(m)));
    beam_dir[k] = {d3q19::cx(m) / len, d3q19::cy(m) / len, d3q19::cz(m) / len};
    if (split.weight[static_cast<std::size_t>(k)] > 0)
      beam_shadow[k] = sun_transmittance(lb, mul(beam_dir[k], -1.0), st.step);
  }
  Image img;
  img.width = cam.width;
  img.height = cam.height;
  img.rgba.assign(static_cast<std::size_t>(cam.width) * cam.height * 4, 0.0f);
  for_each_row(cam.height, st.threads, st.progress, ctx, [&](int py) {
    for (int px = 0; px < cam.width; ++px) {
      const Vec3d dir = rays.dir(px, py);
      double radiance[3] = {0, 0, 0}, trans[3] = {1, 1, 1};
      double t0, t1;
      if (clip(d, rays.origin, dir, t0, t1)) {
        // Cosine between the sun's travel direction (-sun) and the direction toward the eye (-dir).
        const double cos_theta = dot(sun, dir);
        for (double t = t0 + 0.5 * st.step; t < t1; t += st.step) {
          const double len = std::min(st.step, t1 - (t - 0.5 * st.step));
          const Vec3d p = add(rays.origin, mul(dir, t));
          const double rho = sample(d, v.density, p);
          if (rho <= 0) continue;
          const std::size_t material = static_cast<std::size_t>(material_at(v, p));
          const auto& m = v.materials[material];
          const auto& mlb = lb.materials[material];
          for (int c = 0; c < 3; ++c) {
            const double sigma_t = rho * mlb[c].sigma_t(), sigma_s = rho * m[c].sigma_s, lb_sigma_s = rho * mlb[c].sigma_s;
            // Light scattered toward the eye per unit length, constant over the step; the step's
            // own attenuation integrated exactly.
            double source = 0;
            const double to_sun = direct || indirect ? sample(d, shadow[c], p) : 0.0;
            if (direct) source += sigma_s * henyey_greenstein(m[c].g, cos_theta) * st.intensity * to_sun;
            if (indirect) {
              // The LB light beyond its own unscattered sun, in-scattered isotropically, and (delta-M)
              // the sun's light in the forward peak, E (T* - T), scattered out of it by the scaled
              // phase function.
              const double lb_to_sun = sample(d, lb_shadow[c], p);
              double unscattered = 0;
              Vec3d beam_flux{0, 0, 0};
              for (int k = 0; k < 3; ++k) {
                if (!(split.weight[static_cast<std::size_t>(k)] > 0)) continue;
                const double u = st.intensity * split.weight[static_cast<std::size_t>(k)] * sample(d, beam_shadow[k][c], p);
                unscattered += u;
                beam_flux = add(beam_flux, mul(beam_dir[k], u));
              }
              const double scattered = std::max(0.0, sample(d, v.light[c], p) - unscattered);
              if (p1) {
                const auto& f = v.flux[static_cast<std::size_t>(c)];
                const Vec3d flux{sample(d, f[0], p) - beam_flux.x, sample(d, f[1], p) - beam_flux.y,
                                 sample(d, f[2], p) - beam_flux.z};
                source += lb_sigma_s * p1_in_scattering(scattered, flux, mlb[c].g, {-dir.x, -dir.y, -dir.z});
              } else {
                source += lb_sigma_s * scattered / (4 * kPi);
              }
              if (v.delta_m)
                source += lb_sigma_s * henyey_greenstein(mlb[c].g, cos_theta) * st.intensity *
                          std::max(0.0, lb_to_sun - to_sun);
            }
            if (whole_lb) source += lb_sigma_s * sample(d, v.light[c], p) / (4 * kPi);
            const double a = sigma_t * len;
            const double through = std::exp(-a);
            const double weight = a > 1e-12 ? (1 - through) / sigma_t : len;
            radiance[c] += trans[c] * source * weight;
            trans[c] *= through;
          }
          if (trans[0] < 1e-6 && trans[1] < 1e-6 && trans[2] < 1e-6) break;
        }
      }
      float* out = &img.rgba[(static_cast<std::size_t>(py) * cam.width + px) * 4];
      for (int c = 0; c < 3; ++c) out[c] = static_cast<float>(radiance[c] + trans[c] * st.background[c]);
      out[3] = static_cast<float>(1.0 - (trans[0] + trans[1] + trans[2]) / 3.0);
    }
  });
  return img;
}

double p1_in_scattering(double phi, const Vec3d& flux, double g, const Vec3d& toward_eye) {
  if (!(phi > 0)) return 0.0;
  const double len = std::sqrt(dot(flux, flux));
  const double cut = len > phi ? phi / len : 1.0;
  return std::max(0.0, phi + 3.0 * g * cut * dot(flux, toward_eye)) / (4 * kPi);
}

std::array<float, 3> false_colour(double t) {
  // Viridis at nine evenly spaced points, interpolated linearly (perceptually uniform, readable in
  // grey and by colour-blind viewers).
  static constexpr float kStops[9][3] = {{0.267f, 0.005f, 0.329f}, {0.282f, 0.141f, 0.458f}, {0.254f, 0.265f, 0.530f},
                                         {0.207f, 0.372f, 0.553f}, {0.164f, 0.471f, 0.558f}, {0.128f, 0.567f, 0.551f},
                                         {0.135f, 0.659f, 0.518f}, {0.478f, 0.821f, 0.318f}, {0.993f, 0.906f, 0.144f}};
  t = std::isfinite(t) ? std::clamp(t, 0.0, 1.0) * 8.0 : 0.0;
  const int i = std::min(7, static_cast<int>(t));
  const double f = t - i;
  std::array<float, 3> out{};
  for (int c = 0; c < 3; ++c) {
    const double srgb = kStops[i][c] + f * (kStops[i + 1][c] - kStops[i][c]);
    out[c] = static_cast<float>(srgb <= 0.04045 ? srgb / 12.92 : std::pow((srgb + 0.055) / 1.055, 2.4));  // to linear
  }
  return out;
}

double FieldSettings::position(double value) const {
  if (log) {
    if (!(value > 0)) return 0.0;
    return (std::log(value) - std::log(lo)) / (std::log(hi) - std::log(lo));
  }
  return (value - lo) / (hi - lo);
}

float upper_percentile(std::vector<float>& values) {
  const std::size_t top = values.size() * 995 / 1000;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(top), values.end());
  return values[top];
}

void choose_field_scale(const RenderVolume& v, FieldSettings& st) {
  std::vector<float> values;
  for (std::size_t i = 0; i < v.field.size(); ++i)
    if (v.density[i] > 0.0f && std::isfinite(v.field[i]) && (!st.log || v.field[i] > 0.0f)) values.push_back(v.field[i]);
  // No medium (a gas frame without smoke): the scale of every node's value rather than 0..1.
  if (values.empty())
    for (float x : v.field)
      if (std::isfinite(x) && (!st.log || x > 0.0f)) values.push_back(x);
  if (values.empty()) {
    st.lo = st.log ? 1e-4 : 0.0;
    st.hi = 1.0;
    return;
  }
  const double hi = upper_percentile(values);
  const double lo = *std::min_element(values.begin(), values.end());
  if (st.log) {
    st.hi = hi;
    st.lo = std::max(lo, hi * 1e-4);
    if (!(st.hi > st.lo)) st.hi = 10 * st.lo;
  } else {
    st.lo = std::min(0.0, lo);
    st.hi = hi > st.lo ? hi : st.lo + 1;
  }
}

Image render_field(const RenderVolume& v, const std::vector<float>& field, const Camera& cam, const FieldSettings& st,
                   const RunContext& ctx) {
  if (!(st.step > 0.01 && st.step <= 2)) throw_invalid("march step must be in (0.01, 2] voxels");
  if (!(std::isfinite(st.lo) && std::isfinite(st.hi) && st.hi > st.lo) || (st.log && !(st.lo > 0)))
    throw_invalid("the colour scale must run from a finite low to a larger finite high value (both > 0 for a log scale)");
  if (!(st.opacity > 0 && std::isfinite(st.opacity))) throw_invalid("opacity must be a positive number");
  if (field.size() != v.frame.dims.count()) throw_invalid("the field does not match the volume's nodes");
  const IndexSpace space(v.frame);
  const CameraRays rays(cam, space);
  const Dims& d = v.frame.dims;
  Image img;
  img.width = cam.width;
  img.height = cam.height;
  img.rgba.assign(static_cast<std::size_t>(cam.width) * cam.height * 4, 0.0f);
  for_each_row(cam.height, st.threads, st.progress, ctx, [&](int py) {
    for (int px = 0; px < cam.width; ++px) {
      const Vec3d dir = rays.dir(px, py);
      double colour[3] = {0, 0, 0}, trans = 1;
      double t0, t1;
      if (clip(d, rays.origin, dir, t0, t1))
        for (double t = t0 + 0.5 * st.step; t < t1 && trans > 1e-4; t += st.step) {
          const double len = std::min(st.step, t1 - (t - 0.5 * st.step));
          const Vec3d p = add(rays.origin, mul(dir, t));
          const double rho = sample(d, v.density, p);
          if (rho <= 0) continue;
          // Emission-absorption: each step shows its value's colour with the opacity of its density.
          const double alpha = 1 - std::exp(-st.opacity * rho * len);
          const std::array<float, 3> c = false_colour(st.position(sample(d, field, p)));
          for (int k = 0; k < 3; ++k) colour[k] += trans * alpha * c[k];
          trans *= 1 - alpha;
        }
      float* out = &img.rgba[(static_cast<std::size_t>(py) * cam.width + px) * 4];
      for (int k = 0; k < 3; ++k) out[k] = static_cast<float>(colour[k]);
      out[3] = static_cast<float>(1 - trans);
    }
  });
  return img;
}

std::optional<Camera> orbit_camera(const RenderVolume& v, const std::string& preset, int width, int height) {
  const IndexSpace space(v.frame);
  const Dims& d = v.frame.dims;
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (int k = 0; k < d.nz; ++k)
    for (int j = 0; j < d.ny; ++j)
      for (int i = 0; i < d.nx; ++i)
        if (v.density[d.index(i, j, k)] > 0.0f) {
          const double p[3] = {static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)};
          for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
          }
        }
  if (lo[0] > hi[0])
    for (int a = 0; a < 3; ++a) {
      lo[a] = 0;
      hi[a] = (a == 0 ? d.nx : a == 1 ? d.ny : d.nz) - 1;
    }
  const Vec3d centre_i{0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
  const Vec3d centre = add(space.origin, mul(centre_i, space.voxel));
  const double radius = 0.5 * space.voxel *
                        std::sqrt(std::pow(hi[0] - lo[0] + 1, 2) + std::pow(hi[1] - lo[1] + 1, 2) + std::pow(hi[2] - lo[2] + 1, 2));
  Vec3d from;
  if (preset == "front") from = {0, -1, 0};
  else if (preset == "side") from = {1, 0, 0};
  else if (preset == "top") from = {0, 0, 1};
  else if (preset == "three-quarter") from = unit({-1, -1, 0.8});
  else return std::nullopt;
  Camera c;
  c.width = width;
  c.height = height;
  c.fov_degrees = 35;
  const double fit = std::tan(0.5 * c.fov_degrees * kPi / 180.0) * std::min(1.0, static_cast<double>(width) / height);
  c.position = add(centre, mul(from, 1.1 * radius / fit));
  c.look_at = centre;
  c.up = preset == "top" ? Vec3d{0, 1, 0} : Vec3d{0, 0, 1};
  return c;
}

}  // namespace lblight
