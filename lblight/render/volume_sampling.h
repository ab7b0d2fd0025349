// What lblight's two volume renderers share (render_volume's ray marcher and path_trace's
// reference): the volume's index space, trilinear samples of node arrays, the nearest node's
// material, clipping rays to the box, the pinhole camera's rays and the parallel loop over rows.
// Internal to lblight/render.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <vector>

#include "lblight/core/error.h"
#include "lblight/core/run_context.h"
#include "lblight/render/volume_render.h"

namespace lblight::render_detail {

inline constexpr double kPi = 3.14159265358979323846;

inline Vec3d sub(const Vec3d& a, const Vec3d& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3d add(const Vec3d& a, const Vec3d& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3d mul(const Vec3d& a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline double dot(const Vec3d& a, const Vec3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3d cross(const Vec3d& a, const Vec3d& b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
inline Vec3d unit(const Vec3d& a) {
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
inline double sample(const Dims& d, const std::vector<float>& v, const Vec3d& p) {
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

inline int material_at(const RenderVolume& v, const Vec3d& p) {
  if (v.material.empty()) return 0;
  const Dims& d = v.frame.dims;
  const int i = std::clamp(static_cast<int>(std::lround(p.x)), 0, d.nx - 1);
  const int j = std::clamp(static_cast<int>(std::lround(p.y)), 0, d.ny - 1);
  const int k = std::clamp(static_cast<int>(std::lround(p.z)), 0, d.nz - 1);
  return v.material[d.index(i, j, k)] == kMaterialWood ? 1 : 0;
}

// Where a ray (index space) enters and leaves the box of node centres grown by half a voxel.
inline bool clip(const Dims& d, const Vec3d& o, const Vec3d& dir, double& t0, double& t1) {
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

// A pinhole camera's primary rays in the volume's index space (uniform scale: directions are the
// same as in the world).
struct CameraRays {
  Vec3d origin, forward, right, up;
  double half = 0, aspect = 1;
  int width = 0, height = 0;
  CameraRays(const Camera& cam, const IndexSpace& space) : width(cam.width), height(cam.height) {
    if (cam.width < 1 || cam.height < 1 || cam.width > 16384 || cam.height > 16384)
      throw_invalid("image size " + std::to_string(cam.width) + "x" + std::to_string(cam.height) + "; allowed: 1..16384 each");
    if (!(cam.fov_degrees > 0 && cam.fov_degrees < 179)) throw_invalid("field of view must be in (0, 179) degrees");
    forward = unit(sub(cam.look_at, cam.position));
    right = cross(forward, cam.up);
    if (dot(right, right) < 1e-20) right = cross(forward, Vec3d{0, 1, 0});
    right = unit(right);
    up = cross(right, forward);
    half = std::tan(0.5 * cam.fov_degrees * kPi / 180.0);
    aspect = static_cast<double>(cam.width) / cam.height;
    origin = space.to_index(cam.position);
  }
  Vec3d dir(int px, int py) const {
    const double sx = (2.0 * (px + 0.5) / width - 1.0) * half * aspect;
    const double sy = (1.0 - 2.0 * (py + 0.5) / height) * half;
    return unit(add(forward, add(mul(right, sx), mul(up, sy))));
  }
};

// Runs row(py) for every image row on `threads` threads (0 = all cores), reporting the fraction
// done from the calling thread and rethrowing the first failure (cancellation included).
void for_each_row(int height, int threads, const std::function<void(double)>& progress, const RunContext& ctx,
                  const std::function<void(int)>& row);

}  // namespace lblight::render_detail
