// A scene's forest (docs/scene-format.md, "forest"): instances of its models placed in world
// space, listed one by one and/or produced by a seeded placement generator, checked against what
// the scene declared about instance rotation (a yaw-rotated copy of a model baked for
// instance_rotation "none" would select base solutions that were left out).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "lblight/lattice/dense_grid.h"
#include "lblight/lattice/sun.h"
#include "lblight/lattice/sun_coverage.h"
#include "lblight/scene/json_reader.h"

namespace lblight {

struct ForestInstance {
  std::string model;                  // a model of the scene, by name
  std::array<double, 3> position{};   // world position of the model's frame origin
  double yaw_degrees = 0;             // rotation about the vertical (z) axis
  double scale = 1;                   // uniform geometric scale
};

// Uniform random placement over a rectangle of the ground, at least min_spacing apart.
struct ForestGenerator {
  std::array<double, 4> area{};       // x_min, y_min, x_max, y_max (world units)
  double height = 0;                  // z of every generated position
  int count = 0;                      // how many (from "count" or "density" x area)
  double min_spacing = 0;
  std::array<double, 2> yaw_degrees{0, 0};  // uniform in [lo, hi]
  std::array<double, 2> scale{1, 1};        // uniform in [lo, hi]
  std::vector<std::pair<std::string, double>> models;  // name, weight (> 0)
  std::uint64_t seed = 1;
  std::string json_path;
};

struct ForestSpec {
  std::vector<ForestInstance> instances;   // listed
  std::vector<std::string> instance_paths;  // JSON pointer of each listed instance, for messages
  std::optional<ForestGenerator> generator;
  // The coarse forest grid ([Steele2009] sec. 4.3, docs/forest.md): solved unless "coarse": false;
  // cell edge in world units, 0 = kDefaultCoarseCellVoxels x the coarsest model voxel x the largest scale.
  bool coarse = true;
  double cell_size = 0;
  double coarse_tolerance = 1e-3;  // the coarse lattices' target error: they only shade
  bool empty() const { return instances.empty() && !generator; }
};

// Where an instance puts its model: world = position + scale * Rz(yaw) * p, p in the model's own
// world coordinates (its grid's index_to_world); directions rotate with Rz(yaw) only.
class InstanceTransform {
 public:
  explicit InstanceTransform(const ForestInstance& instance);
  Vec3d to_world(const Vec3d& model) const;
  Vec3d to_model(const Vec3d& world) const;
  Vec3d direction_to_model(const Vec3d& world) const;
  double scale() const { return scale_; }

 private:
  double cos_ = 1, sin_ = 0, scale_ = 1;
  Vec3d position_;
};

// World position of array node (i, j, k) of `frame` (index_min added: index_to_world acts on index
// coordinates, as OpenVDB's transform does); fractional positions allowed.
Vec3d frame_to_world(const DenseFrame& frame, double i, double j, double k);
// A voxel's edge: the cube root of the product of its three edge lengths.
double frame_voxel_edge(const DenseFrame& frame);
// World-space box an instance's copy of `frame` covers: its node centres grown by `pad` voxels,
// through the instance's transform.
void instance_world_bounds(const DenseFrame& frame, const InstanceTransform& t, double pad, Vec3d& lo, Vec3d& hi);

inline constexpr int kMaxForestInstances = 1'000'000;  // ~100 MB of instances

// Reads the "forest" object; model names must be among `models`, and a yaw other than 0 (mod
// 360) needs instance_rotation "yaw" or "any".
ForestSpec read_forest(const JsonReader& r, const std::set<std::string>& models, InstanceRotation rotation);

// Every instance: the listed ones, then the generated ones (the same for a seed on every
// machine: own random numbers, not the standard library's distributions). Error(InvalidInput)
// naming the generator when the area cannot hold `count` instances min_spacing apart.
std::vector<ForestInstance> forest_instances(const ForestSpec& forest, const std::string& file);

}  // namespace lblight
