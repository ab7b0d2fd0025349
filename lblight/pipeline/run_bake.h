// The whole bake, from a plan to files on disk: what `lblight bake` and tools/gpu_pipeline_sim
// both run.
#pragma once

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "lblight/backend/backend.h"
#include "lblight/core/run_context.h"
#include "lblight/solve/bake.h"
#include "lblight/solve/plan.h"

namespace lblight {

class BakeOutput;

// Hands every event to the caller's observer `next`, then each solution (and the memory figures)
// to the output.
class WriteEachSolution final : public BakeObserver {
 public:
  WriteEachSolution(BakeOutput& out, BakeObserver& next);
  void model_started(const ModelPlan& mp, const Backend& backend, std::size_t bytes, StateLayout layout) override;
  void memory_in_use(const ModelPlan& mp, std::size_t bytes) override;
  void progress(const BakeProgress& p) override { next_.progress(p); }
  void solution_done(const ModelPlan& mp, SolutionResult& r) override;
  bool wants_iterates() const override { return next_.wants_iterates(); }
  void inspect(const BakeProgress& p, LatticeSolver& solver, bool measured) override { next_.inspect(p, solver, measured); }

 private:
  BakeOutput& out_;
  BakeObserver& next_;
};

// Solves every model of `plan` on `backend` (bake_model) and writes it into `target` through a
// BakeOutput: staged, so the folder appears complete or not at all. Each solution is written as it
// arrives, on a thread of its own when the backend leaves the host's cores free (a GPU), so the
// output overlaps the solve; the manifest comes last and is returned. `observer` sees every event
// first (progress logs, summaries) and must leave the solutions' totals in place.
// seconds_before: time already spent on the run (loading, planning), counted in the manifest's
// total_seconds. Error(Cancelled) once ctx.cancel is set, leaving nothing behind. `unit`: the plan
// is one work unit (unit_record, docs/scale-out.md) and the output its partial.
nlohmann::json run_bake(const BakePlan& plan, const Backend& backend, const std::filesystem::path& target,
                        const std::string& command_line, BakeObserver& observer, const RunContext& ctx = {},
                        double seconds_before = 0, const nlohmann::json& unit = nullptr);

}  // namespace lblight
