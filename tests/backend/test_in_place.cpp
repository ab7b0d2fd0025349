// In-place streaming (StateLayout::InPlace, docs/model.md sec. 3.1): the OpenMP backend's and the
// GPU kernels' (emulated on the CPU) AA pattern gives the same bits as two levels, whatever the
// parity of the step count and whatever is done to the state in between, in half the memory.
// The conformance cases (tests/backend/conformance.cpp) also run on both in place.
#include <catch2/catch.hpp>

#include "tests/backend/emulated_gpu.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {

std::array<double, 19> base(int j) { return base_boundary(j); }

// Rows longer than a cache line (a remainder chunk) and shorter than one; two systems of two
// channels; steps in odd and even chunks; the state read back, written, and bumped by add_mode
// after an odd step (the swapped layout); a few Krylov vector operations from the state (where
// the precision has them).
void check_in_place_bits(const Backend& backend) {
  std::vector<Precision> precisions;
  for (Precision p : {Precision::Float32, Precision::Float64, Precision::Float16})
    if (backend.supports(p)) precisions.push_back(p);
  for (Dims d : {Dims{37, 21, 17}, Dims{12, 9, 6}}) {
    const LatticeGeometry g = random_lattice(d, 0.9f, 0.2, 5);
    const std::vector<ChannelMaterials> channels = {channel({0.1, 0.8, 0.6}, true, {0.3, 0.5, -1.0}, false),
                                                    channel({0.05, 0.9, 0.0}, false)};
    const std::vector<SystemSpec> batch = {system_for(0, base(5)), system_for(1, base(12))};
    std::vector<double> phi(d.count(), 0.0);
    for (std::size_t i = 0; i < phi.size(); i += 7) phi[i] = 0.01 * static_cast<double>(i % 13);
    StateAccess::ModeShapes shape{};
    for (auto& s : shape)
      for (int m = 0; m < 19; ++m) s[static_cast<std::size_t>(m)] = 0.1 + 0.01 * m;
    for (Precision p : precisions) {
      const auto run = [&](StateLayout layout) {
        SolverOptions o;
        o.precision = p;
        o.max_systems = 2;
        o.layout = layout;
        auto s = backend.create(g, channels, o);
        s->reset(batch);
        std::vector<std::vector<double>> out;
        std::vector<Residual> r;
        std::vector<double> f;
        for (int chunk : {1, 7, 12, 3, 9, 2}) {
          s->step_and_measure(chunk, r);
          for (const Residual& x : r) out.push_back({x.diff_sq, x.total_sq, x.diff_max, x.total_max, x.deficit_sq});
          for (int k = 0; k < 2; ++k) {
            std::vector<float> t(d.count());
            s->read_totals(k, t.data());
            out.emplace_back(t.begin(), t.end());
            s->state_access()->read_state(k, f);
            out.push_back(f);
          }
        }
        // after 34 steps the in-place state is swapped (a step count of odd parity: 1 + 33)
        s->step(1);
        s->state_access()->read_state(1, f);
        for (double& v : f) v *= 0.75;
        s->state_access()->write_state(1, f);
        s->step(3);
        s->state_access()->add_mode(0, phi, shape, g.material);
        s->step_and_measure(4, r);
        s->state_access()->read_state(0, f);
        out.push_back(f);
        s->state_access()->read_state(1, f);
        out.push_back(f);
        s->step(1);
        if (backend.name() != "cpu" && p == Precision::Float16) return out;  // the GPU's Krylov solve is float32
        KrylovVectors* kv = s->krylov_vectors();
        kv->vectors_reserve(3);
        kv->vector_from_state(0);
        kv->vector_step_offset(1);
        kv->vector_apply_minus(0, 2);
        double xy = 0, uw = 0;
        kv->vector_dots(0, 2, 1, 1, xy, uw);
        out.push_back({xy, uw});
        kv->vector_to_state(2);
        s->step_and_measure(3, r);
        s->state_access()->read_state(0, f);
        out.push_back(f);
        return out;
      };
      INFO(backend.description() << ", " << d.nx << "x" << d.ny << "x" << d.nz << " " << to_string(p));
      const auto two = run(StateLayout::TwoLevels), one = run(StateLayout::InPlace);
      REQUIRE(one.size() == two.size());
      for (std::size_t k = 0; k < one.size(); ++k) {
        INFO("output " << k);
        REQUIRE(one[k].size() == two[k].size());
        std::size_t differ = 0, first = 0;
        for (std::size_t i = 0; i < one[k].size(); ++i)
          if (one[k][i] != two[k][i] && differ++ == 0) first = i;
        INFO(differ << " values differ, the first at " << first << ": " << (differ ? one[k][first] : 0.0)
                    << " in place, " << (differ ? two[k][first] : 0.0) << " two levels");
        CHECK(differ == 0);
      }
    }
  }
}

}  // namespace

TEST_CASE("In-place streaming gives the same bits as two levels on the CPU", "[transport][in_place]") {
  check_in_place_bits(*cpu_backend(2));
}

TEST_CASE("In-place streaming gives the same bits as two levels in the GPU kernels (emulated)",
          "[transport][in_place][gpu-emulated]") {
  check_in_place_bits(*make_emulated_gpu_backend());
  check_in_place_bits(*make_emulated_gpu_backend(1));  // every system of the batch on each thread
}

TEST_CASE("In-place streaming halves the state memory", "[transport][in_place]") {
  const Dims d{64, 64, 64};
  const LatticeGeometry g = random_lattice(d, 0.5f, 0.0, 3);
  for (const std::shared_ptr<Backend> backend :
       {std::shared_ptr<Backend>(cpu_backend(1)), std::shared_ptr<Backend>(make_emulated_gpu_backend())}) {
    INFO(backend->description());
    const double two = static_cast<double>(backend->bytes_per_system(d, Precision::Float32));
    const double one = static_cast<double>(backend->bytes_per_system_in_place(d, Precision::Float32));
    CHECK(one < 0.56 * two);
    SolverOptions o;
    o.layout = StateLayout::InPlace;
    auto s = backend->create(g, {channel({0.1, 0.8, 0.6}, true)}, o);
    s->reset({system_for(0, base(3))});
    CHECK(static_cast<double>(s->bytes_in_use()) <= one + 64.0 * 64 * 64 * 9);  // + density, material, wood
    CHECK(s->steps_per_pass() == 1);
  }
}
