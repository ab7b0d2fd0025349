// The Monte Carlo reference for a planned model: each solution of the plan traced as the light it
// stands for (montecarlo.h, docs/truth.md), channel by distinct channel, as a SolutionResult that
// the bake output writes like an LB solution (plus its standard error).
#pragma once

#include <functional>

#include "lblight/reference/montecarlo.h"
#include "lblight/solve/bake.h"
#include "lblight/solve/plan.h"

namespace lblight {

// What a planned solution means physically: base_solution_light for B00..B18, the scene's sun and
// ambient (in the same lattice direction the plan decomposes) for a static bake.
Illumination solution_light(const Scene& scene, const SolutionPlan& solution);

// Traces one solution in every distinct channel; stream_base separates the random numbers of
// solutions. progress (optional) sees each batch. totals hold the fluence, std_error its
// standard error, error_estimate the worst channel's relative standard error, iterations the
// batches and photons the photons of all channels; converged: every channel reached the target.
SolutionResult trace_solution(const ModelPlan& model, const Scene& scene, const SolutionPlan& solution,
                              const MonteCarloOptions& options, std::uint64_t stream_base, const RunContext& ctx = {},
                              const std::function<void(int channel, const FluenceEstimate&)>& progress = {});

}  // namespace lblight
