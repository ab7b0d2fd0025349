// Error against run time (lblight report): every run of a chosen solution is compared, check by
// check, with a converged float64 reference, next to the solver's own error estimate.
#pragma once

#include <string>
#include <vector>

#include "lblight/backend/backend.h"
#include "lblight/core/run_context.h"
#include "lblight/solve/plan.h"

namespace lblight {

struct ReportRunSpec {
  SolverMethod method = SolverMethod::Plain;
  Precision precision = Precision::Float32;
  std::string label() const;
};

struct ReportOptions {
  std::vector<int> solutions{0, 6};  // base solutions studied (static scenes: their one solution)
  std::vector<ReportRunSpec> runs{{SolverMethod::Plain, Precision::Float32}, {SolverMethod::BiCGStab, Precision::Float32}};
  int channel = -1;                  // colour channel; -1 = the one with the highest albedo (slowest)
  double reference_tolerance = 1e-8;
  double depth = 20.0;               // runs continue to tolerance / depth to show the curve below it
};

struct ReportPoint {
  int step = 0;
  double seconds = 0;                // wall time of the run (without the report's own checking)
  double true_l2 = 0, true_max = 0;  // relative to the reference, over all lattice nodes
  double estimate_l2 = 0, estimate_max = 0;  // the solver's estimate (inf = not available)
};

struct ReportCurve {
  std::string model, solution, channel, run;
  std::vector<ReportPoint> points;
  // Where the true relative L2 error first drops below the tolerance, and where bake would stop
  // (the first check whose estimate is below the tolerance), with the true error there.
  int steps_to_tolerance = -1;
  double seconds_to_tolerance = -1;
  int stop_step = -1;
  double stop_seconds = -1, stop_true_l2 = -1;
  bool estimate_bounds = true;       // estimate >= true L2 error at every check where it exists
  double worst_ratio = 0;            // max over checks of true L2 / estimate
};

struct ReportReference {
  std::string model, solution, channel;
  int steps = 0;
  double seconds = 0, estimate = 0;
};

struct Report {
  double tolerance = 0;
  std::vector<ReportReference> references;
  std::vector<ReportCurve> curves;
};

// One solution of `mp` in one distinct channel, solved (never derived): what a report studies.
ModelPlan single_solution_plan(const ModelPlan& mp, const SolutionPlan& sol, int distinct_channel);
// The colour channel with the highest albedo: the slowest to converge.
int slowest_channel(const ModelPlan& mp);

// `backend` runs the curves; `reference_backend` (float64, i.e. the CPU) computes the reference.
// Each reference and run is announced through ctx.progress; Error(Cancelled) once ctx.cancel is set.
Report make_report(const BakePlan& plan, const Backend& backend, const Backend& reference_backend,
                   const ReportOptions& options, const RunContext& ctx = {});

}  // namespace lblight
