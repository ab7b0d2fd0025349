// lblight bake: scene in, base-solution volumes and a manifest out.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <future>
#include <iostream>
#include <memory>

#include <unistd.h>

#include "apps/lblight/bake_progress.h"
#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "apps/lblight/solve_options.h"
#include "lblight/core/error.h"
#include "lblight/core/isolated_call.h"
#include "lblight/io/output_dir.h"
#include "lblight/pipeline/run_bake.h"
#include "lblight/pipeline/work_units.h"

namespace lblight::cli {
namespace {

struct BakeArgs {
  SolveOptions solve;
  std::string output;
  std::string only;     // one work unit: a partial output (docs/scale-out.md)
  bool resume = false;  // skip units whose partial is finished
};

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// --resume: whether `dir` holds the finished partial of `unit` (unit_record); logs either way.
bool unit_done(const nlohmann::json& unit, const std::filesystem::path& dir) {
  const std::string name = unit["name"], hash = unit["hash"];
  const PartCheck c = check_part(dir, name, hash, /*verify_checksums=*/true);
  if (c.state == PartState::Done) {
    spdlog::info("unit '{}': finished in {} (inputs hash {}), not recomputed", name, dir.string(), hash);
    return true;
  }
  spdlog::info("unit '{}': {}; baking it", name,
               c.state == PartState::Absent ? "no partial output yet in " + dir.string()
                                            : dir.string() + " is not its finished partial (" + c.why + ")");
  return false;
}

int run_bake(const BakeArgs& args, const GlobalOptions& global) {
  const auto t0 = std::chrono::steady_clock::now();
  const Scene scene = load_scene(args.solve.scene);
  PlanOverrides ov = args.solve.overrides();
  const UnitSpec only = args.only.empty() ? UnitSpec{} : parse_unit(args.only);
  if (!only.name.empty()) ov.only = only.name;
  const std::filesystem::path target = output_folder_path(
      args.output.empty() ? std::filesystem::path(std::filesystem::path(args.solve.scene).stem().string() + "-bake")
                          : std::filesystem::path(args.output));
  check_scene_output(scene, target);
  StagedDirectory::check_target(target, OutputKind::Bake);  // fail before any solving

  // Starting a GPU (driver and context, 0.1-1 s) overlaps loading and voxelising the models; a
  // failure to start is reported once the plan is made.
  std::future<std::unique_ptr<Backend>> starting;
  if (args.solve.backend != "cpu" && args.solve.backend != "mpi")
    starting = std::async(std::launch::async, [&args] {
      const auto guard = hold_forks();  // the driver loads libraries: no .vdb probe forks meanwhile
      return args.solve.make_backend("bake");
    });
  BakePlan plan = make_plan(scene, ov, args.solve.run_context());
  const double planned = seconds_since(t0);
  auto backend = starting.valid() ? starting.get() : args.solve.make_backend("bake");
  spdlog::debug("start-up: scene loaded and planned (models voxelised) in {:.3f} s, backend ready at {:.3f} s",
                planned, seconds_since(t0));
  if (!backend->occupies_host_cores()) keep_freed_host_memory();
  if (!backend->supports(plan.precision))
    throw_invalid(std::string("the ") + backend->name() + " backend cannot store " + to_string(plan.precision) +
                      "; allowed: float32, float64 or float16 on cpu (float16 where the compiler has _Float16), float32 or float16 on cuda",
                  {scene.file.string(), "/solver/precision", {}});

  // A distributed backend's other ranks run the same bake into a folder of their own, removed after.
  std::filesystem::path out = target;
  if (!backend->writes_output()) {
    if (args.resume || !only.name.empty())
      throw_invalid("--backend " + backend->name() + " bakes the whole scene on every rank: not with --only or --resume");
    out = std::filesystem::temp_directory_path() / ("lblight-rank-output-" + std::to_string(::getpid()));
    spdlog::set_level(spdlog::level::warn);  // rank 0 tells the progress
  }
  for (const ModelPlan& mp : plan.models)
    if (mp.steps.method != SolverMethod::Plain && backend->name() == "mpi")
      throw_invalid(std::string("--backend mpi runs plain iteration, not method ") + to_string(mp.steps.method) +
                        "; use --method plain",
                    {scene.file.string(), "/solver/method", {}});

  spdlog::info("scene '{}' ({}), backend: {}", scene.name, scene.file.string(), backend->description());
  for (const std::string& w : plan.warnings) spdlog::warn("{}", w);
  std::size_t total = 0;
  for (const ModelPlan& mp : plan.models) total += mp.solutions.size();
  ProgressLog log(total);
  const RunContext ctx = args.solve.run_context();

  if (!only.name.empty()) {  // one unit (or some of its solutions): its partial output
    const nlohmann::json unit = unit_record(plan, plan.models[0], backend->name(), ov, only.solutions);
    if (args.resume && unit_done(unit, target)) {
      std::cout << "unit '" << args.only << "' already done in " << target.string() << ": not recomputed\n";
      return 0;
    }
    run_bake(plan, *backend, target, global.command_line, log, ctx, seconds_since(t0), unit);
  } else if (args.resume) {
    // Every unit into <target>.parts (kept until the merge), so that a bake killed mid-way
    // resumes at the first unfinished unit; then the parts merge into target.
    const std::filesystem::path parts_dir = target.string() + ".parts";
    std::filesystem::create_directories(parts_dir);
    std::vector<std::filesystem::path> parts;
    std::vector<BakePlan> unit_plans;  // kept: the log holds their models until the summary
    unit_plans.reserve(plan.models.size());
    for (std::size_t i = 0; i < plan.models.size(); ++i) {
      parts.push_back(parts_dir / plan.models[i].spec->name);
      const nlohmann::json unit = unit_record(plan, plan.models[i], backend->name());
      if (unit_done(unit, parts.back())) continue;
      unit_plans.push_back(unit_plan(plan, i));
      run_bake(unit_plans.back(), *backend, parts.back(), global.command_line, log, ctx, seconds_since(t0), unit);
    }
    MergeOptions merge{global.command_line, scene.hash, scene.name, scene.file.string(), lattice_names(scene),
                       /*move_files=*/true};
    merge_parts(parts, target, merge, ctx);
    std::error_code ec;
    std::filesystem::remove_all(parts_dir, ec);
    if (ec) spdlog::warn("could not remove {}: {}", parts_dir.string(), ec.message());
  } else {
    run_bake(plan, *backend, out, global.command_line, log, ctx, seconds_since(t0));
  }
  if (out != target) {
    std::error_code ec;
    std::filesystem::remove_all(out, ec);
    return 0;
  }

  Table table({"model", "solution", "direction", "iterations", "seconds", "error estimate"});
  for (const auto& row : log.rows()) table.add(row);
  std::cout << table.str() << log.done() << " solution(s) in " << format_seconds(seconds_since(t0))
            << " s; output: " << target.string() << "\n";
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
  cmd->add_option("--only", args->only,
                  "Bake one work unit, MODEL[:SOLUTIONS]: a model of the scene or a coarse forest lattice (forest, "
                  "forest.alone.<model>), optionally only some of its solutions (whole batches, e.g. tree:1-6); -o "
                  "then receives its partial output, which `lblight merge` combines with the others' "
                  "(docs/scale-out.md)")
      ->check(kNonEmpty);
  cmd->add_flag("--resume", args->resume,
                "Do not recompute finished units: with --only, exit at once when -o holds this unit's finished "
                "partial (same inputs hash, files intact); without, bake unit by unit into OUTDIR.parts, keeping "
                "those already there, then merge them into OUTDIR");
  return {cmd, [args, &global] { return run_bake(*args, global); }};
}

}  // namespace lblight::cli
