// Backend conformance, written once for every backend (the binding is conformance.h): each case
// runs on every backend the test executable binds, so the OpenMP loop, the CUDA kernels on a GPU
// and the same kernels emulated on the CPU are held to one contract (lblight/backend/backend.h,
// docs/model.md secs. 3-5). Cases for a part a backend does not offer (Krylov vectors, raw
// state, a storage precision) say so and skip that backend.
#include <catch2/catch.hpp>

#include <cmath>

#include "backends/cuda/lb_device.h"
#include "lblight/backend/node_rules.h"
#include "lblight/lattice/ground.h"
#include "lblight/lattice/lb_model.h"
#include "lblight/lattice/sun.h"
#include "lblight/solve/krylov.h"
#include "tests/backend/conformance.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {

std::array<double, 19> base(int j) { return base_boundary(j); }

// A backend creating every solver with one level of state, updated in place.
class InPlace final : public Backend {
 public:
  explicit InPlace(std::shared_ptr<Backend> inner) : inner_(std::move(inner)) {}
  std::string name() const override { return inner_->name(); }
  std::string description() const override { return inner_->description() + ", in place"; }
  bool supports(Precision p) const override { return inner_->supports(p); }
  bool occupies_host_cores() const override { return inner_->occupies_host_cores(); }
  std::size_t bytes_per_system(const Dims& d, Precision p) const override {
    return inner_->bytes_per_system_in_place(d, p);
  }
  std::size_t bytes_per_lattice(const Dims& d) const override { return inner_->bytes_per_lattice(d); }
  std::size_t available_bytes() const override { return inner_->available_bytes(); }
  int preferred_batch(const Dims& d, Precision p, int total) const override {
    return inner_->preferred_batch(d, p, total);
  }
  std::unique_ptr<LatticeSolver> create(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels,
                                        const SolverOptions& options) const override {
    SolverOptions o = options;
    o.layout = StateLayout::InPlace;
    return inner_->create(g, channels, o);
  }
  double measure_copy_bandwidth(std::size_t bytes) const override { return inner_->measure_copy_bandwidth(bytes); }

 private:
  std::shared_ptr<Backend> inner_;
};

}  // namespace

std::shared_ptr<Backend> lblight::test::in_place(std::shared_ptr<Backend> inner) {
  return std::make_shared<InPlace>(std::move(inner));
}

TEST_CASE("Every backend matches the literal reference update (mixed materials, absorption)", "[conformance]") {
  // 19 wide: rows shorter and longer than a CPU SIMD chunk, the GPU's several-row blocks; 257
  // wide: the GPU's one-row kernel with two blocks per row
  const Dims dims = GENERATE(Dims{19, 14, 11}, Dims{257, 6, 5});
  const LatticeGeometry g = random_lattice(dims, 0.95f, 0.15, 11);
  REQUIRE(g.material_count == 2);
  const OpticalParams leaf{0.109, 0.891, -0.12}, bark{0.109, 0.891, -1.0};
  for (const BoundBackend& b : conformance_backends())
    for (bool absorbs : {true, false})
      for (int sol : {0, 3, 11}) {
        INFO(b.label << ", lattice " << dims.nx << "x" << dims.ny << "x" << dims.nz << ", solution " << sol
                     << ", absorbs " << absorbs);
        ReferenceLattice ref(g, {build_omega(leaf), build_omega(bark)}, {absorbs, false}, base(sol));
        ref.step(23);
        const auto want = ref.totals();
        const auto f32 = solve_totals(*b.backend, g, {channel(leaf, absorbs, bark)}, system_for(0, base(sol)), 23);
        CHECK(max_relative_difference(want, f32, 1e-3) < 1e-5);
        if (b.backend->supports(Precision::Float64)) {
          const auto f64 = solve_totals_f64(*b.backend, g, {channel(leaf, absorbs, bark)}, system_for(0, base(sol)), 23);
          CHECK(max_relative_difference(want, f64, 1e-3) < 1e-12);
        }
      }
}

