// The volume renderer (lblight/render/volume_render.h): an empty volume shows the background, a
// homogeneous slab lit from straight above matches the closed-form single-scattered radiance, the
// shadow term is exp(-optical depth) along a lattice axis, the direct term is linear in the sun,
// the LB term uses only the light beyond the unscattered sun, and images do not depend on threads.
#include <catch2/catch.hpp>

#include <cmath>

#include "lblight/lattice/d3q19.h"
#include "lblight/render/volume_render.h"

using namespace lblight;

namespace {

constexpr double kPi = 3.14159265358979323846;

// nx x ny x nz nodes of density rho, voxel edge 1, node (0, 0, 0) at the world origin.
RenderVolume slab(int nx, int ny, int nz, float rho, OpticalParams medium) {
  RenderVolume v;
  v.frame.dims = {nx, ny, nz};
  v.density.assign(v.frame.dims.count(), rho);
  for (auto& m : v.materials) m.fill(medium);
  return v;
}

// A camera above the slab's centre looking straight down; the centre pixel of a 3x3 image is the
// vertical ray through the centre.
Camera above(const RenderVolume& v) {
  Camera c;
  const double cx = 0.5 * (v.frame.dims.nx - 1), cy = 0.5 * (v.frame.dims.ny - 1);
  c.position = {cx, cy, v.frame.dims.nz + 20.0};
  c.look_at = {cx, cy, 0};
  c.up = {0, 1, 0};
  c.fov_degrees = 10;
  c.width = c.height = 3;
  return c;
}

double centre(const Image& img, int channel) { return img.rgba[(1 * 3 + 1) * 4 + channel]; }

}  // namespace

TEST_CASE("render: an empty volume shows the background, fully transparent", "[render]") {
  RenderVolume v = slab(8, 8, 8, 0.0f, {0.1, 0.5, 0.0});
  RenderSettings st;
  st.background = {0.2f, 0.3f, 0.4f};
  Camera c = above(v);
  c.width = c.height = 16;
  const Image img = render_volume(v, c, st);
  for (std::size_t p = 0; p < img.rgba.size() / 4; ++p) {
    REQUIRE(img.rgba[4 * p + 0] == 0.2f);
    REQUIRE(img.rgba[4 * p + 1] == 0.3f);
    REQUIRE(img.rgba[4 * p + 2] == 0.4f);
    REQUIRE(img.rgba[4 * p + 3] == 0.0f);
  }
}

TEST_CASE("render: the shadow term is exp(-optical depth) along a lattice axis", "[render]") {
  const RenderVolume v = slab(5, 5, 12, 0.6f, {0.05, 0.15, 0.0});
  const auto t = sun_transmittance(v, {0, 0, 1}, 0.5);
  const double sigma_t = 0.6 * 0.2;
  for (int k = 0; k < 12; ++k) {
    // From node k's centre up to the last node (the box's last half voxel is outside the nodes).
    const double expected = std::exp(-sigma_t * (11 - k));
    CHECK(t[1][v.frame.dims.index(2, 2, k)] == Approx(expected).epsilon(1e-5));
  }
}

TEST_CASE("render: a homogeneous slab lit from straight above matches the closed-form single scattering", "[render]") {
  // Radiance leaving the top of a slab of thickness L toward a viewer straight above, sun straight
  // above: L_ss = sigma_s p(g, -1) E (1 - exp(-2 sigma_t L)) / (2 sigma_t).
  for (const OpticalParams m : {OpticalParams{0.02, 0.05, 0.3}, OpticalParams{0.05, 0.2, -0.4}, OpticalParams{0.01, 0.1, 0.8}}) {
    const RenderVolume v = slab(41, 41, 21, 1.0f, m);
    RenderSettings st;
    st.toward_sun = {0, 0, 1};
    st.intensity = 2.0;
    st.term = RenderTerm::Direct;
    st.step = 0.25;
    const Image img = render_volume(v, above(v), st);
    const double L = 20, sigma_t = m.sigma_t();
    const double expected = m.sigma_s * henyey_greenstein(m.g, -1.0) * 2.0 * (1 - std::exp(-2 * sigma_t * L)) / (2 * sigma_t);
    INFO("sigma_a " << m.sigma_a << " sigma_s " << m.sigma_s << " g " << m.g);
    CHECK(centre(img, 0) == Approx(expected).epsilon(0.01));
    CHECK(centre(img, 3) == Approx(1 - std::exp(-sigma_t * L)).epsilon(0.01));  // alpha: 1 - transmittance
  }
}

