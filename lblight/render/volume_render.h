// Volume rendering of a bake (`lblight render`, docs/rendering.md): ray marching through the
// density with single scattering of the sun ([Chen2006] eqs. (1)-(6): in-scattering along the view
// ray with the material's Henyey-Greenstein phase function, attenuated toward the eye and toward
// the sun through the same density, H(t) the shadow term) plus the
// multiple scattering the LB solution holds, emitted isotropically. The LB light contains the
// sun's unscattered beam; the renderer removes it (intensity x the transmittance to the sun, in
// the same units: 1 = the open-air light of a unit sun) before using the rest as scattered light,
// so the direct term is not counted twice.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "lblight/core/run_context.h"
#include "lblight/lattice/dense_grid.h"
#include "lblight/lattice/omega.h"
#include "lblight/lattice/sun.h"

namespace lblight {

// What the renderer marches through: a dense box of nodes with uniform cubic voxels, axis-aligned
// in the world (index (i, j, k) + frame.index_min at voxel_size (i, j, k) + origin).
struct RenderVolume {
  DenseFrame frame;
  std::vector<float> density;                  // [0, 1] per node
  std::vector<std::uint8_t> material;          // kMaterialMedium or kMaterialWood per node (empty: all medium)
  std::array<std::array<OpticalParams, 3>, 2> materials{};  // per material, per channel, per voxel length
  std::array<std::vector<float>, 3> light;     // the relit LB light per node (empty: no indirect term)
  // Its flux vector per channel and axis (index axes; bakes with output.moments): the indirect
  // term then in-scatters the scattered light's P1 radiance with the phase function
  // (docs/rendering.md sec. 1). Empty: isotropic in-scattering.
  std::array<std::array<std::vector<float>, 3>, 3> flux;
  // The light was solved with the calibrated model's delta-M scaling (docs/model.md sec. 8): the
  // forward peak g^2 of scattering counted as unscattered. The renderer then takes the light's
  // scattered part and the eye ray's extinction from the same scaled medium (docs/rendering.md sec. 1).
  bool delta_m = false;
  std::vector<float> field;                    // a grid shown in false colour (render_field), per node
};

struct Camera {
  Vec3d position{0, -5, 2}, look_at{0, 0, 1}, up{0, 0, 1};
  double fov_degrees = 40;  // vertical
  int width = 512, height = 512;
};

// Direct: the sun single-scattered with HG and shadows; Indirect: the LB light beyond the
// unscattered sun, in-scattered with the phase function to first order where the volume has the
// flux (isotropically where not); All: both. Lb: the whole LB light (unscattered sun included)
// scattered isotropically, no HG term - what the Blender add-on's material renders
// (tools/blender), for comparing the two.
enum class RenderTerm { Direct, Indirect, All, Lb };

struct RenderSettings {
  Vec3d toward_sun{0, 0, 1};
  double intensity = 1.0;      // irradiance of the sun's beam
  RenderTerm term = RenderTerm::All;
  double step = 0.5;           // march step in voxels
  std::array<float, 3> background{0, 0, 0};
  int threads = 0;             // 0 = all cores; the image does not depend on it
  std::function<void(double)> progress;  // fraction of rows done, from the calling thread
};

struct Image {
  int width = 0, height = 0;
  std::vector<float> rgba;  // row-major from the top row, 4 floats per pixel, linear radiance
};

// The voxel edge (world units) and the world position of index (0, 0, 0) of the volume's frame;
// Error(InvalidInput) when the transform is not a uniform axis-aligned scale and translation.
double volume_voxel_size(const DenseFrame& frame);

// Transmittance toward the sun per node and channel: exp(-integral of rho sigma_t) from the node's
// centre out of the volume along toward_sun, marched at `step` voxels.
std::array<std::vector<float>, 3> sun_transmittance(const RenderVolume& volume, const Vec3d& toward_sun, double step);

Image render_volume(const RenderVolume& volume, const Camera& camera, const RenderSettings& settings,
                    const RunContext& ctx = {});

// `lblight render --grid`: any grid in false colour. Emission-absorption through the density
// (extinction `opacity` per voxel length at density 1), each step coloured by its value on the
// scale [lo, hi] (linear or logarithmic); values outside are clamped to the ends.
struct FieldSettings {
  double lo = 0, hi = 1;
  bool log = false;
  double opacity = 0.5;
  double step = 0.5;  // march step in voxels
  int threads = 0;
  std::function<void(double)> progress;
  double position(double value) const;  // where `value` sits on the scale, 0..1 within it
};

// field: one value per node of the volume's frame.
Image render_field(const RenderVolume& volume, const std::vector<float>& field, const Camera& camera,
                   const FieldSettings& settings, const RunContext& ctx = {});

// The 99.5th percentile of non-empty `values` (reordered): where automatic exposures and colour
// scales put their top, so a few hot nodes or pixels do not wash a picture out.
float upper_percentile(std::vector<float>& values);

// A scale for volume.field over its occupied nodes: low = 0 (the minimum when negative values
// exist; for a log scale the smallest positive value, at most 4 decades under high), high = the
// 99.5th percentile (so a few hot nodes do not wash the picture out). With no occupied node,
// over all nodes.
void choose_field_scale(const RenderVolume& volume, FieldSettings& settings);

// The colour scale (viridis) at t in [0, 1] (clamped), as linear RGB (viridis's sRGB colours decoded).
std::array<float, 3> false_colour(double t);

// A camera that frames the volume's occupied box from a preset direction: "front" (from -y),
// "side" (from +x), "top", "three-quarter" (from -x -y, 30 degrees up). Empty for an unknown name.
std::optional<Camera> orbit_camera(const RenderVolume& volume, const std::string& preset, int width, int height);
inline constexpr const char* kOrbitPresets = "front, side, top, three-quarter";

// Henyey-Greenstein phase function (per steradian) for the cosine between the light's travel
// direction and the direction it scatters into; |g| is clamped to kMaxRenderedG.
inline constexpr double kMaxRenderedG = 0.95;
double henyey_greenstein(double g, double cos_theta);
// The same without the clamp (|g| < 1).
double henyey_greenstein_unclamped(double g, double cos_theta);

// Light in-scattered toward `toward_eye` (unit) per unit scattering coefficient from light of
// fluence phi and flux J, reconstructed to first order (P1: radiance (phi + 3 J . w) / 4 pi) and
// convolved with a Henyey-Greenstein phase function of asymmetry g (whose first Legendre
// coefficient is g): (phi + 3 g J . toward_eye) / 4 pi, never below 0. J is first cut to |J| <= phi
// (light cannot flow faster than it is).
double p1_in_scattering(double phi, const Vec3d& flux, double g, const Vec3d& toward_eye);

}  // namespace lblight
