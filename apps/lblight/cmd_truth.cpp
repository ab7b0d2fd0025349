// lblight truth: the Monte Carlo reference of a scene, the light the LB bake approximates, written
// like a bake (plus standard-error grids) so that `compare` measures a bake against it.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <chrono>
#include <iostream>
#include <limits>
#include <memory>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "apps/lblight/solve_options.h"
#include "lblight/core/error.h"
#include "lblight/io/output_dir.h"
#include "lblight/pipeline/run_truth.h"

namespace lblight::cli {
namespace {

struct TruthArgs {
  std::string scene, output, solutions;
  std::string method = "montecarlo", diffusion_solver = "multigrid";
  int threads = 0;
  MonteCarloOptions mc;
};

class TruthLog final : public BakeObserver {
 public:
  explicit TruthLog(std::size_t total) : total_(total) {}
  void progress(const BakeProgress& ev) override {
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - last_beat_).count() < 3.0) return;
    last_beat_ = now;
    spdlog::info("  [{}] {}: {} batches, relative standard error {}, {} s", ev.model->spec->name,
                 ev.batch.front()->grid_name, ev.step, format_error(ev.error_estimate), format_seconds(ev.seconds));
  }
  void solution_done(const ModelPlan& mp, SolutionResult& r) override {
    ++done_;
    spdlog::info("[{}/{}] {} {}: {} photons, {} s, relative standard error {}", done_, total_, mp.spec->name,
                 r.plan.grid_name, r.photons, format_seconds(r.seconds), format_error(r.error_estimate));
    rows_.push_back({mp.spec->name, r.plan.grid_name, std::to_string(r.photons), format_seconds(r.seconds),
                     format_error(r.error_estimate)});
  }
  std::vector<std::vector<std::string>> rows_;

 private:
  std::size_t total_, done_ = 0;
  std::chrono::steady_clock::time_point last_beat_ = std::chrono::steady_clock::now();
};

int run_truth(const TruthArgs& args, const GlobalOptions& global) {
  const auto t0 = std::chrono::steady_clock::now();
  // The tracer always runs min_batches batches before it trusts its error: a cap below that
  // would be ignored, not honoured.
  const std::uint64_t floor_photons = static_cast<std::uint64_t>(args.mc.min_batches) * args.mc.photons_per_batch;
  if (args.method == "montecarlo" && args.mc.max_photons != 0 && args.mc.max_photons < floor_photons)
    throw_invalid("--max-photons " + std::to_string(args.mc.max_photons) + " is below the " +
                  std::to_string(args.mc.min_batches) + " batches of --photons-per-batch " +
                  std::to_string(args.mc.photons_per_batch) + " the tracer always runs; allowed: 0 or at least " +
                  std::to_string(floor_photons) + " (or a smaller --photons-per-batch)",
                  {"--max-photons", {}, {}});
  const Scene scene = load_scene(args.scene);
  PlanOverrides ov;
  if (!args.solutions.empty()) ov.solutions = parse_solution_list(args.solutions, {"--solutions", {}, {}});
  const std::filesystem::path target = output_folder_path(
      args.output.empty() ? std::filesystem::path(std::filesystem::path(args.scene).stem().string() + "-truth")
                          : std::filesystem::path(args.output));
  check_scene_output(scene, target);
  StagedDirectory::check_target(target, OutputKind::Bake);
  RunContext ctx;
  ctx.cancel = &g_interrupted;
  ctx.threads = usable_threads(args.threads);
  const BakePlan plan = make_plan(scene, ov, ctx);
  for (const std::string& w : plan.warnings) spdlog::warn("{}", w);
  std::size_t total = 0;
  for (const ModelPlan& mp : plan.models) total += mp.solutions.size();
  TruthLog log(total);
  if (args.method == "montecarlo") {
    spdlog::info("scene '{}': Monte Carlo reference of {} solution(s), target relative standard error {}", scene.name,
                 total, args.mc.target_error);
    const double before = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    lblight::run_truth(plan, args.mc, target, global.command_line, log, ctx, before);
  } else {
    DiffusionRunOptions o;
    o.limiter = args.method == "fld" ? FluxLimiter::LevermorePomraning : FluxLimiter::Classical;
    o.solver = args.diffusion_solver == "gauss-seidel" ? DiffusionSolver::GaussSeidel : DiffusionSolver::Multigrid;
    spdlog::info("scene '{}': {} of {} solution(s)", scene.name, args.method == "fld" ? "flux-limited diffusion" : "classical diffusion", total);
    const double before = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    lblight::run_diffusion(plan, o, target, global.command_line, log, ctx, before);
  }
  Table table({"model", "solution", "photons", "seconds", "rel. std. error"});
  for (const auto& row : log.rows_) table.add(row);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << table.str() << total << " solution(s) in " << format_seconds(seconds) << " s; output: "
            << target.string() << "\n";
  return 0;
}

}  // namespace