TEST_CASE("render: the direct term is linear in the sun, and the LB term counts only light beyond the unscattered sun",
          "[render]") {
  RenderVolume v = slab(21, 21, 11, 0.8f, {0.03, 0.12, 0.2});
  RenderSettings st;
  st.toward_sun = {0.3, 0.2, 1.0};
  st.term = RenderTerm::Direct;
  const Image one = render_volume(v, above(v), st);
  st.intensity = 2.0;
  const Image two = render_volume(v, above(v), st);
  for (std::size_t i = 0; i < one.rgba.size(); i += 4) CHECK(two.rgba[i] == Approx(2 * one.rgba[i]).epsilon(1e-6));
  // LB light that is exactly the lattice's unscattered sun (split onto three lattice directions,
  // each attenuated along its own path) holds no scattered light: no indirect term.
  st.intensity = 1.5;
  const Vec3d travel{-0.3, -0.2, -1.0};
  const SunWeights split = decompose_direction(travel);
  std::array<std::vector<float>, 3> t;
  for (auto& c : t) c.assign(v.density.size(), 0.0f);
  for (int k = 0; k < 3; ++k) {
    const int m = split.direction[k];
    const auto tk = sun_transmittance(v, {-1.0 * d3q19::cx(m), -1.0 * d3q19::cy(m), -1.0 * d3q19::cz(m)}, st.step);
    for (int c = 0; c < 3; ++c)
      for (std::size_t i = 0; i < t[c].size(); ++i) t[c][i] += static_cast<float>(split.weight[k] * tk[c][i]);
  }
  for (int c = 0; c < 3; ++c) {
    v.light[c].resize(t[c].size());
    for (std::size_t i = 0; i < t[c].size(); ++i) v.light[c][i] = static_cast<float>(1.5 * t[c][i]);
  }
  st.term = RenderTerm::Indirect;
  const Image none = render_volume(v, above(v), st);
  for (std::size_t i = 0; i < none.rgba.size(); i += 4) CHECK(std::fabs(none.rgba[i]) < 1e-6);
  // One unit of scattered light everywhere: isotropic emission sigma_s / (4 pi) per unit length,
  // seen through the slab: (sigma_s / 4 pi) (1 - exp(-sigma_t L)) / sigma_t.
  for (int c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < t[c].size(); ++i) v.light[c][i] = static_cast<float>(1.5 * t[c][i] + 1.0);
  const Image unit = render_volume(v, above(v), st);
  const double sigma_t = 0.8 * 0.15, sigma_s = 0.8 * 0.12;
  CHECK(centre(unit, 1) == Approx(sigma_s / (4 * kPi) * (1 - std::exp(-sigma_t * 10)) / sigma_t).epsilon(0.005));
}

