#include "lblight/reference/truth.h"

#include <algorithm>
#include <cmath>

namespace lblight {

Illumination solution_light(const Scene& scene, const SolutionPlan& s) {
  if (s.index >= 0) return base_solution_light(s.index);
  const Vec3d& t = scene.lighting.toward_sun;
  const double len = std::sqrt(t.x * t.x + t.y * t.y + t.z * t.z);
  return static_light({-t.x / len, -t.y / len, -t.z / len}, scene.lighting.intensity, scene.lighting.ambient);
}

SolutionResult trace_solution(const ModelPlan& mp, const Scene& scene, const SolutionPlan& s,
                              const MonteCarloOptions& options, std::uint64_t stream_base, const RunContext& ctx,
                              const std::function<void(int, const FluenceEstimate&)>& progress) {
  SolutionResult r;
  r.plan = s;
  r.plan.derived = false;  // B00 is traced as isotropic light, never summed from beams
  r.converged = true;
  const Illumination light = solution_light(scene, s);
  std::array<std::vector<float>, 3> mean, se;
  for (int ch = 0; ch < static_cast<int>(mp.channels.size()); ++ch) {
    std::function<void(const FluenceEstimate&)> each;
    if (progress) each = [&](const FluenceEstimate& e) { progress(ch, e); };
    MonteCarloOptions o = options;
    o.ground_albedo = mp.ground.on ? mp.ground.channel_albedo[static_cast<std::size_t>(ch)] : -1.0;
    const FluenceEstimate e = trace_fluence(mp.lattice, channel_optics(mp, ch), light, o, stream_base * 4 + ch, ctx, each);
    mean[ch].assign(e.mean.begin(), e.mean.end());
    se[ch].assign(e.std_error.begin(), e.std_error.end());
    r.iterations = std::max(r.iterations, e.batches);
    r.photons += e.photons;
    r.seconds += e.seconds;
    r.error_estimate = std::max(r.error_estimate, e.relative_error);
    r.converged = r.converged && options.target_error > 0 && e.relative_error <= options.target_error;
  }
  for (int c = 0; c < 3; ++c) {
    r.totals[c] = mean[mp.channel_of[c]];
    r.std_error[c] = se[mp.channel_of[c]];
  }
  r.error_estimate_max = r.error_estimate;
  return r;
}

}  // namespace lblight
