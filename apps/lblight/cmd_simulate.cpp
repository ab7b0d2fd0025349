// lblight simulate: runs the gas sources of a scene ([Wei2004], docs/fluid.md) and writes each
// frame as an OpenVDB volume (density = smoke, temperature, velocity), plus simulation.json.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/core/error.h"
#include "lblight/core/version.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/vdb_io.h"
#include "lblight/scene/gas_source.h"
#include "lblight/scene/scene.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct SimulateArgs {
  std::string scene, output, model;
  int frames = 0;
};

std::string frame_file(const std::string& model, int frame) {
  char buf[32];
  std::snprintf(buf, sizeof buf, ".%04d.vdb", frame);
  return model + buf;
}

int run_simulate(const SimulateArgs& a, const GlobalOptions& global) {
  const Scene scene = load_scene(a.scene);
  std::vector<const ModelSpec*> gases;
  for (const ModelSpec& m : scene.models)
    if (m.density.type == SourceType::Gas && (a.model.empty() || m.name == a.model)) gases.push_back(&m);
  if (gases.empty())
    throw_invalid(a.model.empty() ? "the scene has no model with a \"gas\" density source"
                                  : "no gas model '" + a.model + "' in the scene",
                  {a.scene, {}, {}});
  const fs::path target = output_folder_path(a.output);
  StagedDirectory::check_target(target, OutputKind::Simulation);
  StagedDirectory out(target, OutputKind::Simulation);
  RunContext ctx;
  ctx.cancel = &g_interrupted;
  nlohmann::json record = {{"lblight_version", kVersion}, {"command", global.command_line}, {"scene", a.scene},
                           {"frames", nlohmann::json::array()}};
  for (const ModelSpec* m : gases) {
    GasSource src = m->density.gas;
    const int frames = a.frames > 0 ? a.frames : src.frames;
    const Location where{scene.file.string(), m->density.json_path, {}};
    const Dims dims{src.resolution[0], src.resolution[1], src.resolution[2]};
    const auto t0 = std::chrono::steady_clock::now();
    run_gas(src, frames, where, ctx, [&](int f, const fluid::GasSolver& solver) {
      const ModelGrid density = gas_density(src, solver);
      const std::vector<double> temp = solver.temperature();
      const auto vel = solver.velocity();
      std::vector<float> t(temp.begin(), temp.end());
      std::array<std::vector<float>, 3> v;
      for (int c = 0; c < 3; ++c) v[c].assign(vel[c].begin(), vel[c].end());
      const double h = density.index_to_world[0];
      // Velocity in world units per lattice step (lattice units x node size).
      for (auto& c : v)
        for (float& x : c) x = static_cast<float>(x * h);
      nlohmann::json meta = {{"lblight_version", kVersion}, {"lblight_frame", f}, {"lblight_steps", f * src.steps_per_frame},
                             {"lblight_model", m->name}};
      std::vector<DenseGridOut> grids = {
          {"density", &density.density, nullptr, true, {{"lblight_meaning", "smoke concentration / inlet smoke, clamped to [0, 1]"}}},
          {"temperature", &t, nullptr, false, {{"lblight_units", "degrees"}}},
          {"velocity", nullptr, &v, false, {{"lblight_units", "world units per lattice step"}}}};
      std::vector<float> obstacle;
      if (!src.obstacles.empty()) {
        for (std::uint8_t b : solver.settings().solid) obstacle.push_back(b ? 1.0f : 0.0f);
        grids.push_back({"obstacle", &obstacle, nullptr, false, {{"lblight_meaning", "1 on solid (bounce-back) nodes"}}});
      }
      const std::string name = frame_file(m->name, f);
      write_vdb(out.path(name), density.frame(), grids, meta);
      double smoke = 0;
      for (float d : density.density) smoke += d;
      record["frames"].push_back({{"model", m->name}, {"frame", f}, {"file", name}, {"steps", f * src.steps_per_frame},
                                  {"smoke_sum", smoke}});
      spdlog::info("simulate: {} frame {}/{} ({} steps)", m->name, f, frames, f * src.steps_per_frame);
    });
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double updates = static_cast<double>(dims.count()) * frames * src.steps_per_frame;
    std::cout << m->name << ": " << frames << " frame(s) of " << dims.nx << "x" << dims.ny << "x" << dims.nz << " nodes in " << seconds << " s (" << updates / seconds / 1e6
              << " M fluid node updates per second)\n";
  }
  write_file_atomically(out.path("simulation.json"), record.dump(1) + "\n");
  out.commit();
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
      "obstacles) with simulation.json. "
      "`bake` lights the frame the source names. docs/fluid.md.");
  cmd->add_option("scene", args->scene, "Scene file (.json)")->required();
  cmd->add_option("-o,--output", args->output, "Output folder")->required()->check(kNonEmpty);
  cmd->add_option("--model", args->model, "Only this gas model")->check(kNonEmpty);
  cmd->add_option("--frames", args->frames, "Frames to write (default: the source's)")->check(CLI::Range(1, 10000));
  return {cmd, [args, &global] { return run_simulate(*args, global); }};
}

}  // namespace lblight::cli