TEST_CASE("Every backend runs a ground layer as the literal reference does (docs/model.md sec. 4.3)", "[conformance][ground]") {
  LatticeGeometry g = random_lattice({19, 14, 11}, 0.95f, 0.15, 7);
  for (int y = 1; y < 13; ++y)
    for (int x = 1; x < 18; ++x) {
      g.density[g.dims.index(x, y, 1)] = 1.0f;
      g.material[g.dims.index(x, y, 1)] = kMaterialGround;
    }
  g.material_count = 3;
  const OpticalParams leaf{0.109, 0.891, -0.12}, bark{0.109, 0.891, -1.0};
  const std::array<double, 19> share = ground_share(ambient_boundary(LbModel{}));
  ChannelMaterials ch = channel(leaf, true, bark);
  ch.omega[kMaterialGround] = ground_omega(0.45, share);
  ch.absorbs[kMaterialGround] = true;
  const std::array<double, 19> boundary = with_open_ground(base(13), 0.45, share);
  ReferenceLattice ref(g, {build_omega(leaf), build_omega(bark), ch.omega[kMaterialGround]}, {true, false, true}, boundary);
  ref.step(23);
  const auto want = ref.totals();
  for (const BoundBackend& b : conformance_backends()) {
    INFO(b.label);
    const auto f32 = solve_totals(*b.backend, g, {ch}, system_for(0, boundary), 23);
    CHECK(max_relative_difference(want, f32, 1e-3) < 1e-5);
    if (b.backend->supports(Precision::Float64)) {
      const auto f64 = solve_totals_f64(*b.backend, g, {ch}, system_for(0, boundary), 23);
      CHECK(max_relative_difference(want, f64, 1e-3) < 1e-12);
    }
  }
}

TEST_CASE("Every backend matches OpenMP to 1e-5 in float32 (batch of solutions and channels)", "[conformance][slow]") {
  // 45 wide: 64 x 2 GPU blocks (several-row kernel), 15 system groups of 1; 257 wide: the one-row
  // kernel of 128^3, 256^3 and the plant, two blocks per row, 8 groups of 2 (the last of 1)
  const Dims d = GENERATE(Dims{45, 33, 27}, Dims{257, 20, 18});
  INFO("lattice " << d.nx << "x" << d.ny << "x" << d.nz);
  REQUIRE(gpu::step_launch(d, 15).per_group == (d.nx == 45 ? 1 : 2));
  const LatticeGeometry g = random_lattice(d, 0.95f, 0.1, 5);
  std::vector<SystemSpec> batch;
  for (int sol : {0, 1, 6, 9, 17})
    for (int c = 0; c < 3; ++c) batch.push_back(system_for(c, base(sol)));
  const auto want = solve_batch_totals(*cpu_backend(), g, leaf_channels(), batch, 90);
  for (const BoundBackend& b : conformance_backends()) {
    INFO(b.label);
    const auto got = solve_batch_totals(*b.backend, g, leaf_channels(), batch, 90);
    for (std::size_t s = 0; s < batch.size(); ++s) {
      INFO("system " << s);
      CHECK(max_relative_difference(want[s], got[s], 1e-3 * peak_magnitude(want[s])) < 1e-5);
    }
    // one system at a time gives the same answer as the batch
    const auto single = solve_batch_totals(*b.backend, g, leaf_channels(), {batch[7]}, 90);
    CHECK(single[0] == got[7]);
  }
}

TEST_CASE("Every backend rejects a lattice geometry that breaks the contract, naming the fault", "[conformance]") {
  const auto ch = channel({0.1, 0.8, 0.6}, true, {0.1, 0.8, -1.0}, false);
  for (const BoundBackend& b : conformance_backends())
    for (const auto& broken : broken_geometries()) {
      INFO(b.label << ": " << broken.fault);
      CHECK_THROWS_WITH(b.backend->create(broken.g, {ch}, {Precision::Float32, 1}),
                        Catch::Contains(b.backend->name() + " backend") && Catch::Contains(broken.expect));
    }
}