TEST_CASE("render: light solved with delta-M scaling is rendered in the same scaled medium", "[render]") {
  // Sun and eye straight above a slab of g = 0.8: the forward peak f = g^2 of scattering counts as
  // unscattered in the LB light. The eye ray then fades with sigma_t* = sigma_t - f sigma_s, the
  // direct term stays the exact single scattering, and LB light equal to its own unscattered sun
  // E T* (no scattered part) adds only the sun's light in the peak, E (T* - T), scattered by the
  // scaled phase function: closed forms over z (depth below the top node).
  const OpticalParams m{0.02, 0.2, 0.8};
  const double f = 0.64, ss = m.sigma_s * (1 - f), gs = (0.8 - f) / (1 - f);
  const double st_true = m.sigma_t(), st_scaled = m.sigma_a + ss, L = 20;
  RenderVolume v = slab(9, 9, 21, 1.0f, m);
  v.delta_m = true;
  RenderSettings st;
  st.toward_sun = {0, 0, 1};
  st.step = 0.1;
  st.term = RenderTerm::Direct;
  const auto integral = [&](double a) { return (1 - std::exp(-a * L)) / a; };
  const double direct = m.sigma_s * henyey_greenstein(m.g, -1.0) * integral(st_true + st_scaled);
  CHECK(centre(render_volume(v, above(v), st), 0) == Approx(direct).epsilon(0.01));
  for (auto& c : v.light) c.resize(v.density.size());
  for (int k = 0; k < 21; ++k)
    for (int j = 0; j < 9; ++j)
      for (int i = 0; i < 9; ++i)
        for (auto& c : v.light) c[v.frame.dims.index(i, j, k)] = static_cast<float>(std::exp(-st_scaled * (20 - k)));
  st.term = RenderTerm::Indirect;
  const double peak = ss * henyey_greenstein(gs, -1.0) * (integral(2 * st_scaled) - integral(st_true + st_scaled));
  CHECK(centre(render_volume(v, above(v), st), 0) == Approx(peak).epsilon(0.02));
  // Without delta-M the same light is mostly scattered light (E T* > E T), emitted isotropically.
  v.delta_m = false;
  CHECK(centre(render_volume(v, above(v), st), 0) > 2 * peak);
}

TEST_CASE("render: identical images for any thread count", "[render]") {
  RenderVolume v = slab(16, 12, 10, 0.5f, {0.05, 0.3, 0.5});
  for (std::size_t i = 0; i < v.density.size(); ++i) v.density[i] = static_cast<float>((i * 7919) % 97) / 97.0f;
  for (auto& c : v.light) c.assign(v.density.size(), 0.7f);
  RenderSettings st;
  st.toward_sun = {0.4, -0.3, 0.8};
  const std::optional<Camera> cam = orbit_camera(v, "three-quarter", 40, 30);
  REQUIRE(cam);
  st.threads = 1;
  const Image a = render_volume(v, *cam, st);
  st.threads = 2;
  const Image b = render_volume(v, *cam, st);
  CHECK(a.rgba == b.rgba);
  CHECK_FALSE(orbit_camera(v, "sideways", 4, 4));
}

TEST_CASE("render --grid: a uniform field shows its scale colour with the density's opacity, the scale is chosen and clamped",
          "[render]") {
  RenderVolume v = slab(6, 6, 10, 0.5f, {0.05, 0.3, 0.0});
  v.field.assign(v.density.size(), 3.0f);
  FieldSettings st;
  st.lo = 1;
  st.hi = 5;
  st.opacity = 0.4;
  const Image img = render_field(v, v.field, above(v), st);
  // Vertical ray through 10 nodes of density 0.5, interpolated between the outer node centres (9
  // voxel lengths): opacity 1 - exp(-0.4 * 0.5 * 9).
  const double alpha = 1 - std::exp(-0.4 * 0.5 * 9);
  const std::array<float, 3> c = false_colour(0.5);
  CHECK(centre(img, 3) == Approx(alpha).epsilon(1e-4));
  for (int k = 0; k < 3; ++k) CHECK(centre(img, k) == Approx(alpha * c[k]).epsilon(1e-4));
  // Ends of the scale: viridis runs from dark purple to yellow, and values beyond it are clamped.
  CHECK(false_colour(-1) == false_colour(0));
  CHECK(false_colour(7) == false_colour(1));
  CHECK(false_colour(1)[0] > 0.9f * false_colour(1)[1]);
  CHECK(false_colour(0)[2] > false_colour(0)[1]);
  CHECK(st.position(3) == Approx(0.5));
  st.log = true;
  st.lo = 0.01;
  st.hi = 100;
  CHECK(st.position(1) == Approx(0.5));
  CHECK(st.position(0) == 0.0);
  // Automatic scale over the occupied nodes only: the hot node outside the medium is ignored.
  RenderVolume w = slab(10, 10, 10, 0.0f, {0.05, 0.3, 0.0});
  w.field.assign(w.density.size(), 0.0f);
  for (int i = 0; i < 1000; ++i) {
    if (i % 2) continue;
    w.density[static_cast<std::size_t>(i)] = 1.0f;
    w.field[static_cast<std::size_t>(i)] = static_cast<float>(i) / 1000.0f;
  }
  w.field[1] = 1e6f;
  FieldSettings a;
  choose_field_scale(w, a);
  CHECK(a.lo == 0.0);
  CHECK(a.hi == Approx(0.996).margin(0.004));
  a.log = true;
  choose_field_scale(w, a);
  CHECK(a.lo == Approx(0.002));  // the smallest positive value, 2.7 decades under high (within the 4-decade cap)
  st.hi = st.lo;
  CHECK_THROWS(render_field(v, v.field, above(v), st));
}

