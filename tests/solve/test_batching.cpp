// How a bake splits its systems into batches (solve/bake.h): whole solutions, within memory,
// evened out; and the CUDA backend's fill rule (backends/cuda/lb_device.h, host code).
#include <catch2/catch.hpp>

#include <chrono>

#include "backends/cuda/lb_device.h"
#include "lblight/core/error.h"
#include "tests/support/test_support.h"

using namespace lblight;

namespace {

// Only what batch planning asks of a backend; creating a solver is not part of it.
class PlanningBackend final : public Backend {
 public:
  // in_place: bytes per system with the state in place (0: not offered)
  // faster: prefers_in_place for solves that do not rewrite the state (as the CUDA backend)
  PlanningBackend(int preferred, std::size_t available, std::size_t per_system = 1000, std::size_t in_place = 0,
                  bool faster = false)
      : preferred_(preferred), available_(available), per_system_(per_system), in_place_(in_place), faster_(faster) {}
  std::size_t bytes_per_system_in_place(const Dims&, Precision) const override { return in_place_; }
  bool prefers_in_place(const LatticeGeometry&, Precision, bool rewrites_state) const override { return faster_ && !rewrites_state; }
  std::string name() const override { return "planning"; }
  std::string description() const override { return "batch planning only"; }
  bool supports(Precision) const override { return true; }
  bool occupies_host_cores() const override { return false; }
  std::size_t bytes_per_system(const Dims&, Precision) const override { return per_system_; }
  std::size_t bytes_per_lattice(const Dims&) const override { return 0; }
  std::size_t available_bytes() const override { return available_; }
  int preferred_batch(const Dims&, Precision, int total) const override { return std::min(preferred_, total); }
  std::unique_ptr<LatticeSolver> create(const LatticeGeometry&, const std::vector<ChannelMaterials>&,
                                        const SolverOptions&) const override {
    throw Error(ErrorCategory::Internal, "planning backend cannot solve");
  }
  double measure_copy_bandwidth(std::size_t) const override { return 0; }

 private:
  int preferred_;
  std::size_t available_, per_system_, in_place_;
  bool faster_;
};

struct PlanFixture {
  ModelSpec spec;
  ModelPlan mp;
  PlanFixture(int solutions, int channels, Dims d = {16, 16, 16}) {
    spec.name = "m";
    mp.spec = &spec;
    mp.lattice.dims = d;
    mp.channels.resize(static_cast<std::size_t>(channels));
    mp.solutions.resize(static_cast<std::size_t>(solutions));
  }
};

}  // namespace

TEST_CASE("balanced_batch evens batches out without adding any", "[batching]") {
  CHECK(balanced_batch(57, 18, 3) == 15);  // 15+15+15+12, not 18+18+18+3
  CHECK(balanced_batch(57, 3, 3) == 3);
  CHECK(balanced_batch(57, 64, 3) == 57);
  CHECK(balanced_batch(54, 33, 3) == 27);
  CHECK(balanced_batch(10, 4, 1) == 4);    // 4+4+2: three batches either way
  CHECK(balanced_batch(9, 4, 1) == 3);     // 3+3+3 instead of 4+4+1
  CHECK(balanced_batch(57, 20, 3) == 19);  // capacity not whole solutions: plain evening out
  CHECK(balanced_batch(1, 5, 3) == 1);
  for (int total = 1; total <= 70; ++total)
    for (int cap = 1; cap <= 70; ++cap)
      for (int ch = 1; ch <= 3; ++ch) {
        const int b = balanced_batch(total, cap, ch);
        INFO(total << " systems, capacity " << cap << ", " << ch << " channels -> " << b);
        REQUIRE(b >= 1);
        REQUIRE(b <= std::max(1, std::min(total, cap)));
        REQUIRE((total + b - 1) / b == (total + std::min(total, cap) - 1) / std::min(total, cap));
        if (cap % ch == 0 && total % ch == 0) REQUIRE(b % ch == 0);
      }
}

TEST_CASE("state_layout: two levels while a whole solution fits, in place when only that fits, as asked otherwise",
          "[batching][in_place]") {
  PlanFixture f(19, 3);  // 57 systems
  const BakeOptions opt;
  // 0.9 x 10000 bytes: 9 systems of 1000 with two levels, 18 of 500 in place
  CHECK(state_layout(f.mp, PlanningBackend(3, 10000, 1000, 500), opt) == StateLayout::TwoLevels);
  CHECK(batch_capacity(f.mp, PlanningBackend(3, 10000, 1000, 500), opt) == 3);
  // 0.9 x 2500: two systems with two levels, four in place: a whole solution (3 channels) only in place
  CHECK(state_layout(f.mp, PlanningBackend(3, 2500, 1000, 500), opt) == StateLayout::InPlace);
  CHECK(batch_capacity(f.mp, PlanningBackend(3, 2500, 1000, 500), opt) == 3);
  CHECK(batch_capacity(f.mp, PlanningBackend(3, 2500, 1000, 0), opt) == 2);  // not offered: two levels, 2 systems
  // 0.9 x 800: not one system with two levels; one in place
  CHECK(batch_capacity(f.mp, PlanningBackend(3, 800, 1000, 500), opt) == 1);
  CHECK_THROWS_AS(batch_capacity(f.mp, PlanningBackend(3, 800, 1000, 0), opt), Error);
  // memory unknown: two levels, unless the backend runs the lattice faster in place
  CHECK(state_layout(f.mp, PlanningBackend(3, 0, 1000, 500), opt) == StateLayout::TwoLevels);
  CHECK(state_layout(f.mp, PlanningBackend(3, 0, 1000, 500, true), opt) == StateLayout::InPlace);
  CHECK(state_layout(f.mp, PlanningBackend(3, 10000, 1000, 500, true), opt) == StateLayout::InPlace);
  // ... but not for a solve that rewrites the state between steps
  f.mp.steps.method = SolverMethod::BiCGStab;
  CHECK(state_layout(f.mp, PlanningBackend(3, 10000, 1000, 500, true), opt) == StateLayout::TwoLevels);
  f.mp.steps.method = SolverMethod::Dsa;
  CHECK(state_layout(f.mp, PlanningBackend(3, 10000, 1000, 500, true), opt) == StateLayout::TwoLevels);
  f.mp.steps.method = SolverMethod::Plain;
  // as the scene or --state asks
  f.mp.steps.state = StateLayout::InPlace;
  CHECK(state_layout(f.mp, PlanningBackend(3, 10000, 1000, 500), opt) == StateLayout::InPlace);
  CHECK(batch_capacity(f.mp, PlanningBackend(64, 10000, 1000, 500), opt) == 15);  // 18 fit: 4 batches evened
  CHECK_THROWS_WITH(state_layout(f.mp, PlanningBackend(3, 10000, 1000, 0), opt),
                    Catch::Contains("the planning backend keeps two levels"));
  f.mp.steps.state = StateLayout::TwoLevels;
  CHECK(state_layout(f.mp, PlanningBackend(3, 2500, 1000, 500), opt) == StateLayout::TwoLevels);
}