TEST_CASE("Every backend's results are deterministic", "[conformance]") {
  const LatticeGeometry g = random_lattice({30, 30, 30}, 0.8f, 0.0, 8);
  const std::vector<SystemSpec> batch = {system_for(0, base(3))};
  for (const BoundBackend& b : conformance_backends()) {
    INFO(b.label);
    CHECK(solve_batch_totals(*b.backend, g, leaf_channels(), batch, 40) == solve_batch_totals(*b.backend, g, leaf_channels(), batch, 40));
  }
}

TEST_CASE("Every backend's measure() sums what read_totals returns, and the change since the last", "[conformance]") {
  const LatticeGeometry g = random_lattice({17, 11, 9}, 0.9f, 0.2, 7);
  const Dims& d = g.dims;
  const std::vector<SystemSpec> batch = {system_for(0, base(0)), system_for(2, base(14))};
  for (const BoundBackend& b : conformance_backends()) {
    INFO(b.label);
    auto solver = b.backend->create(g, leaf_channels(), {Precision::Float32, 2});
    solver->reset(batch);
    std::vector<Residual> r;
    std::vector<std::vector<float>> before(2, std::vector<float>(d.count())), after = before;
    solver->step(12);
    solver->measure(r);
    for (int s = 0; s < 2; ++s) solver->read_totals(s, before[s].data());
    solver->step(5);
    solver->measure(r);
    REQUIRE(r.size() == 2);
    for (int s = 0; s < 2; ++s) {
      solver->read_totals(s, after[s].data());
      double total_sq = 0, diff_sq = 0, total_max = 0, diff_max = 0;
      for (int z = 1; z < d.nz - 1; ++z)
        for (int y = 1; y < d.ny - 1; ++y)
          for (int x = 1; x < d.nx - 1; ++x) {
            const std::size_t i = d.index(x, y, z);
            const double t = after[s][i], dd = t - static_cast<double>(before[s][i]);
            total_sq += t * t;
            diff_sq += dd * dd;
            total_max = std::max(total_max, std::fabs(t));
            diff_max = std::max(diff_max, std::fabs(dd));
          }
      INFO("system " << s);
      CHECK(r[s].finite);
      CHECK(r[s].total_sq == Approx(total_sq).epsilon(1e-12));
      CHECK(r[s].diff_sq == Approx(diff_sq).epsilon(1e-12));
      CHECK(r[s].total_max == total_max);
      CHECK(r[s].diff_max == diff_max);
      CHECK(diff_sq > 0);
      // boundary nodes store the sum of their fixed values
      CHECK(after[s][d.index(0, 3, 4)] == static_cast<float>(boundary_total(batch[s].boundary)));
    }
  }
}

