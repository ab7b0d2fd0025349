// Error against physical light over run time (`lblight report --truth`, docs/accuracy.md): each
// chosen solution traced by the Monte Carlo reference, then the papers' and the calibrated LB
// (error at every check), CDA and FLD (reference/diffusion_solution.h), and an independent Monte
// Carlo run at growing sample counts, all measured against that reference.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "lblight/backend/backend.h"
#include "lblight/core/run_context.h"
#include "lblight/scene/scene.h"
#include "lblight/solve/plan.h"

namespace lblight {

struct TruthReportOptions {
  std::vector<int> solutions{0, 6};
  int channel = -1;            // colour channel; -1: the one with the highest albedo
  double truth_error = 0.02;   // the reference's relative standard error
  std::uint64_t seed = 1;
};

struct TruthCurve {
  std::string model, solution, run;
  std::vector<std::array<double, 2>> points;  // wall seconds, relative L2 error over the occupied nodes
};

struct TruthReference {
  std::string model, solution, channel;
  double seconds = 0, std_error = 0;
  std::uint64_t photons = 0;
};

struct TruthReport {
  std::vector<TruthReference> references;
  std::vector<TruthCurve> curves;
};

// `scene` is planned once per LB model (paper and calibrated, the scene's method and tolerance
// with `overrides`); the LB runs go on `backend`.
TruthReport make_truth_report(const Scene& scene, const PlanOverrides& overrides, const Backend& backend,
                              const TruthReportOptions& options, const RunContext& ctx = {});

}  // namespace lblight
