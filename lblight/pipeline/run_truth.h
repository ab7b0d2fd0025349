// The Monte Carlo reference of a whole plan, from the plan to files on disk (`lblight truth`): the
// same layout as a bake (so `compare` and `inspect` read it), each grid traced instead of solved,
// with a standard-error grid <name>_se beside it (docs/truth.md).
#pragma once

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "lblight/core/run_context.h"
#include "lblight/reference/diffusion_solution.h"
#include "lblight/reference/montecarlo.h"
#include "lblight/solve/bake.h"
#include "lblight/solve/plan.h"

namespace lblight {

// The manifest's "reference" entry for these settings.
nlohmann::json reference_json(const MonteCarloOptions& options);

// Traces every solution of every model of `plan` and writes them to `target` (staged: complete or
// nothing). observer sees progress (step = batches, error_estimate = the relative standard error)
// and each solution. Error(Cancelled) once ctx.cancel is set, leaving nothing behind.
nlohmann::json run_truth(const BakePlan& plan, const MonteCarloOptions& options, const std::filesystem::path& target,
                         const std::string& command_line, BakeObserver& observer, const RunContext& ctx = {},
                         double seconds_before = 0);

// The same layout from the diffusion solvers (reference/diffusion_solution.h), without standard
// errors: `lblight truth --method cda|fld`.
nlohmann::json run_diffusion(const BakePlan& plan, const DiffusionRunOptions& options,
                             const std::filesystem::path& target, const std::string& command_line,
                             BakeObserver& observer, const RunContext& ctx = {}, double seconds_before = 0);

}  // namespace lblight
