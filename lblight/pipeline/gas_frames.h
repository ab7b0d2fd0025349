// Lighting a gas sequence frame by frame (`lblight simulate --light`, docs/fluid.md "Lighting
// every frame"): each frame's smoke is baked as a model of its own, "<model>.NNNN", into one
// BakeOutput, on the same lattice box every frame (the gas box grown by the model's margin, never
// cropped), so that each frame's solve starts from the previous frame's final state
// (BakeOptions::warm) instead of from zero.
#pragma once

#include "lblight/backend/backend.h"
#include "lblight/core/run_context.h"
#include "lblight/pipeline/bake_output.h"
#include "lblight/solve/bake.h"
#include "lblight/solve/plan.h"

namespace lblight {

// How one frame's lighting went.
struct GasFrameLit {
  int steps = 0;              // the most steps any of its solutions took
  double seconds = 0;         // its bake, output included
  double error_estimate = 0;  // the worst solution's
  bool warm = false;          // started from the previous frame's states
};

class GasFrameLighting {
 public:
  // sequence: the scene's plan without models (plan_without_models), the one `out` was made
  // with; frame plans add their warnings to it. warm false: every frame starts from zero (to
  // measure what warm starts save).
  GasFrameLighting(BakePlan& sequence, const ModelSpec& gas, const PlanOverrides& overrides, const Backend& backend,
                   bool warm);

  // Bakes frame `frame`'s smoke (gas_density, before density_scale) into `out` as
  // "<model>.NNNN.vdb" (the density as lit, the light grids, then `extras`, whose grids lie on the
  // smoke grid's nodes) and its manifest entry; `observer` sees every event first.
  // Error(Unavailable) when the lattice, or the states kept for the next frame, do not fit.
  GasFrameLit light(int frame, ModelGrid smoke, ModelExtras extras, BakeOutput& out, BakeObserver& observer,
                    const RunContext& ctx = {});

  bool warm() const { return warm_; }

 private:
  BakePlan& sequence_;
  ModelSpec gas_;
  PlanOverrides overrides_;
  const Backend& backend_;
  bool warm_;
  WarmStart states_;
};

}  // namespace lblight
