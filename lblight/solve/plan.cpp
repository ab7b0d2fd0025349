#include "lblight/solve/plan.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "lblight/core/error.h"
#include "lblight/core/system_info.h"
#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/ground.h"
#include "lblight/scene/procedural.h"
#include "lblight/scene/forest_coarse.h"
#include "lblight/scene/load_model.h"

namespace lblight {

std::string base_grid_name(int index) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "B%02d", index);
  return buf;
}

std::size_t ModelPlan::solved_solutions() const {
  std::size_t n = 0;
  for (const SolutionPlan& s : solutions) n += s.derived ? 0 : 1;
  return n;
}

ModelGrid crop_to_occupied(const ModelGrid& g) {
  int lo[3] = {g.dims.nx, g.dims.ny, g.dims.nz}, hi[3] = {-1, -1, -1};
  for (int k = 0; k < g.dims.nz; ++k)
    for (int j = 0; j < g.dims.ny; ++j)
      for (int i = 0; i < g.dims.nx; ++i)
        if (g.density[g.dims.index(i, j, k)] > 0.0f) {
          const int p[3] = {i, j, k};
          for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
          }
        }
  if (hi[0] < 0) return g;
  const Dims d{hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1};
  if (d.count() == g.dims.count()) return g;
  ModelGrid c;
  c.dims = d;
  for (int a = 0; a < 3; ++a) c.index_min[a] = g.index_min[a] + lo[a];
  c.index_to_world = g.index_to_world;
  c.description = g.description;
  c.density.resize(d.count());
  c.material.resize(d.count());
  for (int k = 0; k < d.nz; ++k)
    for (int j = 0; j < d.ny; ++j)
      for (int i = 0; i < d.nx; ++i) {
        const std::size_t src = g.dims.index(i + lo[0], j + lo[1], k + lo[2]);
        c.density[d.index(i, j, k)] = g.density[src];
        c.material[d.index(i, j, k)] = g.material[src];
      }
  return c;
}

LatticeGeometry build_lattice(const ModelGrid& g, int margin, int ground_gap) {
  LatticeGeometry lat;
  const int below = layers_below(margin, ground_gap);
  lat.dims = {g.dims.nx + 2 * margin, g.dims.ny + 2 * margin, g.dims.nz + margin + below};
  lat.density.assign(lat.dims.count(), 0.0f);
  lat.material.assign(lat.dims.count(), kMaterialMedium);
  bool wood = false;
  for (int k = 0; k < g.dims.nz; ++k)
    for (int j = 0; j < g.dims.ny; ++j)
      for (int i = 0; i < g.dims.nx; ++i) {
        const std::size_t src = g.dims.index(i, j, k);
        const std::size_t dst = lat.dims.index(i + margin, j + margin, k + below);
        lat.density[dst] = g.density[src];
        lat.material[dst] = g.material[src];
        wood = wood || (g.material[src] == kMaterialWood && g.density[src] > 0.0f);
      }
  lat.material_count = wood ? 2 : 1;
  if (ground_gap >= 0) {
    for (int j = 1; j < lat.dims.ny - 1; ++j)
      for (int i = 1; i < lat.dims.nx - 1; ++i) {
        lat.density[lat.dims.index(i, j, 1)] = 1.0f;
        lat.material[lat.dims.index(i, j, 1)] = kMaterialGround;
      }
    lat.material_count = kMaterialGround + 1;
  }
  return lat;
}

std::array<double, 19> system_boundary(const ModelPlan& mp, const SolutionPlan& s, int channel) {
  if (!mp.ground.on) return s.boundary;
  return with_open_ground(s.boundary, mp.ground.channel_albedo.at(static_cast<std::size_t>(channel)), mp.ground.share);
}

