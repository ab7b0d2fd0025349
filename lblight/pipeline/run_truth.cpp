#include "lblight/pipeline/run_truth.h"

#include <chrono>

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

nlohmann::json run_truth(const BakePlan& plan, const MonteCarloOptions& options, const std::filesystem::path& target,
                         const std::string& command_line, BakeObserver& observer, const RunContext& ctx,
                         double seconds_before) {
  const auto t0 = std::chrono::steady_clock::now();
  BakeOutput output(plan, target, {command_line, "montecarlo", "Monte Carlo reference (host threads)",
                                   reference_json(options)});
  std::uint64_t stream = 0;
  for (const ModelPlan& mp : plan.models) {
    output.set_peak_bytes(mp, static_cast<std::size_t>(kMonteCarloBytesPerNode *
                                                        static_cast<double>(mp.lattice.dims.count())));
    for (const SolutionPlan& s : mp.solutions) {
      BakeProgress ev;
      ev.model = &mp;
      ev.batch = {&s};
      SolutionResult r = trace_solution(mp, *plan.scene, s, options, stream++, ctx, [&](int, const FluenceEstimate& e) {
        ev.step = e.batches;
        ev.error_estimate = ev.error_estimate_max = e.relative_error;
        ev.seconds = e.seconds;
        observer.progress(ev);
      });
      observer.solution_done(mp, r);
      output.add(mp, r);
    }
    output.finish_model(mp);
  }
  ctx.check_cancelled();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return output.commit(seconds_before + seconds);
}

}  // namespace lblight
