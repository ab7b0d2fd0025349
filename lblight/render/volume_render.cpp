#include "lblight/render/volume_render.h"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "lblight/core/error.h"

namespace lblight {
namespace {

constexpr double kPi = 3.14159265358979323846;

Vec3d sub(const Vec3d& a, const Vec3d& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3d add(const Vec3d& a, const Vec3d& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3d mul(const Vec3d& a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double dot(const Vec3d& a, const Vec3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
Vec3d cross(const Vec3d& a, const Vec3d& b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
Vec3d unit(const Vec3d& a) {
  const double l = std::sqrt(dot(a, a));
  if (!(l > 0) || !std::isfinite(l)) throw_invalid("a direction must be a finite, non-zero vector");
  return mul(a, 1.0 / l);
}

// The volume in index space: node n at (i, j, k), world = origin + voxel * (i, j, k).
struct IndexSpace {
  double voxel = 1;
  Vec3d origin;
  explicit IndexSpace(const DenseFrame& f) : voxel(volume_voxel_size(f)) {
    const auto& m = f.index_to_world;
    origin = {m[3] + voxel * f.index_min[0], m[7] + voxel * f.index_min[1], m[11] + voxel * f.index_min[2]};
  }
  Vec3d to_index(const Vec3d& w) const { return mul(sub(w, origin), 1.0 / voxel); }
};

// Trilinear sample of a node array at index position p (0 outside the box).
double sample(const Dims& d, const std::vector<float>& v, const Vec3d& p) {
  const double x = p.x, y = p.y, z = p.z;
  if (x < 0 || y < 0 || z < 0 || x > d.nx - 1 || y > d.ny - 1 || z > d.nz - 1) return 0.0;
  const int i = std::min(static_cast<int>(x), d.nx - 2 < 0 ? 0 : d.nx - 2);
  const int j = std::min(static_cast<int>(y), d.ny - 2 < 0 ? 0 : d.ny - 2);
  const int k = std::min(static_cast<int>(z), d.nz - 2 < 0 ? 0 : d.nz - 2);
  const double fx = x - i, fy = y - j, fz = z - k;
  double s = 0;
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
    const double w = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) * (dz ? fz : 1 - fz);
    if (w == 0) continue;
    s += w * v[d.index(std::min(i + dx, d.nx - 1), std::min(j + dy, d.ny - 1), std::min(k + dz, d.nz - 1))];
  }
  return s;
}

int material_at(const RenderVolume& v, const Vec3d& p) {
  if (v.material.empty()) return 0;
  const Dims& d = v.frame.dims;
  const int i = std::clamp(static_cast<int>(std::lround(p.x)), 0, d.nx - 1);
  const int j = std::clamp(static_cast<int>(std::lround(p.y)), 0, d.ny - 1);
  const int k = std::clamp(static_cast<int>(std::lround(p.z)), 0, d.nz - 1);
  return v.material[d.index(i, j, k)] == kMaterialWood ? 1 : 0;
}

// Where a ray (index space) enters and leaves the box of node centres grown by half a voxel.
bool clip(const Dims& d, const Vec3d& o, const Vec3d& dir, double& t0, double& t1) {
  const double lo[3] = {-0.5, -0.5, -0.5}, hi[3] = {d.nx - 0.5, d.ny - 0.5, d.nz - 0.5};
  const double ov[3] = {o.x, o.y, o.z}, dv[3] = {dir.x, dir.y, dir.z};
  t0 = 0;
  t1 = std::numeric_limits<double>::max();
  for (int a = 0; a < 3; ++a) {
    if (std::fabs(dv[a]) < 1e-300) {
      if (ov[a] < lo[a] || ov[a] > hi[a]) return false;
      continue;
    }
    double ta = (lo[a] - ov[a]) / dv[a], tb = (hi[a] - ov[a]) / dv[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t1 > t0;
}

}  // namespace

double henyey_greenstein(double g, double c) {
  // |g| = 1 is a delta that never points at a pixel: rendered as |g| = kMaxRenderedG instead
  // (bark's g = -1 would leave trunks black in the sun).
  g = std::clamp(g, -kMaxRenderedG, kMaxRenderedG);
  const double gg = g * g;
  const double denom = 1 + gg - 2 * g * c;
  return (1 - gg) / (4 * kPi * denom * std::sqrt(denom));
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
  auto needed = [&](int i, int j, int k) {
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int x = i + dx, y = j + dy, z = k + dz;
          if (x >= 0 && y >= 0 && z >= 0 && x < d.nx && y < d.ny && z < d.nz && v.density[d.index(x, y, z)] > 0.0f) return true;
        }
    return false;
  };
#pragma omp parallel for schedule(dynamic, 1)
  for (int k = 0; k < d.nz; ++k)
    for (int j = 0; j < d.ny; ++j)
      for (int i = 0; i < d.nx; ++i) {
        if (!needed(i, j, k)) continue;
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
  if (cam.width < 1 || cam.height < 1 || cam.width > 16384 || cam.height > 16384)
    throw_invalid("image size " + std::to_string(cam.width) + "x" + std::to_string(cam.height) + "; allowed: 1..16384 each");
  if (!(cam.fov_degrees > 0 && cam.fov_degrees < 179)) throw_invalid("field of view must be in (0, 179) degrees");
  if (!(st.step > 0.01 && st.step <= 2)) throw_invalid("march step must be in (0.01, 2] voxels");
  const IndexSpace space(v.frame);
  const Dims& d = v.frame.dims;
  const bool direct = st.term != RenderTerm::Indirect, indirect = st.term != RenderTerm::Direct && !v.light[0].empty();
  const Vec3d sun = unit(st.toward_sun);
  const std::array<std::vector<float>, 3> shadow = sun_transmittance(v, sun, st.step);
  // Camera basis; rays in index space (uniform scale: directions are the same).
  const Vec3d forward = unit(sub(cam.look_at, cam.position));
  Vec3d right = cross(forward, cam.up);
  if (dot(right, right) < 1e-20) right = cross(forward, Vec3d{0, 1, 0});
  right = unit(right);
  const Vec3d up = cross(right, forward);
  const double half = std::tan(0.5 * cam.fov_degrees * kPi / 180.0);
  const double aspect = static_cast<double>(cam.width) / cam.height;
  const Vec3d origin = space.to_index(cam.position);
  Image img;
  img.width = cam.width;
  img.height = cam.height;
  img.rgba.assign(static_cast<std::size_t>(cam.width) * cam.height * 4, 0.0f);
  std::atomic<int> rows{0};
  const int threads = st.threads > 0 ? st.threads : std::max(1, omp_get_max_threads());
  std::exception_ptr failure;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (int py = 0; py < cam.height; ++py) {
    try {
      ctx.check_cancelled();
      for (int px = 0; px < cam.width; ++px) {
        const double sx = (2.0 * (px + 0.5) / cam.width - 1.0) * half * aspect;
        const double sy = (1.0 - 2.0 * (py + 0.5) / cam.height) * half;
        const Vec3d dir = unit(add(forward, add(mul(right, sx), mul(up, sy))));
        double radiance[3] = {0, 0, 0}, trans[3] = {1, 1, 1};
        double t0, t1;
        if (clip(d, origin, dir, t0, t1)) {
          // Cosine between the sun's travel direction (-sun) and the direction toward the eye (-dir).
          const double cos_theta = dot(sun, dir);
          for (double t = t0 + 0.5 * st.step; t < t1; t += st.step) {
            const double len = std::min(st.step, t1 - (t - 0.5 * st.step));
            const Vec3d p = add(origin, mul(dir, t));
            const double rho = sample(d, v.density, p);
            if (rho <= 0) continue;
            const auto& m = v.materials[static_cast<std::size_t>(material_at(v, p))];
            for (int c = 0; c < 3; ++c) {
              const double sigma_t = rho * m[c].sigma_t(), sigma_s = rho * m[c].sigma_s;
              // Light scattered toward the eye per unit length, constant over the step; the step's
              // own attenuation integrated exactly.
              double source = 0;
              const double to_sun = sample(d, shadow[c], p);
              if (direct) source += sigma_s * henyey_greenstein(m[c].g, cos_theta) * st.intensity * to_sun;
              if (indirect) {
                const double scattered = std::max(0.0, sample(d, v.light[c], p) - st.intensity * to_sun);
                source += sigma_s * scattered / (4 * kPi);
              }
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
    } catch (...) {
#pragma omp critical(lblight_render)
      if (!failure) failure = std::current_exception();
    }
    const int done = ++rows;
    if (st.progress && omp_get_thread_num() == 0) st.progress(static_cast<double>(done) / cam.height);
  }
  if (failure) std::rethrow_exception(failure);
  ctx.check_cancelled();
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
