// What only the OpenMP backend has: a thread count and a choice of store instructions, neither of
// which may change a result. The backend contract itself is tests/backend/conformance.cpp.
#include <catch2/catch.hpp>

#include "lblight/lattice/sun.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {
std::array<double, 19> base(int j) { return base_boundary(j); }
}  // namespace

TEST_CASE("Results do not depend on the thread count", "[transport]") {
  const LatticeGeometry g = random_lattice({23, 17, 19}, 0.9f, 0.2, 3);
  const auto ch = channel({0.1, 0.8, 0.6}, true);
  const auto one = solve_totals(*cpu_backend(1), g, {ch}, system_for(0, base(9)), 25);
  const auto two = solve_totals(*cpu_backend(2), g, {ch}, system_for(0, base(9)), 25);
  CHECK(one == two);
}

TEST_CASE("Streaming and regular stores give identical results (uniform, empty and mixed rows)", "[transport]") {
  // rows of 37 nodes: two full cache-line chunks plus a shifted tail chunk
  const LatticeGeometry g = random_lattice({37, 21, 17}, 0.9f, 0.2, 13);
  REQUIRE(g.material_count == 2);
  const auto ch = channel({0.109, 0.891, -0.12}, true, {0.109, 0.891, -1.0}, false);
  const auto backend = cpu_backend();
  for (Precision p : {Precision::Float32, Precision::Float64}) {
    std::vector<std::vector<float>> out;
    for (StoreMode mode : {StoreMode::Regular, StoreMode::Streaming}) {
      auto solver = backend->create(g, {ch}, {p, 1, mode});
      solver->reset({system_for(0, base(7))});
      solver->step(31);
      std::vector<Residual> r;
      solver->measure(r);
      out.emplace_back(g.dims.count());
      solver->read_totals(0, out.back().data());
    }
    CHECK(out[0] == out[1]);
  }
}
