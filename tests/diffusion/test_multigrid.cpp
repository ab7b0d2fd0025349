// The diffusion solver (lblight/diffusion/multigrid.h): exact solutions recovered, iterations
// that do not grow with the grid, high contrast, thread-count independence.
#include <omp.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "lblight/diffusion/multigrid.h"

using namespace lblight;

namespace {

std::vector<double> random_field(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> v(n);
  for (double& x : v) x = u(rng);
  return v;
}

double rel_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0, n = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    d += (a[i] - b[i]) * (a[i] - b[i]);
    n += b[i] * b[i];
  }
  return std::sqrt(d / n);
}

// A problem with per-node D and a; the source made from a known solution.
struct Case {
  DiffusionProblem problem;
  std::vector<double> exact, source;
};

Case make_case(const Dims& d, const std::vector<double>& D, std::vector<double> a) {
  Case c{diffusion_problem(d, std::move(a), D), random_field(d.count(), 7), {}};
  MultigridSolver(c.problem).apply(c.exact, c.source);
  return c;
}

}  // namespace

TEST_CASE("Multigrid recovers a known solution, with iterations flat in the grid size", "[diffusion]") {
  std::vector<int> iterations;
  for (int n : {15, 31, 62}) {
    const Dims d{n, n + 1, n - 1};
    const Case c = make_case(d, std::vector<double>(d.count(), 0.25), std::vector<double>(d.count(), 0.0));
    MultigridSolver mg(c.problem);
    std::vector<double> phi;
    const DiffusionSolveStats st = mg.solve(c.source, phi, 1e-10, 100);
    INFO("n = " << n << ": " << st.iterations << " iterations, residual " << st.residual);
    CHECK(st.residual <= 1e-10);
    CHECK(rel_diff(phi, c.exact) < 1e-7);
    iterations.push_back(st.iterations);
  }
  CHECK(iterations.back() <= iterations.front() + 6);
  CHECK(iterations.back() <= 30);
}

TEST_CASE("Multigrid handles a dense block in a near void, absorbing and not", "[diffusion]") {
  const Dims d{40, 40, 40};
  std::vector<double> D(d.count(), 8.0), a(d.count(), 0.0);
  for (int z = 10; z < 30; ++z)
    for (int y = 5; y < 35; ++y)
      for (int x = 12; x < 28; ++x) {
        D[d.index(x, y, z)] = 0.01;
        a[d.index(x, y, z)] = (x < 20) ? 0.05 : 0.0;
      }
  const Case c = make_case(d, D, a);
  MultigridSolver mg(c.problem);
  std::vector<double> phi;
  const DiffusionSolveStats st = mg.solve(c.source, phi, 1e-9, 200);
  INFO(st.iterations << " iterations");
  CHECK(st.residual <= 1e-9);
  CHECK(st.iterations <= 60);
  CHECK(rel_diff(phi, c.exact) < 1e-5);
}

TEST_CASE("Multigrid gives the same bits for any thread count", "[diffusion]") {
  const Dims d{33, 20, 27};
  std::vector<double> D = random_field(d.count(), 3);
  for (double& v : D) v = 0.2 + std::abs(v);
  const Case c = make_case(d, D, std::vector<double>(d.count(), 0.01));
  std::vector<double> one, many;
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  MultigridSolver(c.problem).solve(c.source, one, 1e-8, 50);
  omp_set_num_threads(std::max(2, threads));
  MultigridSolver(c.problem).solve(c.source, many, 1e-8, 50);
  omp_set_num_threads(threads);
  CHECK(one == many);
}
