// The diffusion coefficient of [Geist2010] eq. (4), measured from a spreading pulse in a homogeneous
// medium: the second moment of the total density grows as 6 D t.
#include <catch2/catch.hpp>

#include <cmath>

#include "lblight/lattice/d3q19.h"
#include "tests/support/test_support.h"

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

double measured_diffusion(const OpticalParams& p, double rho = 1.0, bool absorb = false) {
  const int n = 61, c = n / 2;
  const Dims d{n, n, n};
  auto backend = cpu_backend();
  SolverOptions so;
  so.precision = Precision::Float64;
  so.max_systems = 1;
  auto solver = backend->create(uniform_lattice(d, static_cast<float>(rho)), {channel(p, absorb)}, so);
  solver->reset({system_for(0, std::array<double, 19>{})});
  // A unit pulse at local equilibrium f = v / (1 + sigma_a) ([Geist2010] eq. 15): f_0 holds sigma_a
  // times the moving mass at any density (none where the material absorbs).
  std::vector<double> f(19 * d.count(), 0.0);
  const std::size_t centre = d.index(c, c, c);
  const double rest = absorb ? 0.0 : p.sigma_a;
  f[centre] = rest / (1.0 + rest);
  for (int m = 1; m < 19; ++m) f[m * d.count() + centre] = d3q19::weight(m) / (1.0 + rest);
  state_of(*solver).write_state(0, f);
  const int t1 = 20, t2 = 60;
  solver->step(t1);
  state_of(*solver).read_state(0, f);
  const double m1 = second_moment(f, d, c);
  solver->step(t2 - t1);
  state_of(*solver).read_state(0, f);
  const double m2 = second_moment(f, d, c);
  return (m2 - m1) / (6.0 * (t2 - t1));
}

}  // namespace

TEST_CASE("Measured diffusion coefficient matches Geist2010 eq. (4) within 1%, also at density 0.5", "[diffusion][slow]") {
  for (OpticalParams p : {OpticalParams{0.008, 0.792, 0.0}, OpticalParams{0.1, 0.6, 0.0}, OpticalParams{0.3, 1.2, 0.0}}) {
    const double want = diffusion_coefficient(p);
    const double got = measured_diffusion(p);
    INFO("sigma_a " << p.sigma_a << " sigma_s " << p.sigma_s << ": D = " << got << ", eq. (4) gives " << want);
    CHECK(std::fabs(got - want) < 0.01 * want);
  }
  // At density rho the collisions scale with rho, and so does f_0's release: light rests in f_0
  // sigma_a / (1 + sigma_a) of the time at any rho (not rho sigma_a / (1 + rho sigma_a)), and not
  // at all where the material absorbs (f_0 dumped). sigma_a = 0.3 tells the forms apart by 13%.
  const OpticalParams p{0.3, 1.7, 0.0};
  CHECK(diffusion_coefficient(p, 0.5) == Approx(((2.0 / 1.0) - 1.0) / (4.0 * 1.3)));
  CHECK(diffusion_coefficient(p, 0.5, true) == Approx(((2.0 / 1.0) - 1.0) / 4.0));
  for (bool absorb : {false, true}) {
    const double want = diffusion_coefficient(p, 0.5, absorb), got = measured_diffusion(p, 0.5, absorb);
    INFO("rho 0.5, absorb " << absorb << ": D = " << got << ", eq. (4) gives " << want);
    CHECK(std::fabs(got - want) < 0.01 * want);
  }
}
