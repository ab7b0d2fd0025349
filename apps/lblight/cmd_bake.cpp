// lblight bake: scene in, base-solution volumes and a manifest out.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <future>
#include <iostream>
#include <memory>

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

// Progress on stderr: one line per solution, and a heartbeat every few seconds on long ones.
class ProgressLog final : public BakeObserver {
 public:
  explicit ProgressLog(std::size_t total) : total_(total) {}

  void model_started(const ModelPlan& mp, const Backend& backend, std::size_t bytes) override {
    const Dims& d = mp.lattice.dims;
    spdlog::info("model '{}': {}x{}x{} lattice, {} solution(s) x {} distinct channel(s) on {} ({} for the lattice)",
                 mp.spec->name, d.nx, d.ny, d.nz, mp.solutions.size(), mp.channels.size(), backend.name(),
                 format_bytes(static_cast<double>(bytes)));
    if (!mp.steps.method_note.empty()) spdlog::info("model '{}': {}", mp.spec->name, mp.steps.method_note);
    last_beat_ = std::chrono::steady_clock::now();
  }

  void progress(const BakeProgress& ev) override {
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - last_beat_).count() < 3.0) return;
    last_beat_ = now;
    std::string names;
    for (const SolutionPlan* s : ev.batch) names += (names.empty() ? "" : ",") + s->grid_name;
    spdlog::info("  [{}] {}: step {}/{}{}, est. error {}, {} s", ev.model->spec->name, names, ev.step,
                 ev.planned_steps, ev.model->steps.mode == IterationMode::Auto ? " max" : "",
                 format_error(ev.error_estimate), format_seconds(ev.seconds));
  }

  void solution_done(const ModelPlan& mp, SolutionResult& r) override {
    ++done_;
    const bool auto_mode = mp.steps.mode == IterationMode::Auto;
    spdlog::info("[{}/{}] {} {} {}: {} steps, {} s, est. error {}{}", done_, total_, mp.spec->name, r.plan.grid_name,
                 format_direction(r.plan.direction), r.iterations, format_seconds(r.seconds),
                 format_error(r.error_estimate),
                 auto_mode ? (r.converged ? " (converged)" : " (NOT converged: raise max_iterations)") : "");
    if (auto_mode && !r.converged)
      spdlog::warn("{} {}: stopped at max_iterations {} with est. error {} above tolerance {}", mp.spec->name,
                   r.plan.grid_name, r.iterations, format_error(r.error_estimate), mp.steps.tolerance);
    // Summary rows in model and index order (a B00 summed from the others arrives last).
    if (models_.empty() || models_.back() != &mp) models_.push_back(&mp);
    rows_.push_back({models_.size(), r.plan.index,
                     {mp.spec->name, r.plan.grid_name, format_direction(r.plan.direction),
                      r.plan.derived ? "sum" : std::to_string(r.iterations), format_seconds(r.seconds),
                      format_error(r.error_estimate)}});
  }

  std::vector<std::vector<std::string>> rows() const {
    auto sorted = rows_;
    std::stable_sort(sorted.begin(), sorted.end(), [](const Row& a, const Row& b) {
      return a.model != b.model ? a.model < b.model : a.index < b.index;
    });
    std::vector<std::vector<std::string>> out;
    for (const Row& r : sorted) out.push_back(r.cells);
    return out;
  }

 private:
  std::size_t total_, done_ = 0;
  std::chrono::steady_clock::time_point last_beat_;
  struct Row {
    std::size_t model;
    int index;
    std::vector<std::string> cells;
  };
  std::vector<const ModelPlan*> models_;
  std::vector<Row> rows_;
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
