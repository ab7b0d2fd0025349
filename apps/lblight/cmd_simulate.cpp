// lblight simulate: runs the gas sources of a scene ([Wei2004], docs/fluid.md) and writes each
// frame as an OpenVDB volume (density = smoke, temperature, velocity), plus simulation.json; with
// --light, also the frame's lighting, each frame's solve started from the previous frame's.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <set>

#include "apps/lblight/bake_progress.h"
#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "apps/lblight/solve_options.h"
#include "lblight/core/error.h"
#include "lblight/core/version.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/vdb_io.h"
#include "lblight/pipeline/gas_frames.h"
#include "lblight/scene/gas_source.h"
#include "lblight/scene/scene.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct SimulateArgs {
  SolveOptions solve;  // the scene; the rest applies to --light
  std::string output, model;
  int frames = 0;
  bool light = false, cold = false;
};

// A frame's fields besides the smoke (temperature, velocity, obstacle) on the gas nodes, and what
// its file and manifest entry say about it.
ModelExtras frame_fields(const ModelSpec& m, const GasSource& src, int f, const fluid::GasSolver& solver, double h) {
  ModelExtras e;
  const std::vector<double> temp = solver.temperature();
  e.grids.push_back({"temperature", std::vector<float>(temp.begin(), temp.end()), {}, {{"lblight_units", "degrees"}}});
  ModelExtras::Grid v{"velocity", {}, {}, {{"lblight_units", "world units per lattice step"}}};
  const auto vel = solver.velocity();
  // Velocity in world units per lattice step (lattice units x node size).
  for (int c = 0; c < 3; ++c)
    for (double x : vel[static_cast<std::size_t>(c)]) v.rgb[static_cast<std::size_t>(c)].push_back(static_cast<float>(x * h));
  e.grids.push_back(std::move(v));
  if (!src.obstacles.empty()) {
    ModelExtras::Grid o{"obstacle", {}, {}, {{"lblight_meaning", "1 on solid (bounce-back) nodes"}}};
    for (std::uint8_t b : solver.settings().solid) o.scalar.push_back(b ? 1.0f : 0.0f);
    e.grids.push_back(std::move(o));
  }
  const long long steps = static_cast<long long>(f) * src.steps_per_frame;
  e.file_metadata = {{"lblight_frame", f}, {"lblight_steps", steps}, {"lblight_gas_model", m.name}};
  e.manifest = {{"gas_model", m.name}, {"frame", f}, {"gas_steps", steps}};
  return e;
}

// Where the frames go: a plain staged folder, or (--light) a bake output that also holds them.
struct SimulationOutput {
  std::optional<StagedDirectory> plain;
  std::unique_ptr<BakeOutput> lit;
  fs::path path(const std::string& name) const { return lit ? lit->path(name) : plain->path(name); }
};