TEST_CASE("Every backend's measure() reports the f_0 reservoir deficit of the nodes that keep f_0", "[conformance]") {
  // (Omega f)_0 = sigma_a sum_{j>=1} f_j - f_0 per interior node with rho > 0 whose material keeps
  // f_0 (Residual): checked against a direct sum over an arbitrary state, leaves absorbing
  // (their f_0 is dumped: no reservoir) or not, wood always keeping it
  const Dims d{9, 8, 7};
  const LatticeGeometry g = random_lattice(d, 0.9f, 0.3, 11);
  const OpticalParams leaf{0.2, 0.6, 0.3}, wood{0.05, 0.9, -1.0};
  for (const BoundBackend& b : conformance_backends())
    for (Precision p : {Precision::Float64, Precision::Float32})
      for (bool leaf_absorbs : {false, true}) {
        INFO(b.label << ", " << to_string(p) << ", leaf absorbs " << leaf_absorbs);
        if (!b.backend->supports(p)) continue;
        auto solver = b.backend->create(g, {channel(leaf, leaf_absorbs, wood, false)}, {p, 1});
        if (!solver->state_access()) {
          WARN(b.label << " offers no state access: the deficit check is skipped for it");
          break;
        }
        solver->reset({system_for(0, std::array<double, 19>{})});
        std::vector<double> f(19 * d.count());
        for (std::size_t i = 0; i < f.size(); ++i) f[i] = 0.1 + 0.01 * static_cast<double>((i * 7919) % 101);
        state_of(*solver).write_state(0, f);
        state_of(*solver).read_state(0, f);  // as the backend holds it (entries fed by the boundary included)
        double want_sq = 0, want_max = 0;
        int counted = 0;
        for (int z = 1; z < d.nz - 1; ++z)
          for (int y = 1; y < d.ny - 1; ++y)
            for (int x = 1; x < d.nx - 1; ++x) {
              const std::size_t n = d.index(x, y, z);
              const bool is_wood = g.material[n] == kMaterialWood;
              if (g.density[n] <= 0.0f || (!is_wood && leaf_absorbs)) continue;
              double moving = 0;
              for (int m = 1; m < 19; ++m) moving += f[m * d.count() + n];
              const double deficit = (is_wood ? wood.sigma_a : leaf.sigma_a) * moving - f[n];
              want_sq += deficit * deficit;
              want_max = std::max(want_max, std::fabs(deficit));
              ++counted;
            }
        REQUIRE(counted > 10);
        std::vector<Residual> r;
        solver->measure(r);
        const double eps = p == Precision::Float64 ? 1e-12 : 1e-5;  // float32: the operator's own rounding
        CHECK(r[0].deficit_sq == Approx(want_sq).epsilon(eps));
        CHECK(r[0].deficit_max == Approx(want_max).epsilon(eps));
      }
}

TEST_CASE("Every backend's add_mode adds the shape times phi at interior nodes, boundary-fed entries kept", "[conformance]") {
  // the DSA correction (solve/dsa.h): the CPU does it in place, others through read/write_state
  const Dims d{8, 7, 9};
  const LatticeGeometry g = random_lattice(d, 0.9f, 0.3, 5);
  StateAccess::ModeShapes shape{};
  for (int m = 0; m < 19; ++m) {
    shape[0][m] = 0.01 * (m + 1);
    shape[1][m] = 0.02 * (19 - m);
  }
  std::vector<double> phi(d.count(), 0.0);
  for (int z = 1; z < d.nz - 1; ++z)
    for (int y = 1; y < d.ny - 1; ++y)
      for (int x = 1; x < d.nx - 1; ++x) phi[d.index(x, y, z)] = 0.5 + 0.1 * ((x * 3 + y * 5 + z * 7) % 11);
  for (const BoundBackend& b : conformance_backends()) {
    INFO(b.label);
    if (!b.backend->supports(Precision::Float64)) continue;
    auto solver = b.backend->create(g, {channel({0.1, 0.8, 0.2}, false)}, {Precision::Float64, 1});
    if (!solver->state_access()) {
      WARN(b.label << " offers no state access: the add_mode check is skipped for it");
      continue;
    }
    std::array<double, 19> boundary{};
    for (int m = 0; m < 19; ++m) boundary[m] = 1.0 + m;
    solver->reset({system_for(0, boundary)});
    std::vector<double> f(19 * d.count());
    for (std::size_t i = 0; i < f.size(); ++i) f[i] = 0.1 + 0.01 * static_cast<double>((i * 7919) % 101);
    state_of(*solver).write_state(0, f);
    state_of(*solver).read_state(0, f);
    state_of(*solver).add_mode(0, phi, shape, g.material);
    std::vector<double> after;
    state_of(*solver).read_state(0, after);
    double worst = 0;
    for (int z = 1; z < d.nz - 1; ++z)
      for (int y = 1; y < d.ny - 1; ++y)
        for (int x = 1; x < d.nx - 1; ++x)
          for (int m = 0; m < 19; ++m) {
            const std::size_t n = d.index(x, y, z), k = static_cast<std::size_t>(m) * d.count() + n;
            const bool fed = d.is_boundary(x - d3q19::cx(m), y - d3q19::cy(m), z - d3q19::cz(m));
            const double want = fed ? f[k] : f[k] + shape[g.material[n]][m] * phi[n];
            worst = std::max(worst, std::fabs(after[k] - want));
          }
    CHECK(worst < 1e-12);
  }
}