TEST_CASE("render --term lb: the whole LB light scattered isotropically, whatever the sun", "[render]") {
  RenderVolume v = slab(21, 21, 11, 0.8f, {0.03, 0.12, 0.2});
  for (auto& c : v.light) c.assign(v.density.size(), 2.0f);
  RenderSettings st;
  st.term = RenderTerm::Lb;
  st.toward_sun = {0.3, 0.2, 1.0};
  const Image a = render_volume(v, above(v), st);
  const double sigma_t = 0.8 * 0.15, sigma_s = 0.8 * 0.12;
  CHECK(centre(a, 1) == Approx(sigma_s * 2.0 / (4 * kPi) * (1 - std::exp(-sigma_t * 10)) / sigma_t).epsilon(0.005));
  st.intensity = 7;  // no direct term and nothing taken out
  st.toward_sun = {0, 0, 1};
  const Image b = render_volume(v, above(v), st);
  CHECK(a.rgba == b.rgba);
}

TEST_CASE("render: with the light's flux, the scattered light is in-scattered with the phase function (P1)",
          "[render][moments]") {
  // Light 1 and flux J everywhere, no sun: the indirect term emits sigma_s (1 + 3 g J . w) / 4 pi
  // toward the eye (w = +z for a camera above), seen through the slab.
  const double g = 0.4;
  RenderVolume v = slab(21, 21, 11, 0.8f, {0.03, 0.12, g});
  RenderSettings st;
  st.intensity = 0.0;
  st.term = RenderTerm::Indirect;
  for (int c = 0; c < 3; ++c) {
    v.light[c].assign(v.frame.dims.count(), 1.0f);
    for (int a = 0; a < 3; ++a) v.flux[c][a].assign(v.frame.dims.count(), a == 2 ? 0.25f : 0.1f);
  }
  const double sigma_t = 0.8 * 0.15, sigma_s = 0.8 * 0.12, seen = (1 - std::exp(-sigma_t * 10)) / sigma_t;
  const Image toward = render_volume(v, above(v), st);
  CHECK(centre(toward, 1) == Approx(sigma_s * (1 + 3 * g * 0.25) / (4 * kPi) * seen).epsilon(0.005));
  for (int c = 0; c < 3; ++c) v.flux[c][2].assign(v.frame.dims.count(), -0.25f);  // flowing away from the eye
  const Image away = render_volume(v, above(v), st);
  CHECK(centre(away, 1) == Approx(sigma_s * (1 - 3 * g * 0.25) / (4 * kPi) * seen).epsilon(0.005));
  for (auto& f : v.flux) f = {};  // no flux: isotropic, as before
  const Image iso = render_volume(v, above(v), st);
  CHECK(centre(iso, 1) == Approx(sigma_s / (4 * kPi) * seen).epsilon(0.005));
}
