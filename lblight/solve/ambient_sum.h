// B00 from the directional solutions (docs/model.md sec. 4): the sum a bake writes instead of
// solving B00, and the flux of a B00 solved from a source (solve/bake.h, BakeOptions::moments).
#pragma once

#include <array>
#include <vector>

#include "lblight/solve/bake.h"

namespace lblight {

// B_0 assembled from the 18 directional solutions as they finish (docs/model.md sec. 4), when the
// model derives it (and `wanted`): interior nodes sum_j b_j B_j with b the boundary of B_0,
// boundary nodes B_0's own fixed total. Error bound: ||sum b_j e_j|| <= sum b_j eps_j ||B_j||,
// over ||B_0||. bake_model uses it, and a merge that assembles a model from its units' totals.
class AmbientSum {
 public:
  AmbientSum(const ModelPlan& model, bool wanted = true);
  bool wanted() const { return plan_ != nullptr; }
  void add(const SolutionResult& r);        // a directional solution, with its totals
  void finish(BakeObserver& observer);      // after all 18: hands B_0 to the observer
  // BakeOptions::moments: r.flux = the flux sum of the 18 directional solutions added (whether or
  // not B_0's totals are wanted); left empty unless all 18 came with their flux.
  void fill_flux(SolutionResult& r) const;

 private:
  const ModelPlan& mp_;
  const SolutionPlan* plan_ = nullptr;
  std::array<std::vector<double>, 3> sum_;
  std::array<FluxField, 3> flux_;  // per channel and axis: sum_j b_j J_j
  std::array<double, 19> flux_weights_{};  // b: B_0's boundary (whether derived or solved)
  int flux_count_ = 0;
  double bound_ = 0, bound_max_ = 0, seconds_ = 0;
  int iterations_ = 0, count_ = 0;
  bool converged_ = true;
};

}  // namespace lblight
