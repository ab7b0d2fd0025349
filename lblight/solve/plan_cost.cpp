#include "lblight/solve/plan_cost.h"

#include <algorithm>

#include "lblight/core/error.h"
#include "lblight/solve/bake.h"
#include "lblight/solve/first_collision.h"

namespace lblight {

PlanCost plan_cost(const ModelPlan& mp, const Backend& backend) {
  PlanCost c;
  const Dims& d = mp.lattice.dims;
  c.bytes_per_system = backend.bytes_per_system(d, mp.steps.precision);
  try {
    c.layout = state_layout(mp, backend, {});
    if (c.layout == StateLayout::InPlace) c.bytes_per_system = backend.bytes_per_system_in_place(d, mp.steps.precision);
    c.batch_systems = batch_capacity(mp, backend, {});
  } catch (const Error& e) {
    if (e.category() != ErrorCategory::Unavailable) throw;
    c.fits = false;
    c.why_not = e.what();
    c.batch_systems = 1;  // what the bake would need at the least
  }
  c.device_bytes = backend.bytes_per_lattice(d) + static_cast<std::size_t>(c.batch_systems) * c.bytes_per_system;
  c.host_result_bytes = static_cast<double>(mp.solutions.size()) * 3.0 * static_cast<double>(d.count()) * sizeof(float);
  c.updates = static_cast<double>(mp.systems()) * mp.estimated_steps * static_cast<double>(d.interior_count());
  if (mp.model.first_collision_on())
    c.walk_voxel_steps = static_cast<double>(d.interior_count()) * kUncollidedDirections * 0.5 * d.longest();
  return c;
}

}  // namespace lblight
