#include "lblight/pipeline/gas_frames.h"

#include <algorithm>
#include <chrono>

#include "lblight/core/error.h"
#include "lblight/core/system_info.h"
#include "lblight/lattice/d3q19.h"
#include "lblight/pipeline/run_bake.h"
#include "lblight/scene/gas_source.h"
#include "lblight/scene/load_model.h"
#include "lblight/solve/plan_cost.h"

namespace lblight {
namespace {

// Records how the frame's solutions went, then hands every event on.
class FrameRecord final : public BakeObserver {
 public:
  explicit FrameRecord(BakeObserver& next) : next_(next) {}
  void model_started(const ModelPlan& mp, const Backend& b, std::size_t bytes, StateLayout layout) override {
    next_.model_started(mp, b, bytes, layout);
  }
  void memory_in_use(const ModelPlan& mp, std::size_t bytes) override { next_.memory_in_use(mp, bytes); }
  void progress(const BakeProgress& p) override { next_.progress(p); }
  void solution_done(const ModelPlan& mp, SolutionResult& r) override {
    lit.steps = std::max(lit.steps, r.iterations);
    lit.error_estimate = std::max(lit.error_estimate, r.error_estimate);
    lit.warm = r.warm_start;
    next_.solution_done(mp, r);
  }
  bool wants_iterates() const override { return next_.wants_iterates(); }
  void inspect(const BakeProgress& p, LatticeSolver& s, bool measured) override { next_.inspect(p, s, measured); }

  GasFrameLit lit;

 private:
  BakeObserver& next_;
};

// `values` on the nodes of `grid` (the uncropped smoke grid) copied into the model's lattice,
// 0 on the margin.
std::vector<float> onto_lattice(const ModelPlan& mp, const std::vector<float>& values) {
  const Dims& g = mp.grid.dims;
  const Dims& l = mp.lattice.dims;
  if (values.size() != g.count())
    throw Error(ErrorCategory::Internal, "gas frame: an extra grid of " + std::to_string(values.size()) +
                                             " values for " + std::to_string(g.count()) + " nodes");
  int offset[3];
  for (int a = 0; a < 3; ++a) offset[a] = mp.grid.index_min[a] - mp.lattice_index_min[a];
  std::vector<float> out(l.count(), 0.0f);
  for (int z = 0; z < g.nz; ++z)
    for (int y = 0; y < g.ny; ++y)
      for (int x = 0; x < g.nx; ++x) out[l.index(x + offset[0], y + offset[1], z + offset[2])] = values[g.index(x, y, z)];
  return out;
}

}  // namespace

GasFrameLighting::GasFrameLighting(BakePlan& sequence, const ModelSpec& gas, const PlanOverrides& overrides,
                                   const Backend& backend, bool warm)
    : sequence_(sequence), gas_(gas), overrides_(overrides), backend_(backend), warm_(warm) {
  // Every frame on the whole gas box: a warm start maps each node's state to the same node.
  gas_.crop = false;
}

GasFrameLit GasFrameLighting::light(int frame, ModelGrid smoke, ModelExtras extras, BakeOutput& out,
                                    BakeObserver& observer, const RunContext& ctx) {
  const auto t0 = std::chrono::steady_clock::now();
  const Scene& scene = *sequence_.scene;
  ModelSpec spec = gas_;
  spec.name = gas_frame_name(gas_.name, frame);
  smoke.description = "gas smoke, frame " + std::to_string(frame) + " (" +
                      std::to_string(static_cast<long long>(frame) * gas_.density.gas.steps_per_frame) + " steps)";
  const ModelPlan mp = plan_model(sequence_, spec, finish_model_grid(spec, scene, std::move(smoke)), overrides_);
  const PlanCost cost = plan_cost(mp, backend_);
  if (!cost.fits) throw Error(ErrorCategory::Unavailable, cost.why_not);
  if (warm_ && states_.states.empty())
    check_host_memory(static_cast<double>(mp.systems()) * d3q19::kQ * sizeof(float) *
                          static_cast<double>(mp.lattice.dims.count()),
                      "the states kept from frame to frame for warm starts (" + std::to_string(mp.systems()) +
                          " system(s) of " + std::to_string(mp.lattice.dims.count()) + " nodes)",
                      "light every frame from zero (--cold), bake fewer solutions or lower the resolution",
                      {scene.file.string(), gas_.json_path, {}});
  for (ModelExtras::Grid& g : extras.grids) {
    if (!g.scalar.empty()) g.scalar = onto_lattice(mp, g.scalar);
    for (auto& c : g.rgb)
      if (!c.empty()) c = onto_lattice(mp, c);
  }
  out.set_extras(mp, std::move(extras));
  WriteEachSolution writer(out, observer);
  FrameRecord record(writer);
  BakeOptions options;
  options.warm = warm_ ? &states_ : nullptr;
  options.moments = sequence_.scene->output.moments;
  bake_model(mp, backend_, options, record, ctx);
  out.finish_model(mp);
  record.lit.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return record.lit;
}

}  // namespace lblight
