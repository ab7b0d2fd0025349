// Scene file v1 (docs/scene-format.md): models with a density source and materials, lighting,
// and solver settings. Parsing checks types, ranges and names; what needs the grids (density
// range, stability) is checked by validate.h once the grids are loaded.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "lblight/compress/lbh_settings.h"
#include "lblight/core/error.h"
#include "lblight/core/precision.h"
#include "lblight/lattice/lb_model.h"
#include "lblight/lattice/sun.h"
#include "lblight/scene/forest.h"
#include "lblight/lattice/sun_coverage.h"
#include "lblight/scene/material.h"

namespace lblight {

inline constexpr int kSceneVersion = 1;
// A scene file larger than this is refused before it is parsed (thousands of models or forest
// instances take a few MiB).
inline constexpr std::uint64_t kMaxSceneBytes = 64ull << 20;

enum class SourceType { Procedural, Vdb, Mesh, Gas };

struct ProceduralSource {
  std::string shape = "cloud";  // cloud | plant
  int resolution = 48;          // nodes along the longest edge
  std::uint64_t seed = 1;
  double size = 1.0;            // world length of the longest edge
};

struct VdbSource {
  std::filesystem::path path;   // resolved against the scene file's folder
  std::string grid = "density";
  std::string wood_grid;        // optional: voxels > 0.5 are wood ("brown")
};

struct MeshSource {
  std::filesystem::path path;
  int resolution = 64;
  int supersample = 8;
  std::vector<std::string> leaf_patterns, wood_patterns;  // empty = defaults
  bool has_bounds = false;
  std::array<double, 3> bounds_min{}, bounds_max{};
  std::string fill = "none";  // none | parity | winding (closed solids; docs/voxelization.md)
};

// A mesh the gas flows around: placed at `position` with `scale` (mesh units to world), its
// nodes solid where at least half their volume is touched (all of it, or its wood parts only).
struct GasObstacle {
  std::filesystem::path path;
  std::array<double, 3> position{0, 0, 0};
  double scale = 1.0;
  std::string part = "all";   // all | wood
  std::string fill = "none";  // none | parity | winding, as a mesh source's
};

// Smoke simulated by the gas solver (lblight/fluid, docs/fluid.md): a box of `resolution` nodes
// (x, y, z), `size` world units along its longest edge, standing on z = 0; a floor with a round
// inlet, the other faces open. The density a bake lights is the smoke of frame `frame`.
struct GasSource {
  std::array<int, 3> resolution{32, 32, 64};
  double size = 1.0;
  double tau = 0.56, tau_temperature = 0.52, tau_smoke = 0.51;
  double ambient_temperature = 28.0;  // degrees
  double buoyancy = 2e-5;             // lattice force per node per degree above ambient ([Wei2004] eq. 16)
  std::array<double, 2> inlet_center{0, 0};  // world x, y
  double inlet_radius = 0.1;          // world units
  double inlet_speed = 0.05;          // lattice units per step (Mach = speed x sqrt(3))
  double inlet_temperature = 40.0;
  double inlet_smoke = 1.0;
  int frames = 8, steps_per_frame = 50;
  int frame = 0;                      // the frame a bake lights (0 = the last)
  std::vector<GasObstacle> obstacles;
};

struct DensitySpec {
  SourceType type = SourceType::Procedural;
  ProceduralSource procedural;
  VdbSource vdb;
  MeshSource mesh;
  GasSource gas;
  double density_scale = 1.0;
  std::string json_path;  // where in the scene file, for messages
};

struct ModelSpec {
  std::string name;
  DensitySpec density;
  Material material;       // medium / leaf ("green") nodes: material index 0
  Material wood_material;  // wood ("brown") nodes: material index 1
  int margin = 1;
  bool crop = true;  // shrink the lattice to the occupied nodes plus margin (same interior results)
  bool ground = true;  // stands on the scene's ground, if it has one (false: floats, e.g. a cloud)
  std::string json_path;
};

// A reflective ground under every model and the coarse forest grid (docs/model.md sec. 4.3):
// light arriving at it goes back up, diffusely, with the albedo of each colour channel.
struct GroundSpec {
  bool enabled = false;                // the scene has a "ground"
  double height = 0.0;                 // world z of the forest's ground (models stand directly on theirs)
  std::array<double, 3> albedo{};      // per channel, 0..1 (0: black, nothing comes back)
};

enum class LightingMode { Base, Static };

struct LightingSpec {
  LightingMode mode = LightingMode::Base;
  std::vector<int> solutions;  // base: indices 0..18 to bake (sorted, unique)
  bool solutions_from_sun = true;  // base: `solutions` follow from `sun_constraints` ("auto")
  SunConstraints sun_constraints;  // base: what relighting may ask for (docs/model.md sec. 4)
  bool ambient_from_sum = true;    // base: B_0 as the sum of B_1..B_18 when all of those run
  Vec3d toward_sun{0, 0, 1};   // static: unit vector toward the sun
  double intensity = 1.0;      // static: sun intensity s
  double ambient = 0.0;        // static: ambient level a
};

enum class IterationMode { Auto, Paper, Fixed };
// Plain iteration of the LB step (the papers), BiCGStab on the same fixed point (solve/krylov.h),
// or LB steps corrected by a diffusion solve (solve/dsa.h).
enum class SolverMethod { Plain, BiCGStab, Dsa };

// The LB model of a scene that names none ("solver": {"model": ...}): physical light by default;
// "paper" reproduces the papers bit for bit (docs/model.md).
inline constexpr const char* kDefaultLbModel = "calibrated";

struct SolverSpec {
  IterationMode mode = IterationMode::Auto;
  SolverMethod method = SolverMethod::Plain;
  int iterations = 0;          // Fixed: step count
  double tolerance = 1e-4;     // Auto: target relative error of the stored totals
  int max_iterations = 0;      // Auto: cap; 0 = 100 x longest lattice edge
  int check_interval = 0;      // steps between convergence checks; 0 = automatic
  Precision precision = Precision::Float32;
  std::optional<StateLayout> state;  // "state": "two-levels", "in-place"; unset ("auto"): as memory allows
  LbModel model;               // "model": "calibrated" (a scene's default) or "paper", with "calibration"
};

// "output": {"lbh": {"threshold": 0.01, "relative": true}} asks bake for <model>.lbh next to
// <model>.vdb: Haar-compressed sub-block streams (docs/lbh-format.md, docs/compression.md).
struct LbhOutputSpec {
  bool enabled = false;
  double threshold = 0.01;  // >= 0; relative: fraction of each solution's largest |value| (<= 1)
  bool relative = true;
  LbhCoefficients coefficients = LbhCoefficients::Auto;  // 8-bit details when the threshold is > 0
};

struct OutputSpec {
  bool vdb = true;  // the base-solution grids as OpenVDB (density is always written with them)
  LbhOutputSpec lbh;
  // Light grids over the whole lattice box (the boundary layer's source values included) instead
  // of only the occupied nodes and their neighbours (docs/output-format.md).
  bool full_box = false;
  // Light grids stored as 16-bit floats (OpenVDB's half; half the file), their rounding error
  // reported per solution in the manifest.
  bool half = false;
  // Each light grid's flux vector per colour channel as well (<grid>_flux_r/_g/_b), what `render`
  // and the add-on in-scatter with the phase function (docs/rendering.md sec. 1): four times the
  // light's grids on disk. false: the scalar light only (rendered with --scattering isotropic).
  bool moments = true;
  // Each model's .vdb also as NanoVDB (<model>.nvdb: every grid, for GPU renderers and real-time
  // engines; docs/output-format.md).
  bool nanovdb = false;
};

struct Scene {
  int version = kSceneVersion;
  std::string name;
  std::filesystem::path file;  // as given
  std::filesystem::path dir;   // folder relative paths resolve against
  std::vector<ModelSpec> models;
  LightingSpec lighting;
  SolverSpec solver;
  OutputSpec output;
  ForestSpec forest;           // empty unless the scene has a "forest" section
  GroundSpec ground;           // off unless the scene has a "ground" section
  std::string hash;            // "fnv1a64:<hex>" of the canonical JSON
};

// Reads and parses a scene file; throws Error(InvalidInput) naming file, JSON path, value and the
// allowed range, or Error(Io) when the file cannot be read.
Scene load_scene(const std::filesystem::path& file);
// The same from text (tests); file is used in messages and to resolve relative paths.
Scene parse_scene(const std::string& text, const std::filesystem::path& file);
// The scene file and every file it names (density .vdb files, meshes, gas obstacles): what a run
// reads, so that no output replaces them (RunPaths).
std::vector<std::filesystem::path> scene_input_files(const Scene& scene);

// "all", "0,1,5-7" or a JSON-like list, to sorted unique indices in 0..18. Throws
// Error(InvalidInput) with `where` as location.
std::vector<int> parse_solution_list(const std::string& text, const Location& where);

const char* to_string(IterationMode mode);
const char* to_string(SolverMethod method);
// "plain", "bicgstab" or "dsa"; nullopt for anything else.
std::optional<SolverMethod> parse_solver_method(const std::string& name);
inline constexpr const char* kSolverMethodNames = "plain, bicgstab, dsa";
// "two-levels" or "in-place"; nullopt for anything else ("auto" included).
std::optional<StateLayout> parse_state_layout(const std::string& name);
const char* to_string(SourceType type);

}  // namespace lblight