Command add_truth_command(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<TruthArgs>();
  CLI::App* cmd = app.add_subcommand(
      "truth",
      "Monte Carlo reference of the scene's lighting: the physical light (volumetric path tracing through the same "
      "lattice, density and materials) that a bake approximates, for the same solutions. Writes OUTDIR/<model>.vdb "
      "(grids as a bake's, plus <grid>_se: the standard error per node) and OUTDIR/manifest.json, so "
      "`lblight compare --metric l2 OUTDIR BAKE` gives a bake's error against physical light. Normalisation: "
      "docs/truth.md. Results are identical for any --threads.");
  cmd->add_option("scene", args->scene, "Scene file (JSON, format v1: docs/scene-format.md)")->required();
  cmd->add_option("-o,--output", args->output, "Output directory (default: <scene name>-truth)")->check(kNonEmpty);
  cmd->add_option("--solutions", args->solutions, "Base solutions: 'all' or indices/ranges such as 0,6 (default: the "
                                                  "scene's)")
      ->check(kNonEmpty);
  cmd->add_option("--method", args->method,
                  "montecarlo (the reference), or the diffusion approximations of [Koerner2014] for comparison: cda "
                  "(classical) or fld (flux-limited), each on ray-marched uncollided light (docs/truth.md)")
      ->check(CLI::IsMember({"montecarlo", "cda", "fld"}))
      ->capture_default_str();
  cmd->add_option("--diffusion-solver", args->diffusion_solver,
                  "For cda and fld: multigrid (Picard iterations, multigrid-preconditioned CG) or gauss-seidel "
                  "([Koerner2014] Algorithm 1)")
      ->check(CLI::IsMember({"multigrid", "gauss-seidel"}))
      ->capture_default_str();
  cmd->add_option("--target-error", args->mc.target_error,
                  "Stop each solution and channel at this relative standard error (L2 over the occupied nodes)")
      ->check(finite_range(1e-6, 1.0))
      ->capture_default_str();
  cmd->add_option("--time-budget", args->mc.time_budget,
                  "Or after this many seconds per solution and channel (0: no limit)")
      ->check(finite_range(0.0, 1e9))
      ->capture_default_str();
  cmd->add_option("--max-photons", args->mc.max_photons,
                  "Or after this many photons (0: no limit; at least 16 batches are always traced)")
      ->check(integer_range(0, std::uint64_t{1} << 50))
      ->capture_default_str();
  cmd->add_option("--photons-per-batch", args->mc.photons_per_batch,
                  "Photons per batch; the standard error comes from the spread between batches")
      ->check(integer_range(256, std::uint64_t{1} << 30))
      ->capture_default_str();
  cmd->add_option("--seed", args->mc.seed, "Random seed (results depend on it and on nothing else)")
      ->check(integer_range(0, std::numeric_limits<std::uint64_t>::max()))
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "Host threads (0 = all cores); results do not depend on it")
      ->check(CLI::Range(0, 4096))
      ->capture_default_str();
  return {cmd, [args, &global] { return run_truth(*args, global); }};
}

}  // namespace lblight::cli