TEST_CASE("BiCGStab reaches the plain iteration's fixed point", "[conformance][krylov][slow]") {
  // densities kept away from 0: a nearly empty node that keeps f_0 relaxes at rate rho per step,
  // which neither method reaches in a test's time (tests/solve/test_extreme.cpp covers that case)
  const LatticeGeometry g = random_lattice({17, 15, 13}, 0.95f, 0.15, 31, 0.3f);
  for (const BoundBackend& b : conformance_backends()) {
    if (!b.backend->supports(Precision::Float64)) {
      WARN(b.label << " does not store float64: the float64 BiCGStab check is skipped for it");
      continue;
    }
    for (bool absorbs : {true, false}) {
      const auto ch = channel({absorbs ? 0.109 : 0.008, absorbs ? 0.891 : 0.792, absorbs ? -0.12 : 0.0}, absorbs,
                              {0.109, 0.891, -1.0}, false);
      // plain: many steps in float64
      const auto plain = solve_totals_f64(*b.backend, g, {ch}, system_for(0, base(3)), 6000);
      auto solver = b.backend->create(g, {ch}, {Precision::Float64, 1});
      solver->reset({system_for(0, base(3))});
      const KrylovResult kr = bicgstab(krylov_of(*solver), 1e-12, 5000);
      INFO(b.label << ", absorbs " << absorbs << ": " << kr.iterations << " iterations, " << kr.steps << " steps");
      CHECK(kr.reached);
      CHECK(kr.steps < 600);
      std::vector<double> f;
      state_of(*solver).read_state(0, f);
      const std::size_t n = g.dims.count();
      std::vector<double> totals(n, 0.0);
      for (int m = 0; m < 19; ++m)
        for (std::size_t i = 0; i < n; ++i) totals[i] += f[m * n + i];
      CHECK(max_relative_difference(plain, totals, 1e-3) < 1e-8);
    }
  }
}

TEST_CASE("BiCGStab in float32 reaches 1e-4 on a dense cube in a fraction of the plain steps", "[conformance][krylov][slow]") {
  // docs/model.md sec. 5: density 1, cloud parameters with g = 0; plain iteration needs ~33N steps
  const LatticeGeometry g = uniform_lattice({26, 26, 26}, 1.0f);
  const auto ch = channel({0.008, 0.792, 0.0}, false);
  const auto truth = solve_totals_f64(*cpu_backend(), g, {ch}, system_for(0, base(6)), 8000);
  for (const BoundBackend& b : conformance_backends()) {
    auto solver = b.backend->create(g, {ch}, {Precision::Float32, 1});
    if (!solver->krylov_vectors()) {
      WARN(b.label << " offers no Krylov vectors: skipped");
      continue;
    }
    solver->reset({system_for(0, base(6))});
    const KrylovResult kr = bicgstab(krylov_of(*solver), 1e-5, 2000);
    std::vector<Residual> r;
    solver->measure(r);
    std::vector<float> got(g.dims.count());
    solver->read_totals(0, got.data());
    double e2 = 0, t2 = 0;
    for (std::size_t i = 0; i < got.size(); ++i) {
      e2 += (got[i] - truth[i]) * (got[i] - truth[i]);
      t2 += truth[i] * truth[i];
    }
    INFO(b.label << ": " << kr.steps << " steps, relative L2 error " << std::sqrt(e2 / t2));
    CHECK(std::sqrt(e2 / t2) < 1e-4);
    CHECK(kr.steps < 33 * 26 / 4);
  }
}