int run_simulate(const SimulateArgs& a, const GlobalOptions& global) {
  const auto t_start = Clock::now();
  const Scene scene = load_scene(a.solve.scene);
  std::vector<const ModelSpec*> gases;
  for (const ModelSpec& m : scene.models)
    if (m.density.type == SourceType::Gas && (a.model.empty() || m.name == a.model)) gases.push_back(&m);
  if (gases.empty())
    throw_invalid(a.model.empty() ? "the scene has no model with a \"gas\" density source"
                                  : "no gas model '" + a.model + "' in the scene",
                  {a.solve.scene, {}, {}});
  const fs::path target = output_folder_path(a.output);
  check_scene_output(scene, target);
  StagedDirectory::check_target(target, OutputKind::Simulation);
  const RunContext ctx = a.solve.run_context();
  const PlanOverrides ov = a.solve.overrides();

  // --light: the frames' plans share the scene and precision; the backend starts once.
  BakePlan sequence = plan_without_models(scene, ov);
  std::unique_ptr<Backend> backend;
  SimulationOutput out;
  if (a.light) {
    backend = a.solve.make_backend("simulate");
    // as bake: every frame reads totals and states back from the device (unmeasured here; the
    // same first-touch cost bake measured per batch, docs/performance.md)
    if (!backend->occupies_host_cores()) keep_freed_host_memory();
    if (!backend->supports(sequence.precision))
      throw_invalid(std::string("the ") + backend->name() + " backend cannot store " + to_string(sequence.precision) +
                        "; allowed: " + supported_precisions(*backend),
                    {scene.file.string(), "/solver/precision", {}});
    spdlog::info("lighting every frame on {} ({})", backend->description(),
                 a.cold ? "each frame from zero" : "each frame from the previous one's light");
    out.lit = std::make_unique<BakeOutput>(sequence, target,
                                           BakeRunInfo{global.command_line, backend->name(), backend->description(), {}, {}},
                                           !backend->occupies_host_cores(), OutputKind::Simulation);
  } else {
    out.plain.emplace(target, OutputKind::Simulation);
  }
  ProgressLog log(0);
  std::set<std::string> warned;  // frames repeat their plan's warnings: each is shown once

  nlohmann::json record = {{"lblight_version", kVersion}, {"command", global.command_line}, {"scene", a.solve.scene},
                           {"frames", nlohmann::json::array()}};
  Table lit_table({"frame", "light steps", "start", "seconds", "error estimate"});
  for (const ModelSpec* m : gases) {
    const GasSource& src = m->density.gas;
    const int frames = a.frames > 0 ? a.frames : src.frames;
    const Location where{scene.file.string(), m->density.json_path, {}};
    const Dims dims{src.resolution[0], src.resolution[1], src.resolution[2]};
    std::optional<GasFrameLighting> lighting;
    if (a.light) lighting.emplace(sequence, *m, ov, *backend, !a.cold);
    const auto t0 = Clock::now();
    double frame_seconds = 0;  // writing and lighting frames, not simulating
    int light_steps = 0;
    run_gas(src, frames, where, ctx, [&](int f, const fluid::GasSolver& solver) {
      const auto t_frame = Clock::now();
      ModelGrid smoke = gas_density(src, solver);
      ModelExtras fields = frame_fields(*m, src, f, solver, smoke.index_to_world[0]);
      double smoke_sum = 0;
      for (float d : smoke.density) smoke_sum += d;
      const std::string name = gas_frame_name(m->name, f) + ".vdb";
      nlohmann::json entry = {{"model", m->name}, {"frame", f}, {"file", name}, {"steps", f * src.steps_per_frame},
                              {"smoke_sum", smoke_sum}};
      if (lighting) {
        const GasFrameLit lit = lighting->light(f, std::move(smoke), std::move(fields), *out.lit, log, ctx);
        for (const std::string& w : sequence.warnings)
          if (warned.insert(w).second) spdlog::warn("{}", w);
        entry["light"] = {{"steps", lit.steps}, {"seconds", lit.seconds}, {"error_estimate", lit.error_estimate},
                          {"warm_start", lit.warm}};
        lit_table.add({gas_frame_name(m->name, f), std::to_string(lit.steps), lit.warm ? "warm" : "cold",
                       format_seconds(lit.seconds), format_error(lit.error_estimate)});
        light_steps += lit.steps;
      } else {
        std::vector<DenseGridOut> grids = {{"density", &smoke.density, nullptr, true,
                                            {{"lblight_meaning", "smoke concentration / inlet smoke, clamped to [0, 1]"}}}};
        for (const ModelExtras::Grid& g : fields.grids) {
          const bool scalar = !g.scalar.empty();
          grids.push_back({g.name, scalar ? &g.scalar : nullptr, scalar ? nullptr : &g.rgb, false, g.metadata});
        }
        nlohmann::json meta = fields.file_metadata;
        meta["lblight_version"] = kVersion;
        meta["lblight_model"] = m->name;
        write_vdb(out.path(name), smoke.frame(), grids, meta);
      }
      record["frames"].push_back(entry);
      spdlog::info("simulate: {} frame {}/{} ({} steps)", m->name, f, frames, f * src.steps_per_frame);
      frame_seconds += since(t_frame);
    });
    const double seconds = since(t0) - frame_seconds;
    const double updates = static_cast<double>(dims.count()) * frames * src.steps_per_frame;
    std::cout << m->name << ": " << frames << " frame(s) of " << dims.nx << "x" << dims.ny << "x" << dims.nz
              << " nodes simulated in " << format_seconds(seconds) << " s (" << updates / seconds / 1e6
              << " M fluid node updates per second)\n";
    if (lighting)
      std::cout << m->name << ": lit in " << format_seconds(frame_seconds) << " s, "
                << static_cast<double>(light_steps) / frames << " light steps per frame ("
                << (a.cold ? "each from zero" : "each from the previous frame") << ")\n";
  }
  throw_if_interrupted();
  write_file_atomically(out.path("simulation.json"), record.dump(1) + "\n");
  if (out.lit) {
    std::cout << lit_table.str();
    out.lit->commit(since(t_start));
  } else {
    out.plain->commit();
  }
  std::cout << "wrote " << target.string() << "\n";
  return 0;
}

}  // namespace

Command add_simulate_command(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<SimulateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "simulate",
      "Run the scene's gas sources ([Wei2004]: D3Q19 BGK flow with buoyancy, smoke and temperature carried by it) and "
      "write every frame as OUT/<model>.NNNN.vdb (density = smoke, temperature, velocity, obstacle when there are "
      "obstacles) with simulation.json: a sequence Blender and Houdini load as one. With --light, every frame is "
      "also lit with the scene's lighting and its file holds the light as a bake's does (density = the density lit, "
      "density_scale applied; `light` or B00..B18), with manifest.json naming each frame as a model <model>.NNNN: "
      "`lblight render OUT/<model>.NNNN.vdb` draws a frame. Each frame's solve starts from the previous frame's light "
      "(--cold: from zero). `bake` lights only the frame the source names. docs/fluid.md.");
  args->solve.add_to(*cmd);
  cmd->add_option("-o,--output", args->output, "Output folder")->required()->check(kNonEmpty);
  cmd->add_option("--model", args->model, "Only this gas model")->check(kNonEmpty);
  cmd->add_option("--frames", args->frames, "Frames to write (default: the source's)")->check(CLI::Range(1, 10000));
  cmd->add_flag("--light", args->light,
                "Light every frame (the scene's lighting and solver; --backend, --tolerance and the other solve "
                "options apply), on the whole gas box so that each frame starts from the previous frame's light");
  cmd->add_flag("--cold", args->cold, "With --light: start every frame's lighting from zero (to measure what warm "
                                      "starts save; the same light within the tolerance)");
  return {cmd, [args, &global] {
            if (args->cold && !args->light) throw_invalid("--cold applies to --light; add --light or drop --cold");
            return run_simulate(*args, global);
          }};
}

}  // namespace lblight::cli
