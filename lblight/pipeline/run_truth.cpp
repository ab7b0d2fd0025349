#include "lblight/pipeline/run_truth.h"

#include <chrono>

#include "lblight/core/error.h"
#include "lblight/pipeline/bake_output.h"
#include "lblight/reference/truth.h"

namespace lblight {

nlohmann::json reference_json(const MonteCarloOptions& o) {
  return {{"method", "montecarlo"},
          {"target_error", o.target_error},
          {"time_budget", o.time_budget},
          {"max_photons", o.max_photons},
          {"photons_per_batch", o.photons_per_batch},
          {"min_batches", o.min_batches},
          {"seed", o.seed},
          {"estimator", "analog tracking, implicit capture, track-length fluence (docs/truth.md)"}};
}

namespace {

// The diffusion solutions (and the report's comparisons built on them) have no ground yet.
void refuse_ground(const BakePlan& plan, const std::string& what) {
  for (const ModelPlan& mp : plan.models)
    if (mp.ground.on)
      throw_invalid(what + " does not model the ground yet (model '" + mp.spec->name +
                        "' stands on it); use the Monte Carlo reference (truth --method montecarlo), or leave "
                        "\"ground\" out",
                    {plan.scene->file.string(), "/ground", {}});
}

// Solves every solution of the plan with `solve` and writes them as a bake would.
template <typename Solve>
nlohmann::json write_all(const BakePlan& plan, BakeOutput& output, double bytes_per_node, BakeObserver& observer,
                         const RunContext& ctx, double seconds_before, std::chrono::steady_clock::time_point t0,
                         Solve&& solve) {
  std::uint64_t stream = 0;
  for (const ModelPlan& mp : plan.models) {
    output.set_peak_bytes(mp, static_cast<std::size_t>(bytes_per_node * static_cast<double>(mp.lattice.dims.count())));
    for (const SolutionPlan& s : mp.solutions) {
      SolutionResult r = solve(mp, s, stream++);
      observer.solution_done(mp, r);
      output.add(mp, r);
      ctx.check_cancelled();
    }
    output.finish_model(mp);
  }
  ctx.check_cancelled();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return output.commit(seconds_before + seconds);
}

}  // namespace

nlohmann::json run_truth(const BakePlan& plan, const MonteCarloOptions& options, const std::filesystem::path& target,
                         const std::string& command_line, BakeObserver& observer, const RunContext& ctx,
                         double seconds_before) {
  const auto t0 = std::chrono::steady_clock::now();
  BakeOutput output(plan, target, {command_line, "montecarlo", "Monte Carlo reference (host threads)",
                                   reference_json(options), nullptr});
  return write_all(plan, output, kMonteCarloBytesPerNode, observer, ctx, seconds_before, t0,
                   [&](const ModelPlan& mp, const SolutionPlan& s, std::uint64_t stream) {
                     BakeProgress ev;
                     ev.model = &mp;
                     ev.batch = {&s};
                     return trace_solution(mp, *plan.scene, s, options, stream, ctx, [&](int, const FluenceEstimate& e) {
                       ev.step = e.batches;
                       ev.error_estimate = ev.error_estimate_max = e.relative_error;
                       ev.seconds = e.seconds;
                       observer.progress(ev);
                     });
                   });
}

nlohmann::json run_diffusion(const BakePlan& plan, const DiffusionRunOptions& options,
                             const std::filesystem::path& target, const std::string& command_line,
                             BakeObserver& observer, const RunContext& ctx, double seconds_before) {
  const auto t0 = std::chrono::steady_clock::now();
  const bool fld = options.limiter == FluxLimiter::LevermorePomraning;
  refuse_ground(plan, fld ? "truth --method fld" : "truth --method cda");
  const std::string solver = options.solver == DiffusionSolver::Multigrid ? "Picard iterations, multigrid CG"
                                                                           : "Algorithm 1 (red-black Gauss-Seidel)";
  BakeOutput output(plan, target,
                    {command_line, fld ? "fld" : "cda",
                     std::string(fld ? "flux-limited diffusion (Levermore-Pomraning)" : "classical diffusion") +
                         " of [Koerner2014] plus ray-marched uncollided light, " + solver + " (docs/truth.md)",
                     nullptr, nullptr});
  // fields of the solver: phi, D, sigma, albedo, emission, uncollided, multigrid work (~12 doubles)
  return write_all(plan, output, 96.0, observer, ctx, seconds_before, t0,
                   [&](const ModelPlan& mp, const SolutionPlan& s, std::uint64_t) {
                     return diffuse_solution(mp, *plan.scene, s, options);
                   });
}

}  // namespace lblight
