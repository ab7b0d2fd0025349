// The physical light the LB model approximates, estimated independently of it: a volumetric path
// tracer on a bake's lattice (docs/truth.md). Each voxel is a homogeneous cube of extinction
// rho * sigma_t per voxel length; photons enter through the interior box's faces as a collimated
// beam or as uniform isotropic light, are tracked voxel by voxel, scatter by Henyey-Greenstein and
// lose sigma_a / sigma_t of their weight at each collision; the fluence of a voxel is the
// track-length estimator (path length in it over its volume). The standard error of every node
// comes from independent batches.
//
// Deterministic for any thread count: each photon draws from its own counter-based random stream
// and scores are summed as 2^-30 fixed-point integers, whose sum does not depend on order.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "lblight/backend/backend.h"
#include "lblight/core/run_context.h"
#include "lblight/lattice/omega.h"

namespace lblight {

// One part of an illumination, in lattice axes.
struct LightSource {
  enum class Kind { Collimated, Isotropic };
  Kind kind = Kind::Collimated;
  std::array<double, 3> direction{};  // Collimated: unit vector, the way the light travels
  // The fluence this part gives on an empty lattice: irradiance normal to the beam (Collimated),
  // 4 pi times the radiance (Isotropic).
  double fluence = 1.0;
};
using Illumination = std::vector<LightSource>;

// The illumination a base solution or static bake stands for (docs/truth.md sec. 2): B_j a
// collimated beam of unit irradiance along n_j, B00 isotropic light of fluence 18 (the empty-lattice
// totals of the LB solutions), a static bake intensity x the sun's beam plus ambient x 18.
Illumination base_solution_light(int index);
Illumination static_light(const std::array<double, 3>& travel_direction, double intensity, double ambient);

// One colour channel: the optical parameters of each material index of the lattice.
using ChannelOptics = std::array<OpticalParams, kMaxMaterials>;

struct MonteCarloOptions {
  double target_error = 0.01;  // stop at this relative L2 standard error over the occupied nodes
  double time_budget = 0;      // or after this many seconds (0: no limit)
  std::uint64_t max_photons = 0;               // or after this many photons (0: no limit)
  std::uint64_t photons_per_batch = 1u << 14;  // one batch is one sample of the standard error
  int min_batches = 16;                        // before the error is trusted
  std::uint64_t seed = 1;
  bool periodic_xy = false;  // x and y wrap around (a laterally infinite slab; tests)
  // >= 0: the lattice stands on a Lambertian ground of this albedo, its kMaterialGround layer
  // (docs/truth.md sec. 8): photons reaching the layer's top face are reflected there, cosine-
  // weighted, and the open ground around the box sends its diffuse light in through the sides.
  double ground_albedo = -1;
};

// Where the light went, in units of the incident power (Collimated: irradiance x the box's area
// across the beam; Isotropic: fluence / 4 x its surface), each with its standard error.
struct PowerBalance {
  double incident = 0;
  std::array<double, 6> escaped{};  // through the faces -x, +x, -y, +y, -z, +z (-z: into the ground, with one)
  std::array<double, 6> escaped_se{};
  double absorbed = 0, absorbed_se = 0;  // sum over voxels of rho sigma_a x fluence
  double lost = 0;  // weight of photons stopped after kMaxCollisions (should stay 0)
};

struct FluenceEstimate {
  std::vector<double> mean;       // per lattice node; boundary nodes: the empty-lattice fluence
  std::vector<double> std_error;  // per node, of the mean (0 on the boundary)
  std::uint64_t photons = 0;
  int batches = 0;
  double seconds = 0;
  // sqrt(sum se^2 / sum mean^2) over the occupied nodes (every interior node when none is).
  double relative_error = 0;
  PowerBalance power;
};

inline constexpr int kMaxCollisions = 1 << 20;

// Bytes trace_fluence holds per lattice node.
inline constexpr double kMonteCarloBytesPerNode = 40.0;

// Traces `light` through one channel of `lattice` until options' target error, time budget or
// photon cap. `stream` separates the random numbers of different systems (solution, channel).
// after_batch (optional) sees the running estimate after every batch (report's curves). Stops
// with Error(Cancelled) at the next batch once ctx.cancel is set; uses ctx.threads host threads.
FluenceEstimate trace_fluence(const LatticeGeometry& lattice, const ChannelOptics& optics, const Illumination& light,
                              const MonteCarloOptions& options, std::uint64_t stream, const RunContext& ctx = {},
                              const std::function<void(const FluenceEstimate&)>& after_batch = {});

}  // namespace lblight