namespace {

// The most empty layers a model's lattice puts between its ground and its lowest medium layer.
constexpr long long kMaxGroundGap = 65536;

// Mean cosine of the discrete phase function seen from an axial direction.
double mean_cosine(double g) {
  double s = 0;
  for (int i = 1; i < d3q19::kQ; ++i) {
    const double len = std::sqrt(static_cast<double>(d3q19::length_sq(i)));
    s += d3q19::weight(i) * normalized_phase(g, i, 1) * (d3q19::cx(i) / len);
  }
  return s;
}

// Rough step count for the plain iteration to reach `tol` (shown by validate; the bake itself
// stops on the measured error): the slowest diffusion mode of the occupied box plus the
// per-step loss of absorbing materials, on top of the crossing time.
// The slowest decay rate per step of that estimate (1 - q of the plain iteration).
// `as_solved`: absorption as the LB model removes it (the calibrated model's remove_absorbed
// drains every medium, a cloud's too), for validate's estimate; without it, the material's own
// absorb flag, the contraction hint the convergence monitor was measured with.
double slowest_decay(const ModelPlan& mp, bool as_solved = false) {
  const Dims& d = mp.lattice.dims;
  double rho_sum = 0;
  std::size_t n = 0;
  for (float r : mp.grid.density)
    if (r > 0) {
      rho_sum += r;
      ++n;
    }
  if (n == 0) return 1.0;
  const double rho = rho_sum / static_cast<double>(n);
  double slowest = 1e300;
  for (int c = 0; c < kChannels; ++c) {
    const OpticalParams& p = mp.spec->material.channel[c];
    // eq. (4) with the transport (reduced) scattering of an anisotropic phase function
    const OpticalParams transport{p.sigma_a, p.sigma_s * (1.0 - mean_cosine(p.g)), 0.0};
    const bool absorbs = as_solved ? model_absorbs(mp.spec->material.absorbs, mp.model) : mp.spec->material.absorbs;
    const double diff = std::max(1e-6, diffusion_coefficient(transport, std::max(rho, 1e-6), absorbs));
    const double pi2 = 9.8696044010893586;
    const double decay_diffusion = diff * pi2 *
                                   (1.0 / (d.nx * d.nx) + 1.0 / (d.ny * d.ny) + 1.0 / (d.nz * d.nz));
    const double decay_absorb = absorbs ? rho * p.sigma_a : 0.0;
    slowest = std::min(slowest, decay_diffusion + decay_absorb);
  }
  return std::min(1.0, slowest);
}

double estimate_steps(const ModelPlan& mp, double tol) {
  return mp.lattice.dims.longest() + std::log(1.0 / tol) / slowest_decay(mp, /*as_solved=*/true);
}

bool same_channel(const ChannelMaterials& a, const ChannelMaterials& b, int count) {
  for (int k = 0; k < count; ++k)
    if (a.omega[k] != b.omega[k] || a.absorbs[k] != b.absorbs[k] || a.voxel_average[k] != b.voxel_average[k])
      return false;
  return true;
}

// The model's grid, checked (docs/model.md sec. 6), cropped to its occupied box and grown into
// its lattice.
// ground_index: the index coordinate (z) of the ground layer, or none for directly below the
// cropped grid; used only when the lattice stands on the scene's ground.
void plan_lattice(ModelPlan& mp, const Scene& scene, ModelGrid grid, std::vector<std::string>& warnings,
                  bool on_ground, std::optional<long long> ground_index = std::nullopt) {
  const ModelSpec& spec = *mp.spec;
  mp.grid = std::move(grid);
  mp.stats = check_stability(spec, mp.grid, scene, warnings);
  const std::array<double, 3> vs = mp.grid.voxel_size();
  const double lo = std::min({vs[0], vs[1], vs[2]}), hi = std::max({vs[0], vs[1], vs[2]});
  if (hi > lo * (1 + 1e-6))
    warnings.push_back("model '" + spec.name + "': voxels are " + message_number(vs[0]) + " x " + message_number(vs[1]) +
                       " x " + message_number(vs[2]) +
                       " (not cubic); the lattice treats them as cubes, so light travels as in the grid stretched "
                       "to cubic voxels: resample the grid to cubic voxels for physical light");
  const Dims full = mp.grid.dims;
  mp.savings.full_lattice = {full.nx + 2 * spec.margin, full.ny + 2 * spec.margin, full.nz + 2 * spec.margin};
  if (spec.crop) {
    mp.grid = crop_to_occupied(mp.grid);
    mp.savings.cropped = mp.grid.dims.count() != full.count();
  }
  mp.ground.on = on_ground && scene.ground.enabled;
  if (mp.ground.on && scene.solver.model.first_collision_on())
    throw_invalid("lattice '" + spec.name + "' stands on the ground, which calibration first_collision does not "
                  "model (its exact uncollided light has no reflecting ground); switch first_collision off, or let "
                  "the models float (\"ground\": false; the coarse forest lattices stand on the scene's ground "
                  "whenever it has one)",
                  {scene.file.string(), "/solver/calibration/first_collision", {}});
  if (mp.ground.on) {
    mp.ground.albedo = scene.ground.albedo;
    mp.ground.share = ground_share(ambient_boundary(scene.solver.model));
    const long long lowest = mp.grid.index_min[2];
    const long long gap = ground_index ? std::max(0LL, lowest - 1 - *ground_index) : 0;
    if (gap > kMaxGroundGap)  // before the int below, and before a lattice that tall is even sized
      throw_invalid("model '" + spec.name + "' stands " + std::to_string(gap) + " voxels above the ground (at most " +
                        std::to_string(kMaxGroundGap) +
                        " empty layers between the ground and the medium): lower the model or the ground's height",
                    {scene.file.string(), "/ground/height", {}});
    mp.ground.gap = static_cast<int>(gap);
    if (ground_index && lowest - 1 < *ground_index)
      warnings.push_back("'" + spec.name + "': the medium reaches " + std::to_string(*ground_index + 1 - lowest) +
                         " layer(s) below the ground's height; its ground is placed under its lowest layer instead");
  }
  // The lattice and what any bake of it holds on the host besides (one solution's totals, B00's
  // sum), checked before the lattice is built: a thin grid's margin can multiply its nodes.
  const Dims& gd = mp.grid.dims;
  const int gap = mp.ground.on ? mp.ground.gap : -1;
  const Dims ld{gd.nx + 2 * spec.margin, gd.ny + 2 * spec.margin, gd.nz + spec.margin + layers_below(spec.margin, gap)};
  check_host_memory(static_cast<double>(ld.count()) * host_bytes_per_node(scene.solver.model, scene.output.moments),
                    "model '" + spec.name + "' (a " + std::to_string(ld.nx) + "x" + std::to_string(ld.ny) + "x" +
                        std::to_string(ld.nz) + " lattice)",
                    "lower the resolution, crop the density source or lower margin", {scene.file.string(), spec.json_path, {}});
  mp.lattice = build_lattice(mp.grid, spec.margin, gap);
  for (int c = 0; c < 2; ++c) mp.lattice_index_min[c] = mp.grid.index_min[c] - spec.margin;
  mp.lattice_index_min[2] = mp.grid.index_min[2] - layers_below(spec.margin, gap);
}

// One system per distinct channel: a grey material solves once and fills R, G and B.
void plan_channels(ModelPlan& mp, const LbModel& model) {
  const ModelSpec& spec = *mp.spec;
  mp.model = model;
  for (int c = 0; c < kChannels; ++c) {
    ChannelMaterials ch;
    ch.omega[kMaterialMedium] = build_model_omega(spec.material.channel[c], model);
    ch.absorbs[kMaterialMedium] = model_absorbs(spec.material.absorbs, model);
    ch.omega[kMaterialWood] = build_model_omega(spec.wood_material.channel[c], model);
    ch.absorbs[kMaterialWood] = model_absorbs(spec.wood_material.absorbs, model);
    ch.voxel_average.fill(model.calibrated && model.voxel_average);
    if (mp.ground.on) {
      ch.omega[kMaterialGround] = ground_omega(mp.ground.albedo[c], mp.ground.share);
      ch.absorbs[kMaterialGround] = true;
      ch.voxel_average[kMaterialGround] = false;
    }
    int found = -1;
    for (std::size_t u = 0; u < mp.channels.size(); ++u)
      if (same_channel(mp.channels[u], ch, mp.lattice.material_count)) found = static_cast<int>(u);
    if (found < 0) {
      found = static_cast<int>(mp.channels.size());
      mp.channels.push_back(ch);
      if (mp.ground.on) mp.ground.channel_albedo.push_back(mp.ground.albedo[c]);
    }
    mp.channel_of[c] = found;
  }
  mp.savings.channels_solved = static_cast<int>(mp.channels.size());
}

// The solutions and their boundary values: the static sun's one, or the base solutions the scene
// (or --solutions) asks for, B00 marked derived when it is the sum of the other 18.
void plan_solutions(ModelPlan& mp, const Scene& scene, const PlanOverrides& ov) {
  if (scene.lighting.mode == LightingMode::Static) {
    if (ov.solutions) throw_invalid("--solutions applies to base lighting; this scene bakes static lighting",
                                    {scene.file.string(), "/lighting/mode", {}});
    if (scene.solver.model.first_collision_on())
      throw_invalid("calibration first_collision applies to the ambient solution B00 of \"mode\": \"base\"; this "
                    "scene bakes static lighting, which has none: switch first_collision off",
                    {scene.file.string(), "/solver/calibration/first_collision", {}});
    SolutionPlan s;
    s.index = -1;
    s.grid_name = "light";
    const Vec3d& t = scene.lighting.toward_sun;
    s.boundary = static_boundary(decompose_direction({-t.x, -t.y, -t.z}), scene.lighting.intensity, 0.0);
    const std::array<double, 19> ambient = ambient_boundary(scene.solver.model);
    for (int i = 0; i < 19; ++i) s.boundary[i] += scene.lighting.ambient * ambient[i];
    mp.solutions.push_back(s);
    return;
  }
  const std::vector<int>& wanted = ov.solutions.value_or(scene.lighting.solutions);
  bool all_directional = true;
  for (int j = 1; j < 19; ++j)
    all_directional = all_directional && std::find(wanted.begin(), wanted.end(), j) != wanted.end();
  if (!ov.solutions && scene.lighting.solutions_from_sun)
    for (int j = 0; j < 19; ++j)
      if (std::find(wanted.begin(), wanted.end(), j) == wanted.end()) mp.savings.solutions_left_out.push_back(j);
  for (int idx : wanted) {
    SolutionPlan s;
    s.index = idx;
    s.grid_name = base_grid_name(idx);
    s.direction = {d3q19::cx(idx), d3q19::cy(idx), d3q19::cz(idx)};
    s.boundary = idx == 0 ? ambient_boundary(scene.solver.model) : base_boundary(idx);
    // docs/model.md sec. 4: with an empty boundary layer (margin >= 1 guarantees it) the interior
    // of B_0 is the sum of the directional solutions, so it need not be solved.
    // (Not with first_collision: B00's uncollided light is then exact, not the sum of 18 beams.)
    s.derived = idx == 0 && all_directional && scene.lighting.ambient_from_sum && mp.spec->margin >= 1 &&
                !scene.solver.model.first_collision_on();
    mp.savings.ambient_from_sum = mp.savings.ambient_from_sum || s.derived;
    mp.solutions.push_back(s);
  }
}

// How the model is iterated, with what the chosen method and storage cannot do refused here,
// before any solving.
void plan_steps(ModelPlan& mp, const Scene& scene, const PlanOverrides& ov, Precision precision) {
  const int longest = mp.lattice.dims.longest();
  StepPolicy& st = mp.steps;
  st.mode = ov.mode.value_or(scene.solver.mode);
  st.method = ov.method.value_or(scene.solver.method);
  st.precision = precision;
  st.state = ov.state ? ov.state : scene.solver.state;
  if (st.method != SolverMethod::Plain && st.mode != IterationMode::Auto)
    throw_invalid(std::string("solver method ") + to_string(st.method) + " needs iterations \"auto\" (it stops on the error estimate), not " +
                      std::string(st.mode == IterationMode::Paper ? "\"paper\"" : "a fixed step count") +
                      "; set --iterations auto or solver.iterations \"auto\"",
                  {scene.file.string(), "/solver/method", {}});
  if (st.method != SolverMethod::Plain && precision == Precision::Float16)
    throw_invalid(std::string("solver method ") + to_string(st.method) + " runs on float32 storage, not float16; use method plain with float16, or "
                  "precision float32",
                  {scene.file.string(), "/solver/method", {}});
  if (precision == Precision::Float16)
    for (const SolutionPlan& s : mp.solutions)
      for (std::size_t c = 0; c < mp.channels.size(); ++c)
        for (double v : system_boundary(mp, s, static_cast<int>(c)))  // over a ground: with its reflection
          if (v > kFloat16MaxBoundary)
            throw_invalid("float16 storage holds values up to 65504, and a boundary value of " + message_number(v) +
                              " (intensity plus ambient) is above the " + message_number(kFloat16MaxBoundary) +
                              " that leaves room for; light is linear in them: scale intensity and ambient down "
                              "and the result up, or use float32",
                          {scene.file.string(), "/lighting/intensity", {}});
  if (st.method == SolverMethod::Dsa && scene.solver.model.first_collision_on())
    throw_invalid("solver method dsa does not take calibration first_collision's volume source; use --method plain "
                  "or bicgstab",
                  {scene.file.string(), "/solver/method", {}});
  st.tolerance = ov.tolerance.value_or(scene.solver.tolerance);
  if (st.method == SolverMethod::Dsa && st.tolerance < kDsaMinTolerance)
    throw_invalid("solver method dsa reaches about " + message_number(kDsaMinTolerance) +
                      " (its residual comes from float32 totals), not tolerance " + message_number(st.tolerance) +
                      "; use method bicgstab with precision float64 for tighter tolerances",
                  {scene.file.string(), "/solver/tolerance", {}});
  st.check_interval = scene.solver.check_interval > 0 ? scene.solver.check_interval
                                                      : std::clamp((longest + 2) / 4, 4, 16);
  st.min_steps = longest;
  st.max_steps = scene.solver.max_iterations > 0 ? scene.solver.max_iterations : 100 * longest;
  if (st.mode == IterationMode::Paper) st.fixed_steps = 2 * longest;
  if (st.mode == IterationMode::Fixed) st.fixed_steps = ov.mode ? ov.iterations : scene.solver.iterations;
  st.decay_hint = slowest_decay(mp);
  mp.estimated_steps = st.mode == IterationMode::Auto
                           ? std::clamp(estimate_steps(mp, st.tolerance), static_cast<double>(st.min_steps),
                                        static_cast<double>(st.max_steps))
                           : st.fixed_steps;
  // DSA removes the diffusive slow-down; where plain iteration converges within a few crossings
  // of the lattice (absorbing plants: light is absorbed before it diffuses far) its cycles cost
  // more than they save (docs/accuracy.md, "Cost against lattice size").
  if (st.method == SolverMethod::Dsa && mp.estimated_steps < kDsaMinCrossings * longest) {
    st.method = SolverMethod::Plain;
    st.method_note = "dsa asked, plain chosen: plain iteration needs about " +
                     std::to_string(static_cast<long long>(mp.estimated_steps)) + " steps, under " +
                     std::to_string(static_cast<int>(kDsaMinCrossings)) + " crossings of the lattice";
  }
}

// A coarse lattice as a model of its own: its spec (kept alive by the forest plan), grid and the
// scene's lighting and solver settings.
void add_coarse_plan(BakePlan& plan, const Scene& scene, const PlanOverrides& ov, const std::string& name,
                     CoarseGrid coarse, PlanRole role, const std::string& alone_model, double cell) {
  auto spec = std::make_shared<ModelSpec>();
  spec->name = name;
  spec->material = coarse.medium;
  spec->wood_material = coarse.wood;
  spec->margin = 1;
  spec->crop = true;
  spec->json_path = "/forest/coarse";
  spec->density.json_path = "/forest/coarse";
  plan.forest->coarse_specs.push_back(spec);
  ModelPlan mp;
  mp.spec = spec.get();
  mp.role = role;
  mp.alone_model = alone_model;
  // The forest's ground is the highest layer of cells that no medium above the ground's height
  // reaches: a voxel centre at z deposits into cells floor(z / cell) and the one above
  // (forest_coarse.cpp), so the layer under floor(height / cell). A model alone stands directly on
  // its ground, as its instances stand on the forest's.
  std::optional<long long> ground_index;
  if (role == PlanRole::ForestCoarse)
    ground_index = static_cast<long long>(std::floor(scene.ground.height / cell + 1e-9)) - 1;
  bool on_ground = true;
  for (const ModelSpec& m : scene.models)
    if (role == PlanRole::ForestAlone && m.name == alone_model) on_ground = m.ground;
  plan_lattice(mp, scene, std::move(coarse.grid), plan.warnings, on_ground, ground_index);
  plan_channels(mp, scene.solver.model);
  mp.moments = scene.output.moments;
  plan_solutions(mp, scene, ov);
  PlanOverrides coarse_ov = ov;
  coarse_ov.tolerance = scene.forest.coarse_tolerance;
  plan_steps(mp, scene, coarse_ov, plan.precision);
  plan.models.push_back(std::move(mp));
}

// The forest's instances and, unless the scene turns it off, its coarse lattices (docs/forest.md).
// A default cell size that makes a cell too dense shrinks until cells pass.
void plan_forest(BakePlan& plan, const Scene& scene, const PlanOverrides& ov) {
  ForestPlan& fp = plan.forest.emplace();
  fp.instances = forest_instances(scene.forest, scene.file.string());
  fp.coarse = scene.forest.coarse;
  if (!fp.coarse) return;
  std::vector<ForestModel> models;
  for (const ModelPlan& mp : plan.models) models.push_back({mp.spec, &mp.grid});
  const Location where{scene.file.string(), "/forest/coarse/cell_size", {}};
  double cell = scene.forest.cell_size;
  fp.cell_size_note = "cell_size from the scene";
  if (!(cell > 0)) {
    cell = default_coarse_cell_size(models, fp.instances);
    fp.cell_size_note = "default: " + message_number(kDefaultCoarseCellVoxels) + " x the coarsest model voxel x the largest scale";
  }
  CoarseForest cf = build_coarse_forest(models, fp.instances, cell, where);
  auto warn_clamped = [&](const CoarseGrid& g, const std::string& what) {
    if (g.clamped_cells > 0)
      plan.warnings.push_back(what + ": " + std::to_string(g.clamped_cells) + " cell(s) deeper than " +
                              message_number(kMaxCoarseOpticalDepth) + " (up to " + message_number(g.max_optical_depth) +
                              ": solid wood, dense foliage) clamped to it; a smaller forest.coarse.cell_size clamps fewer");
  };
  warn_clamped(cf.forest, "coarse forest grid");
  fp.cell_size = cell;
  for (std::size_t m = 0; m < cf.alone.size(); ++m) warn_clamped(cf.alone[m], "coarse grid of '" + scene.models[m].name + "' alone");
  const std::size_t fine_models = plan.models.size();
  add_coarse_plan(plan, scene, ov, kForestCoarseName, std::move(cf.forest), PlanRole::ForestCoarse, {}, cell);
  for (std::size_t m = 0; m < fine_models; ++m) {
    const std::string model = scene.models[m].name;
    add_coarse_plan(plan, scene, ov, forest_alone_name(model), std::move(cf.alone[m]), PlanRole::ForestAlone, model,
                    cell);
  }
}

}  // namespace

