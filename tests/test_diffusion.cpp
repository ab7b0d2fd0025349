// The diffusion coefficient of 000 eq. (4), measured from a spreading pulse in a homogeneous
// medium: the second moment of the total density grows as 6 D t.
#include <catch2/catch.hpp>

#include <cmath>

#include "lblight/lattice/d3q19.h"
#include "tests/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {

// Mean squared distance from the centre of the total density sum_m f_m.
double second_moment(const std::vector<double>& f, const Dims& d, int c) {
  double mass = 0, m2 = 0;
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x) {
        double t = 0;
        for (int m = 0; m < 19; ++m) t += f[m * d.count() + d.index(x, y, z)];
        const double r2 = double(x - c) * (x - c) + double(y - c) * (y - c) + double(z - c) * (z - c);
        mass += t;
        m2 += t * r2;
      }
  return m2 / mass;
}

double measured_diffusion(const OpticalParams& p) {
  const int n = 61, c = n / 2;
  const Dims d{n, n, n};
  auto backend = cpu_backend();
  SolverOptions so;
  so.precision = Precision::Float64;
  so.max_systems = 1;
  auto solver = backend->create(uniform_lattice(d, 1.0f), {channel(p, false)}, so);
  solver->reset({system_for(0, std::array<double, 19>{})});
  // A unit pulse at local equilibrium f = v / (1 + sigma_a) (000 eq. 15).
  std::vector<double> f(19 * d.count(), 0.0);
  const std::size_t centre = d.index(c, c, c);
  f[centre] = p.sigma_a / (1.0 + p.sigma_a);
  for (int m = 1; m < 19; ++m) f[m * d.count() + centre] = d3q19::weight(m) / (1.0 + p.sigma_a);
  solver->write_state(0, f);
  const int t1 = 20, t2 = 60;
  solver->step(t1);
  solver->read_state(0, f);
  const double m1 = second_moment(f, d, c);
  solver->step(t2 - t1);
  solver->read_state(0, f);
  const double m2 = second_moment(f, d, c);
  return (m2 - m1) / (6.0 * (t2 - t1));
}

}  // namespace

TEST_CASE("Measured diffusion coefficient matches 000 eq. (4) within 5%", "[diffusion]") {
  for (OpticalParams p : {OpticalParams{0.008, 0.792, 0.0}, OpticalParams{0.1, 0.6, 0.0}, OpticalParams{0.3, 1.2, 0.0}}) {
    const double want = diffusion_coefficient(p);
    const double got = measured_diffusion(p);
    INFO("sigma_a " << p.sigma_a << " sigma_s " << p.sigma_s << ": D = " << got << ", eq. (4) gives " << want);
    CHECK(std::fabs(got - want) < 0.05 * want);
  }
}