TEST_CASE("batch_capacity: whole solutions, the backend's preference, memory", "[batching]") {
  PlanFixture f(19, 3);  // 57 systems
  const BakeOptions opt;
  CHECK(batch_capacity(f.mp, PlanningBackend(3, 0), opt) == 3);       // the CPU's choice
  CHECK(batch_capacity(f.mp, PlanningBackend(1, 0), opt) == 3);       // a backend's 1 grows to a solution
  CHECK(batch_capacity(f.mp, PlanningBackend(64, 0), opt) == 57);     // one batch
  CHECK(batch_capacity(f.mp, PlanningBackend(18, 0), opt) == 15);     // 4 batches, evened out
  CHECK(batch_capacity(f.mp, PlanningBackend(64, 5000), opt) == 3);   // 0.9 * 5000 / 1000 = 4 fit -> 1 solution
  CHECK(batch_capacity(f.mp, PlanningBackend(64, 2500), opt) == 2);   // 2 fit: channels split
  CHECK_THROWS_AS(batch_capacity(f.mp, PlanningBackend(64, 1000), opt), Error);  // not even one system
  BakeOptions user;
  user.max_systems = 1;  // asked for explicitly: kept
  CHECK(batch_capacity(f.mp, PlanningBackend(64, 0), user) == 1);
  f.mp.steps.method = SolverMethod::BiCGStab;  // Krylov vectors belong to system 0
  CHECK(batch_capacity(f.mp, PlanningBackend(64, 0), opt) == 1);
}

TEST_CASE("CUDA batches: small lattices share launches, 128^3 runs a solution at a time", "[batching]") {
  CHECK(gpu::systems_to_fill({128, 128, 128}, 57) == 3);  // 2.0M interior nodes: 2 fill, 3 = one solution
  CHECK(gpu::systems_to_fill({256, 256, 256}, 57) == 1);
  CHECK(gpu::systems_to_fill({64, 64, 64}, 57) == 18);
  CHECK(gpu::systems_to_fill({32, 32, 32}, 57) == 57);
  CHECK(gpu::systems_to_fill({16, 16, 16}, 200) == gpu::kMaxBatch);
  PlanFixture big(19, 3, {128, 128, 128});
  CHECK(batch_capacity(big.mp, PlanningBackend(gpu::systems_to_fill({128, 128, 128}, 57), 0), {}) == 3);
  PlanFixture mid(19, 3, {64, 64, 64});
  CHECK(batch_capacity(mid.mp, PlanningBackend(gpu::systems_to_fill({64, 64, 64}, 57), 0), {}) == 15);
}

TEST_CASE("Solutions sharing a batch share its wall time: their seconds add up to at most the bake's", "[batching][bake]") {
  // docs/output-format.md, `seconds`: a batch's time is split evenly among its solutions. A grey
  // material gives one system per solution, so three solutions run as one batch of three.
  const Scene scene = parse_scene(R"({"version": 1, "models": [{"name": "c", "density": {"type": "procedural",
      "shape": "box", "resolution": 12}, "material": {"sigma_a": 0.01, "sigma_s": 0.79, "g": 0}}],
      "lighting": {"solutions": "1,2,3"}, "solver": {"iterations": 300}})",
                                  "s.json");
  const BakePlan plan = make_plan(scene);
  const ModelPlan& mp = plan.models.at(0);
  REQUIRE(mp.systems() == 3);
  BakeOptions opt;
  opt.max_systems = 3;
  const auto backend = test::cpu_backend();
  REQUIRE(batch_capacity(mp, *backend, opt) == 3);
  struct Seconds final : BakeObserver {
    std::vector<double> seconds;
    void solution_done(const ModelPlan&, SolutionResult& r) override { seconds.push_back(r.seconds); }
  } seen;
  const auto t0 = std::chrono::steady_clock::now();
  bake_model(mp, *backend, opt, seen);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  REQUIRE(seen.seconds.size() == 3);
  double sum = 0;
  for (double s : seen.seconds) {
    CHECK(s > 0);
    sum += s;
  }
  INFO("solutions' seconds " << sum << ", bake_model's wall time " << wall);
  CHECK(sum <= wall);
}
