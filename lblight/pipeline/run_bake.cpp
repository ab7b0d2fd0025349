#include "lblight/pipeline/run_bake.h"

#include <chrono>

#include "lblight/pipeline/bake_output.h"
#include "lblight/solve/plan_cost.h"

namespace lblight {

WriteEachSolution::WriteEachSolution(BakeOutput& out, BakeObserver& next) : out_(out), next_(next) {}

void WriteEachSolution::model_started(const ModelPlan& mp, const Backend& backend, std::size_t bytes,
                                      StateLayout layout) {
  next_.model_started(mp, backend, bytes, layout);
  out_.set_peak_bytes(mp, bytes);
}

void WriteEachSolution::memory_in_use(const ModelPlan& mp, std::size_t bytes) {
  next_.memory_in_use(mp, bytes);
  out_.set_peak_bytes(mp, bytes);
}

void WriteEachSolution::solution_done(const ModelPlan& mp, SolutionResult& r) {
  next_.solution_done(mp, r);
  out_.add(mp, r);
}

nlohmann::json run_bake(const BakePlan& plan, const Backend& backend, const std::filesystem::path& target,
                        const std::string& command_line, BakeObserver& observer, const RunContext& ctx,
                        double seconds_before, const nlohmann::json& unit) {
  const auto t0 = std::chrono::steady_clock::now();
  // Every model must fit before the first one solves: a bake that fails at its second model has
  // spent the first one's time for nothing.
  for (const ModelPlan& mp : plan.models) {
    const PlanCost cost = plan_cost(mp, backend);
    if (!cost.fits) throw Error(ErrorCategory::Unavailable, cost.why_not);
  }
  // On a GPU the host waits on the device: convert and write each solution while the next solves.
  BakeOutput output(plan, target, {command_line, backend.name(), backend.description(), {}, unit},
                    /*write_in_background=*/!backend.occupies_host_cores());
  WriteEachSolution writer(output, observer);
  BakeOptions options;  // a unit of some of the model's solutions bakes only those
  if (unit.is_object() && unit.contains("solutions")) options.solutions = unit["solutions"].get<std::vector<int>>();
  options.moments = plan.scene->output.moments;
  for (const ModelPlan& mp : plan.models) {
    bake_model(mp, backend, options, writer, ctx);
    output.finish_model(mp);
  }
  ctx.check_cancelled();  // a signal during the last model's output: nothing goes into place
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return output.commit(seconds_before + seconds);
}

}  // namespace lblight
