#include "lblight/pipeline/truth_report.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "lblight/core/error.h"
#include "lblight/reference/diffusion_solution.h"
#include "lblight/reference/truth.h"
#include "lblight/solve/bake.h"
#include "lblight/solve/report.h"

namespace lblight {
namespace {

using Clock = std::chrono::steady_clock;

// Relative L2 of `got` against `ref` over the occupied nodes (compare --metric l2).
template <typename A, typename B>
double error_against(const LatticeGeometry& g, const A& got, const B& ref) {
  double d = 0, n = 0;
  for (std::size_t i = 0; i < g.density.size(); ++i)
    if (g.density[i] > 0) {
      const double e = static_cast<double>(got[i]) - static_cast<double>(ref[i]);
      d += e * e;
      n += static_cast<double>(ref[i]) * static_cast<double>(ref[i]);
    }
  return n > 0 ? std::sqrt(d / n) : 0.0;
}

// Error against the reference at every check of an LB run, in the run's own wall time.
class TruthRecorder final : public BakeObserver {
 public:
  TruthRecorder(const LatticeGeometry& g, const std::vector<double>& truth, TruthCurve& curve)
      : g_(g), truth_(truth), curve_(curve), totals_(truth.size()) {}
  void solution_done(const ModelPlan&, SolutionResult&) override {}
  bool wants_iterates() const override { return true; }
  void inspect(const BakeProgress& ev, LatticeSolver& solver, bool measured) override {
    const auto t0 = Clock::now();
    if (!measured) solver.measure(scratch_);
    solver.read_totals(0, totals_.data());
    curve_.points.push_back({ev.seconds - own_, error_against(g_, totals_, truth_)});
    own_ += std::chrono::duration<double>(Clock::now() - t0).count();
  }

 private:
  const LatticeGeometry& g_;
  const std::vector<double>& truth_;
  TruthCurve& curve_;
  std::vector<float> totals_;
  std::vector<Residual> scratch_;
  double own_ = 0;
};

}  // namespace

TruthReport make_truth_report(const Scene& scene, const PlanOverrides& ov, const Backend& backend,
                              const TruthReportOptions& opt, const RunContext& ctx) {
  TruthReport report;
  Scene paper_scene = scene, calibrated_scene = scene;
  paper_scene.solver.model = LbModel{};
  calibrated_scene.solver.model = LbModel{};
  calibrated_scene.solver.model.calibrated = true;
  if (scene.ground.enabled)
    throw_invalid("report --truth does not model the ground yet (its diffusion solutions have none); leave \"ground\" out "
                  "of the scene for the report, or compare a bake with `lblight truth` and `compare --metric l2`",
                  {scene.file.string(), "/ground", {}});
  const BakePlan paper = make_plan(paper_scene, ov, ctx), calibrated = make_plan(calibrated_scene, ov, ctx);
  for (std::size_t m = 0; m < paper.models.size(); ++m) {
    const ModelPlan& mp = paper.models[m];
    const int colour = opt.channel >= 0 ? opt.channel : slowest_channel(mp);
    for (std::size_t k = 0; k < mp.solutions.size(); ++k) {
      const SolutionPlan& sol = mp.solutions[k];
      if (sol.index >= 0 && std::find(opt.solutions.begin(), opt.solutions.end(), sol.index) == opt.solutions.end())
        continue;
      const ModelPlan sub = single_solution_plan(mp, sol, mp.channel_of[static_cast<std::size_t>(colour)]);
      const ModelPlan sub_cal = single_solution_plan(calibrated.models[m], calibrated.models[m].solutions[k],
                                                     calibrated.models[m].channel_of[static_cast<std::size_t>(colour)]);
      const Illumination light = solution_light(scene, sol);
      const ChannelOptics optics = channel_optics(sub, 0);
      ctx.report("model '" + mp.spec->name + "' " + sol.grid_name + " (" + kChannelNames[colour] +
                 "): Monte Carlo reference");
      MonteCarloOptions mc;
      mc.target_error = opt.truth_error;
      mc.seed = opt.seed;
      const FluenceEstimate ref = trace_fluence(sub.lattice, optics, light, mc, 0, ctx);
      report.references.push_back({mp.spec->name, sol.grid_name, kChannelNames[colour], ref.seconds,
                                   ref.relative_error, ref.photons});
      auto curve = [&](const std::string& run) -> TruthCurve& {
        report.curves.push_back({mp.spec->name, sol.grid_name, run, {}});
        ctx.report("  run: " + run);
        return report.curves.back();
      };
      for (const ModelPlan* lb : {&sub, &sub_cal}) {
        TruthCurve& c = curve(std::string(lb == &sub ? "paper" : "calibrated") + " LB " + to_string(lb->steps.method));
        TruthRecorder recorder(lb->lattice, ref.mean, c);
        bake_model(*lb, backend, {}, recorder, ctx);
      }
      for (FluxLimiter limiter : {FluxLimiter::Classical, FluxLimiter::LevermorePomraning}) {
        TruthCurve& c = curve(limiter == FluxLimiter::Classical ? "CDA" : "FLD");
        DiffusionRunOptions d;
        d.limiter = limiter;
        const SolutionResult r = diffuse_solution(sub, scene, sol, d);
        c.points.push_back({r.seconds, error_against(sub.lattice, r.totals[0], ref.mean)});
      }
      TruthCurve& c = curve("Monte Carlo (another seed)");
      MonteCarloOptions again = mc;
      again.seed = opt.seed + 1;
      trace_fluence(sub.lattice, optics, light, again, 0, ctx, [&](const FluenceEstimate& e) {
        c.points.push_back({e.seconds, error_against(sub.lattice, e.mean, ref.mean)});
      });
    }
  }
  return report;
}

}  // namespace lblight
