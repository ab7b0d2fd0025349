// The flux (first angular moment) of the light (solve/flux.h, docs/model.md sec. 3.2): a beam in
// vacuum has flux equal to its fluence times its direction; the P1 radiance it stands for
// integrates back to the scalar light and, convolved with a Henyey-Greenstein phase function,
// gives what the renderer in-scatters (render/volume_render.h, p1_in_scattering).
#include <catch2/catch.hpp>

#include <cmath>

#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/sun.h"
#include "lblight/render/volume_render.h"
#include "lblight/solve/flux.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {

constexpr double kPi = 3.14159265358979323846;

// Directions over the sphere, equal solid angle each: a Fibonacci lattice of n points.
std::vector<Vec3d> sphere_points(int n) {
  std::vector<Vec3d> out;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n, r = std::sqrt(1.0 - z * z), phi = golden * i;
    out.push_back({r * std::cos(phi), r * std::sin(phi), z});
  }
  return out;
}

double dot3(const Vec3d& a, const Vec3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

}  // namespace

TEST_CASE("flux: a beam in vacuum has flux equal to its fluence times its direction", "[moments]") {
  const LatticeGeometry g = uniform_lattice({7, 6, 8}, 0.0f);
  const std::vector<ChannelMaterials> channels = {channel({0.1, 0.9, 0.3}, true)};
  const auto backend = cpu_backend(2);
  for (int j : {1, 6, 9, 14}) {
    auto solver = backend->create(g, channels, {});
    solver->reset({system_for(0, base_boundary(j))});
    solver->step(30);
    std::vector<Residual> measured;
    solver->measure(measured);  // the totals are fresh after a measure
    std::vector<double> state;
    state_of(*solver).read_state(0, state);
    std::vector<float> totals(g.dims.count());
    solver->read_totals(0, totals.data());
    const FluxField flux = state_flux(g, channels[0], state);
    const double len = std::sqrt(static_cast<double>(d3q19::length_sq(j)));
    const double n[3] = {d3q19::cx(j) / len, d3q19::cy(j) / len, d3q19::cz(j) / len};
    int checked = 0;
    for (std::size_t i = 0; i < totals.size(); ++i) {
      if (totals[i] == 0.0f) continue;
      for (int a = 0; a < 3; ++a) CHECK(flux[a][i] == Approx(totals[i] * n[a]).margin(1e-6));
      ++checked;
    }
    CHECK(checked > 100);
  }
}

TEST_CASE("flux: in a medium it is bounded by the light, and light scattered back lowers it", "[moments]") {
  // A beam down into a scattering slab (the calibrated model's voxel average on): |J| <= phi at
  // every node, and J . n below phi inside (scattered light flows every way).
  const LatticeGeometry g = uniform_lattice({6, 6, 12}, 0.8f);
  ChannelMaterials ch = channel({0.05, 0.95, 0.2}, false);
  ch.voxel_average.fill(true);
  const auto backend = cpu_backend(2);
  auto solver = backend->create(g, {ch}, {});
  solver->reset({system_for(0, base_boundary(6))});
  solver->step(400);
  std::vector<Residual> measured;
  solver->measure(measured);
  std::vector<double> state;
  state_of(*solver).read_state(0, state);
  std::vector<float> totals(g.dims.count());
  solver->read_totals(0, totals.data());
  const FluxField flux = state_flux(g, ch, state);
  const Dims& d = g.dims;
  const std::size_t mid = d.index(3, 3, 6);
  CHECK(-flux[2][mid] < 0.9 * totals[mid]);  // B06 travels along -z
  CHECK(-flux[2][mid] > 0.0f);
  for (std::size_t i = 0; i < totals.size(); ++i) {
    if (d.is_boundary(i % d.nx, (i / d.nx) % d.ny, static_cast<int>(i / (static_cast<std::size_t>(d.nx) * d.ny)))) continue;
    const double j = std::sqrt(flux[0][i] * flux[0][i] + flux[1][i] * flux[1][i] + flux[2][i] * flux[2][i]);
    CHECK(j <= totals[i] * (1 + 1e-5) + 1e-7);
  }
}

TEST_CASE("P1: the radiance integrates back to the light, and its HG in-scattering is (phi + 3 g J.w) / 4 pi",
          "[moments][render]") {
  const std::vector<Vec3d> dirs = sphere_points(40000);
  const double phi = 2.0;
  const Vec3d flux{0.3, -0.2, 0.45};  // |J| < phi / 3: the P1 radiance stays positive
  double integral = 0;
  for (const Vec3d& w : dirs) integral += (phi + 3 * dot3(flux, w)) / (4 * kPi) * (4 * kPi / dirs.size());
  CHECK(integral == Approx(phi).epsilon(1e-6));
  const Vec3d out{0.6, 0.0, -0.8};
  for (double g : {-0.44, 0.0, 0.3, 0.47}) {
    double in_scattered = 0;  // integral of p_HG(w . out) L(w) dw with L the P1 radiance
    for (const Vec3d& w : dirs)
      in_scattered += henyey_greenstein_unclamped(g, dot3(w, out)) * (phi + 3 * dot3(flux, w)) / (4 * kPi) *
                      (4 * kPi / dirs.size());
    INFO("g = " << g);
    CHECK(p1_in_scattering(phi, flux, g, out) == Approx(in_scattered).epsilon(2e-3));
  }
  // Isotropic light or an isotropic phase function: phi / 4 pi; flux longer than the light is cut.
  CHECK(p1_in_scattering(phi, {0, 0, 0}, 0.8, out) == Approx(phi / (4 * kPi)));
  CHECK(p1_in_scattering(phi, flux, 0.0, out) == Approx(phi / (4 * kPi)));
  CHECK(p1_in_scattering(1.0, {0, 0, -5}, 0.3, {0, 0, -1}) == Approx((1.0 + 0.9) / (4 * kPi)));
  CHECK(p1_in_scattering(0.0, flux, 0.3, out) == 0.0);
}
