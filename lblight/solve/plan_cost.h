// What a model's plan will cost on a backend, before any solving: memory (by bake's own batch
// rule, batch_capacity) and lattice updates. `validate` prints it; a scheduler could size jobs
// with it.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string>

#include "lblight/backend/backend.h"
#include "lblight/solve/plan.h"

namespace lblight {

struct PlanCost {
  int batch_systems = 0;            // systems per batch, as bake_model will run them
  std::size_t bytes_per_system = 0;
  StateLayout layout = StateLayout::TwoLevels;  // as bake will create the solver (state_layout)
  std::size_t device_bytes = 0;     // the lattice plus one batch on the backend's device
  double host_result_bytes = 0;     // every solution's totals (3 channels of float) on the host
  double updates = 0;               // systems x estimated steps x interior nodes
  // Host work besides: first_collision's voxel walks (nodes x directions x half the longest
  // edge), at kWalkSecondsPerVoxel on one core.
  double walk_voxel_steps = 0;
  bool fits = true;                 // false: not even one system fits the device's free memory
  std::string why_not;              // batch_capacity's message when it does not fit
  // Wall time at `updates_per_second` (0 when that is not known), the walks on `host_cores`.
  double seconds(double updates_per_second, int host_cores = 1) const {
    if (!(updates_per_second > 0)) return 0;
    return updates / updates_per_second + walk_voxel_steps * kWalkSecondsPerVoxel / std::max(1, host_cores);
  }
  // Measured: the 48^3 plant's walks, 128 directions, 3 channels (docs/model.md sec. 8).
  static constexpr double kWalkSecondsPerVoxel = 4e-9;
};

PlanCost plan_cost(const ModelPlan& model, const Backend& backend);

}  // namespace lblight
