#include "lblight/solve/ambient_sum.h"

#include <chrono>
#include <cmath>

#include "lblight/backend/node_rules.h"
#include "lblight/core/error.h"

namespace lblight {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

}  // namespace

AmbientSum::AmbientSum(const ModelPlan& mp, bool wanted) : mp_(mp) {
  for (const SolutionPlan& s : mp.solutions)
    if (s.index == 0) flux_weights_ = s.boundary;
  if (!wanted) return;
  for (const SolutionPlan& s : mp.solutions)
    if (s.derived) plan_ = &s;
  if (!plan_) return;
  for (auto& c : sum_) c.assign(mp.lattice.dims.count(), 0.0);
}

void AmbientSum::add(const SolutionResult& r) {
  if (r.plan.index < 1) return;
  if (!r.flux[0][0].empty()) {  // weighted by B_0's boundary (lb_model.h, ambient_boundary)
    const auto b = static_cast<float>(flux_weights_[static_cast<std::size_t>(r.plan.index)]);
    for (int c = 0; c < kChannels; ++c)
      for (int a = 0; a < 3; ++a) {
        std::vector<float>& sum = flux_[c][a];
        const std::vector<float>& j = r.flux[c][a];
        if (sum.empty()) sum.assign(j.size(), 0.0f);
        for (std::size_t i = 0; i < j.size(); ++i) sum[i] += b * j[i];
      }
    ++flux_count_;
  }
  if (!plan_) return;
  const auto t0 = Clock::now();
  double norm_sq = 0, peak = 0;
  const double b = plan_->boundary[static_cast<std::size_t>(r.plan.index)];
  for (int c = 0; c < kChannels; ++c) {
    const std::vector<float>& t = r.totals[c];
    for (std::size_t i = 0; i < t.size(); ++i) {
      sum_[c][i] += b * t[i];
      norm_sq += static_cast<double>(t[i]) * t[i];
      peak = std::max(peak, static_cast<double>(t[i]));
    }
  }
  bound_ += b * r.error_estimate * std::sqrt(norm_sq);
  bound_max_ += b * r.error_estimate_max * peak;
  iterations_ = std::max(iterations_, r.iterations);
  converged_ = converged_ && r.converged;
  ++count_;
  seconds_ += seconds_since(t0);
}

void AmbientSum::finish(BakeObserver& observer) {
  if (!plan_) return;
  if (count_ != 18) throw Error(ErrorCategory::Internal, "B00 from the sum: expected 18 directional solutions");
  const auto t0 = Clock::now();
  SolutionResult r;
  r.plan = *plan_;
  const Dims& d = mp_.lattice.dims;
  double norm_sq = 0, max_value = 0;
  for (int c = 0; c < kChannels; ++c) {
    // what B00 solved directly holds there (over a ground its open-ground light, per channel)
    const double boundary = boundary_total(system_boundary(mp_, *plan_, mp_.channel_of[static_cast<std::size_t>(c)]));
    r.totals[c].resize(d.count());
    for (int z = 0; z < d.nz; ++z)
      for (int y = 0; y < d.ny; ++y)
        for (int x = 0; x < d.nx; ++x) {
          const std::size_t i = d.index(x, y, z);
          const double v = d.is_boundary(x, y, z) ? boundary : sum_[c][i];
          r.totals[c][i] = static_cast<float>(v);
          norm_sq += v * v;
          max_value = std::max(max_value, v);
        }
  }
  r.iterations = iterations_;
  r.converged = converged_;
  r.error_estimate = norm_sq > 0 ? bound_ / std::sqrt(norm_sq) : 0.0;
  r.error_estimate_max = max_value > 0 ? bound_max_ / max_value : 0.0;
  r.seconds = seconds_ + seconds_since(t0);
  for (auto& c : sum_) std::vector<double>().swap(c);
  fill_flux(r);
  observer.solution_done(mp_, r);
}

void AmbientSum::fill_flux(SolutionResult& r) const {
  if (flux_count_ == 18) r.flux = flux_;
}

}  // namespace lblight
