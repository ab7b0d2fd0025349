// lblight bake: scene in, base-solution volumes and a manifest out.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <future>
#include <iostream>
#include <memory>

#include "apps/lblight/bake_progress.h"
#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "apps/lblight/solve_options.h"
#include "lblight/core/error.h"
#include "lblight/core/isolated_call.h"
#include "lblight/io/output_dir.h"
#include "lblight/pipeline/run_bake.h"

namespace lblight::cli {
namespace {

struct BakeArgs {
  SolveOptions solve;
  std::string output;
};

int run_bake(const BakeArgs& args, const GlobalOptions& global) {
  const auto t0 = std::chrono::steady_clock::now();
  const Scene scene = load_scene(args.solve.scene);
  const PlanOverrides ov = args.solve.overrides();
  const std::filesystem::path target = output_folder_path(
      args.output.empty() ? std::filesystem::path(std::filesystem::path(args.solve.scene).stem().string() + "-bake")
                          : std::filesystem::path(args.output));
  StagedDirectory::check_target(target, OutputKind::Bake);  // fail before any solving

  // Starting a GPU (driver and context, 0.1-1 s) overlaps loading and voxelising the models; a
  // failure to start is reported once the plan is made.
  std::future<std::unique_ptr<Backend>> starting;
  if (args.solve.backend != "cpu")
    starting = std::async(std::launch::async, [&args] {
      const auto guard = hold_forks();  // the driver loads libraries: no .vdb probe forks meanwhile
      return args.solve.make_backend();
    });
  const BakePlan plan = make_plan(scene, ov, args.solve.run_context());
  auto backend = starting.valid() ? starting.get() : args.solve.make_backend();
  if (!backend->supports(plan.precision))
    throw_invalid(std::string("the ") + backend->name() + " backend cannot store " + to_string(plan.precision) +
                      "; allowed: float32 or float64 on cpu, float32 or float16 on cuda",
                  {scene.file.string(), "/solver/precision", {}});

  spdlog::info("scene '{}' ({}), backend: {}", scene.name, scene.file.string(), backend->description());
  for (const std::string& w : plan.warnings) spdlog::warn("{}", w);
  std::size_t total = 0;
  for (const ModelPlan& mp : plan.models) total += mp.solutions.size();

  ProgressLog log(total);
  const double before = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  run_bake(plan, *backend, target, global.command_line, log, args.solve.run_context(), before);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  Table table({"model", "solution", "direction", "iterations", "seconds", "error estimate"});
  for (const auto& row : log.rows()) table.add(row);
  std::cout << table.str() << total << " solution(s) in " << format_seconds(seconds) << " s; output: "
            << target.string() << "\n";
  return 0;
}

}  // namespace

Command add_bake_command(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<BakeArgs>();
  CLI::App* cmd = app.add_subcommand(
      "bake",
      "Solve the scene's lighting and write OUTDIR/<model>.vdb (grids density, brown, B00..B18 or light) and "
      "OUTDIR/manifest.json. Progress goes to stderr, a summary table to stdout. The output directory appears only "
      "when complete.");
  args->solve.add_to(*cmd);
  cmd->add_option("-o,--output", args->output, "Output directory (default: <scene name>-bake); replaced if it holds "
                                                "a previous lblight output")
      ->check(kNonEmpty);
  return {cmd, [args, &global] { return run_bake(*args, global); }};
}

}  // namespace lblight::cli
