// What a bake will do, decided before any solving: lattices, materials per channel, the
// solutions and their boundary values, step policy and memory. `validate` prints it; `bake`
// runs it.
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lblight/backend/backend.h"
#include "lblight/core/run_context.h"
#include "lblight/lattice/dense_grid.h"
#include "lblight/scene/scene.h"
#include "lblight/scene/validate.h"

namespace lblight {

// Host memory any bake of a lattice needs per node besides its solver: density and material (5
// bytes), one solution's totals in 3 channels (12) and B00's sum when derived (24).
inline constexpr double kHostBytesPerLatticeNode = 41.0;
// And with calibration first_collision (solve/first_collision.h): B00's source as a state (19
// doubles), a beam's transmittance, its credits and exact uncollided light in 3 channels, and the
// running sums and changes of plain iteration's pulses (3 systems).
inline constexpr double kFirstCollisionBytesPerNode = 8.0 * (19 + 1 + 3 + 3 + 6);

// And with output.moments (solve/flux.h): a state read back in doubles (19), one solution's flux and
// the directional solutions' flux sum for B00 (9 floats each).
inline constexpr double kMomentsBytesPerNode = 8.0 * 19 + 2 * 4.0 * 9;

// Host bytes per lattice node of a bake of `mp` (kHostBytesPerLatticeNode, first_collision's and
// the moments').
double host_bytes_per_node(const LbModel& model, bool moments = false);

// The largest boundary value float16 storage takes (its largest finite value is 65504; light in
// the lattice stays near the boundary's, and the margin keeps sums and overshoot finite).
inline constexpr double kFloat16MaxBoundary = 1e4;

struct PlanOverrides {
  std::optional<std::vector<int>> solutions;  // --solutions
  std::optional<IterationMode> mode;          // --iterations
  int iterations = 0;                         //   with mode Fixed
  std::optional<double> tolerance;            // --tolerance
  std::optional<Precision> precision;
  std::optional<SolverMethod> method;         // --method
  std::optional<StateLayout> state;           // --state (auto: not set)
  // --only: plan just this lattice (a work unit, docs/scale-out.md): a scene model, loading only
  // its grid, or a coarse forest lattice, which needs every model's grid.
  std::optional<std::string> only;
};

struct SolutionPlan {
  int index = 0;                   // base solution 0..18, or -1 for a static bake
  std::string grid_name;           // B00..B18, or "light"
  std::array<int, 3> direction{};  // c_index (zero for ambient and static)
  std::array<double, 19> boundary{};
  bool derived = false;            // B_0 summed from B_1..B_18 instead of solved
};

// What the plan leaves out because the scene does not need it (issue: compute nothing a scene
// does not need); shown by validate and recorded in the manifest.
struct PlanSavings {
  std::vector<int> solutions_left_out;  // base solutions no allowed sun can select
  bool ambient_from_sum = false;        // B_0 = sum of B_1..B_18 (boundary layer empty)
  int channels_solved = 3;              // 1 when R, G and B share their materials
  Dims full_lattice;                    // the lattice before cropping
  bool cropped = false;
};

// Method dsa runs plain iteration where that is estimated to need fewer steps than this many
// crossings of the lattice's longest edge (measured: docs/accuracy.md).
inline constexpr double kDsaMinCrossings = 8.0;
// The smallest tolerance method dsa takes: its residual comes from float32 totals, whose
// round-off (convergence.h) is 2e-6 per check.
inline constexpr double kDsaMinTolerance = 2e-6;

struct StepPolicy {
  IterationMode mode = IterationMode::Auto;
  SolverMethod method = SolverMethod::Plain;
  int fixed_steps = 0;      // Fixed and Paper
  int min_steps = 0;        // Auto: never stop before light has crossed the lattice
  int max_steps = 0;        // Auto: give up (not converged) after this many
  int check_interval = 16;  // steps between convergence measurements
  double tolerance = 1e-4;
  Precision precision = Precision::Float32;  // the state's storage, as BakePlan::precision
  std::optional<StateLayout> state;  // as asked; unset: the backend's choice within memory (state_layout)
  std::string method_note;  // why the plan chose another method than asked (empty: none)
  double decay_hint = 0;    // rough slowest decay per step (diffusion + absorption), for the
                            // rounding floor before the iteration shows its own (convergence.h)
};

// What a lattice of the plan is: a scene model, or one of the coarse forest lattices
// (docs/forest.md): the whole forest, or one model standing alone on the same cells.
enum class PlanRole { Model, ForestCoarse, ForestAlone };

// The ground a lattice stands on (docs/model.md sec. 4.3): lattice layer 1 holds ground nodes,
// then `gap` empty layers, then the grid's lowest layer.
struct GroundPlan {
  bool on = false;
  int gap = 0;
  std::array<double, 3> albedo{};     // per colour channel
  std::vector<double> channel_albedo;  // per entry of ModelPlan::channels
  std::array<double, 19> share{};     // u_m: how the reflected light splits over the upward directions
};

struct ModelPlan {
  const ModelSpec* spec = nullptr;
  PlanRole role = PlanRole::Model;
  std::string alone_model;  // ForestAlone: the scene model it stands for
  ModelGrid grid;
  LatticeGeometry lattice;
  std::array<int, 3> lattice_index_min{};  // index coordinate of lattice node (0, 0, 0)
  std::vector<ChannelMaterials> channels;  // distinct channel materials (1 when R = G = B)
  std::array<int, 3> channel_of{};         // colour channel -> entry of `channels`
  LbModel model;                           // the scene's solver model (channels are built by it)
  bool moments = false;                    // the scene's output.moments (host memory per node)
  std::vector<SolutionPlan> solutions;
  GroundPlan ground;
  PlanSavings savings;
  StepPolicy steps;
  GridStats stats;
  double estimated_steps = 0;              // per solution
  std::size_t solved_solutions() const;  // not derived
  std::size_t systems() const { return solved_solutions() * channels.size(); }
};

// The optical parameters as given, per material, of the model's distinct channel `channel` (an
// entry of ModelPlan::channels).
std::array<OpticalParams, kMaxMaterials> channel_optics(const ModelPlan& model, int channel);

// A scene's forest as planned: its instances and the coarse lattices' cell size. The coarse
// lattices are entries of BakePlan::models named "forest" and "forest.alone.<model>".
struct ForestPlan {
  std::vector<ForestInstance> instances;
  bool coarse = false;
  double cell_size = 0;
  std::string cell_size_note;  // how the cell size was chosen
  std::vector<std::shared_ptr<const ModelSpec>> coarse_specs;  // what the coarse ModelPlans point to
};

inline constexpr const char* kForestCoarseName = "forest";
std::string forest_alone_name(const std::string& model);  // "forest.alone.<model>"

// The names of a scene's lattices in plan order (its models, then "forest" and "forest.alone.<m>"
// when it has coarse forest lattices), without loading any grid: the work units of a bake.
std::vector<std::string> lattice_names(const Scene& scene);

struct BakePlan {
  const Scene* scene = nullptr;
  Precision precision = Precision::Float32;  // resolved once here (override, else the scene's)
  std::vector<ModelPlan> models;             // the scene's models, then the coarse forest lattices
  std::optional<ForestPlan> forest;
  std::vector<std::string> warnings;
};

// Loads every model's grid, validates it (docs/model.md sec. 6) and lays out the work. Loading and
// voxelising stop with Error(Cancelled) once ctx.cancel is set.
BakePlan make_plan(const Scene& scene, const PlanOverrides& overrides = {}, const RunContext& ctx = {});

// The plan's scene and precision, no models yet: make_plan's start, and the frame plans of a gas
// sequence (pipeline/gas_frames.h), which plan_model adds to one frame at a time.
BakePlan plan_without_models(const Scene& scene, const PlanOverrides& overrides = {});

// What make_plan does with each model's loaded grid, for a grid the caller made: checked, cropped
// when spec.crop, grown into its lattice, with its channels, solutions and step policy. Warnings go
// to plan.warnings; the result is not added to plan.models.
ModelPlan plan_model(BakePlan& plan, const ModelSpec& spec, ModelGrid grid, const PlanOverrides& overrides = {});

// The grid cut to the box of its occupied nodes (unchanged when empty or already tight). Index
// coordinates and the transform are kept, so the interior of the smaller lattice sees exactly the
// boundary light it saw before: outside the occupied box light only streams.
ModelGrid crop_to_occupied(const ModelGrid& grid);

// The lattice for a grid: grown by `margin` empty nodes on every side (docs/model.md sec. 4). With
// ground_gap >= 0 the bottom is instead the boundary layer, a layer of ground nodes and ground_gap
// empty layers below the grid (docs/model.md sec. 4.3).
LatticeGeometry build_lattice(const ModelGrid& grid, int margin, int ground_gap = -1);
// Lattice layers below the grid's lowest one.
inline int layers_below(int margin, int ground_gap) { return ground_gap >= 0 ? 2 + ground_gap : margin; }

// The boundary values system (solution s, distinct channel `channel`) runs with: the solution's
// own, plus the open ground's reflection of what it sends down when the lattice stands on the
// ground (lattice/ground.h).
std::array<double, 19> system_boundary(const ModelPlan& mp, const SolutionPlan& s, int channel);

std::string base_grid_name(int index);  // "B07"

}  // namespace lblight