std::string forest_alone_name(const std::string& model) { return std::string(kForestCoarseName) + ".alone." + model; }

std::vector<std::string> lattice_names(const Scene& scene) {
  std::vector<std::string> names;
  for (const ModelSpec& spec : scene.models) names.push_back(spec.name);
  if (!scene.forest.empty() && scene.forest.coarse) {
    names.push_back(kForestCoarseName);
    for (const ModelSpec& spec : scene.models) names.push_back(forest_alone_name(spec.name));
  }
  return names;
}

BakePlan plan_without_models(const Scene& scene, const PlanOverrides& ov) {
  BakePlan plan;
  plan.scene = &scene;
  plan.precision = ov.precision.value_or(scene.solver.precision);
  return plan;
}

ModelPlan plan_model(BakePlan& plan, const ModelSpec& spec, ModelGrid grid, const PlanOverrides& ov) {
  const Scene& scene = *plan.scene;
  ModelPlan mp;
  mp.spec = &spec;
  plan_lattice(mp, scene, std::move(grid), plan.warnings, spec.ground);
  plan_channels(mp, scene.solver.model);
  mp.moments = scene.output.moments;
  plan_solutions(mp, scene, ov);
  plan_steps(mp, scene, ov, plan.precision);
  return mp;
}

BakePlan make_plan(const Scene& scene, const PlanOverrides& ov, const RunContext& ctx) {
  BakePlan plan = plan_without_models(scene, ov);
  // A scene model as the only lattice needs its own grid; a coarse forest lattice every model's.
  bool only_model = false;
  if (ov.only) {
    const std::vector<std::string> names = lattice_names(scene);
    if (std::find(names.begin(), names.end(), *ov.only) == names.end()) {
      std::string allowed;
      for (const std::string& n : names) allowed += (allowed.empty() ? "" : ", ") + n;
      throw_invalid("--only '" + *ov.only + "' is not a lattice of this scene; allowed: " + allowed,
                    {scene.file.string(), {}, {}});
    }
    only_model = std::any_of(scene.models.begin(), scene.models.end(),
                             [&](const ModelSpec& m) { return m.name == *ov.only; });
  }
  plan.models.reserve(scene.models.size());
  for (const ModelSpec& spec : scene.models) {
    if (only_model && spec.name != *ov.only) continue;
    // A procedural shape's least occupied box (what crop cannot cut) must fit before it is
    // generated: at resolution 1024 generating alone takes minutes and gigabytes.
    if (spec.density.type == SourceType::Procedural) {
      const Dims least = procedural_least_occupied(spec.density.procedural);
      const Dims ld{least.nx + 2 * spec.margin, least.ny + 2 * spec.margin, least.nz + 2 * spec.margin};
      check_host_memory(static_cast<double>(ld.count()) * host_bytes_per_node(scene.solver.model, scene.output.moments),
                        "model '" + spec.name + "' (at least a " + std::to_string(ld.nx) + "x" + std::to_string(ld.ny) +
                            "x" + std::to_string(ld.nz) + " lattice: the box its procedural " +
                            spec.density.procedural.shape + " is sure to fill at resolution " +
                            std::to_string(spec.density.procedural.resolution) + ")",
                        "lower the resolution", {scene.file.string(), spec.density.json_path + "/resolution", {}});
    }
    plan.models.push_back(plan_model(plan, spec, load_model_grid(spec, scene, ctx), ov));
  }
  // A model unit of a forest with coarse lattices leaves the forest (its cell size needs every
  // grid) to the forest units.
  if (!scene.forest.empty() && !(only_model && scene.forest.coarse)) plan_forest(plan, scene, ov);
  if (ov.only)
    plan.models.erase(std::remove_if(plan.models.begin(), plan.models.end(),
                                     [&](const ModelPlan& mp) { return mp.spec->name != *ov.only; }),
                      plan.models.end());
  return plan;
}

std::array<OpticalParams, kMaxMaterials> channel_optics(const ModelPlan& mp, int channel) {
  int colour = 0;
  while (colour < 2 && mp.channel_of[static_cast<std::size_t>(colour)] != channel) ++colour;
  std::array<OpticalParams, kMaxMaterials> o{};
  o[kMaterialMedium] = mp.spec->material.channel[static_cast<std::size_t>(colour)];
  o[kMaterialWood] = mp.spec->wood_material.channel[static_cast<std::size_t>(colour)];
  return o;
}

double host_bytes_per_node(const LbModel& model, bool moments) {
  return kHostBytesPerLatticeNode + (model.first_collision_on() ? kFirstCollisionBytesPerNode : 0.0) +
         (moments ? kMomentsBytesPerNode : 0.0);
}

}  // namespace lblight
