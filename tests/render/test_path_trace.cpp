// The path-traced reference picture (lblight/render/path_trace.h) against closed forms: an empty
// volume, the single scattering of a slab lit and seen from straight above, a lossless medium in
// uniform light (the "furnace": radiance L everywhere, so a pixel shows L (1 - T)), its alpha, and
// the same image for any thread count.
#include <catch2/catch.hpp>

#include <cmath>

#include "lblight/render/path_trace.h"

using namespace lblight;

namespace {

constexpr double kPi = 3.14159265358979323846;

RenderVolume box(int nx, int ny, int nz, float rho, OpticalParams medium) {
  RenderVolume v;
  v.frame.dims = {nx, ny, nz};
  v.density.assign(v.frame.dims.count(), rho);
  for (auto& m : v.materials) m.fill(medium);
  return v;
}

// A camera above the box's centre looking straight down, 3x3 pixels of a narrow field.
Camera above(const RenderVolume& v) {
  Camera c;
  const double cx = 0.5 * (v.frame.dims.nx - 1), cy = 0.5 * (v.frame.dims.ny - 1);
  c.position = {cx, cy, v.frame.dims.nz + 20.0};
  c.look_at = {cx, cy, 0};
  c.up = {0, 1, 0};
  c.fov_degrees = 2;
  c.width = c.height = 3;
  return c;
}

// The mean of the 9 pixels of channel c and its standard error (pixels are independent).
std::pair<double, double> mean_and_se(const ReferenceImage& r, int c) {
  double m = 0, var = 0;
  for (int p = 0; p < 9; ++p) {
    m += r.image.rgba[4 * p + c] / 9.0;
    var += std::pow(r.std_error[3 * p + c] / 9.0, 2);
  }
  return {m, std::sqrt(var)};
}

}  // namespace

TEST_CASE("path_trace: an empty volume shows the background, alpha 0", "[render]") {
  const RenderVolume v = box(6, 6, 6, 0.0f, {0.1, 0.5, 0.0});
  PathTraceSettings st;
  st.background = {0.2f, 0.3f, 0.4f};
  st.max_samples = 4;
  const ReferenceImage r = path_trace(v, above(v), st);
  for (int p = 0; p < 9; ++p) {
    CHECK(r.image.rgba[4 * p] == 0.2f);
    CHECK(r.image.rgba[4 * p + 2] == 0.4f);
    CHECK(r.image.rgba[4 * p + 3] == 0.0f);
    CHECK(r.std_error[3 * p] == 0.0f);
  }
}

TEST_CASE("path_trace: single scattering of a slab matches the closed form within its standard error", "[render]") {
  // Sun and eye straight above a slab of optical thickness sigma_t L (nodes 0..nz-1 at density 1):
  // L_ss = sigma_s p(g, -1) E (1 - exp(-2 sigma_t L)) / (2 sigma_t).
  for (const OpticalParams m : {OpticalParams{0.02, 0.05, 0.3}, OpticalParams{0.05, 0.2, -0.4}}) {
    const RenderVolume v = box(9, 9, 21, 1.0f, m);
    PathTraceSettings st;
    st.toward_sun = {0, 0, 1};
    st.intensity = 2.0;
    st.max_scatterings = 1;
    st.max_samples = st.samples_per_pass = 20000;
    const ReferenceImage r = path_trace(v, above(v), st);
    const double L = 20, sigma_t = m.sigma_t();
    const double expected = m.sigma_s * henyey_greenstein(m.g, -1.0) * 2.0 * (1 - std::exp(-2 * sigma_t * L)) / (2 * sigma_t);
    const auto [mean, se] = mean_and_se(r, 1);
    INFO("mean " << mean << " se " << se << " expected " << expected);
    CHECK(se < 0.02 * expected);
    CHECK(std::fabs(mean - expected) < 4 * se);
    // The alpha: the fraction of paths that met the medium, 1 - exp(-sigma_t L).
    double alpha = 0;
    for (int p = 0; p < 9; ++p) alpha += r.image.rgba[4 * p + 3] / 9.0;
    CHECK(alpha == Approx(1 - std::exp(-sigma_t * L)).epsilon(0.01));
  }
}

TEST_CASE("path_trace: a lossless medium in uniform light shows that light times its opacity (furnace)", "[render]") {
  // Every order of scattering: in uniform radiance L a lossless medium's radiance is L everywhere,
  // so with a black background a pixel shows L (1 - exp(-tau)) of its ray's optical depth tau.
  const RenderVolume v = box(9, 9, 9, 1.0f, {0.0, 0.25, 0.6});
  PathTraceSettings st;
  st.intensity = 0;
  st.ambient = 0.5;  // radiance 18 x 0.5 / (4 pi)
  st.max_samples = st.samples_per_pass = 4000;
  const ReferenceImage r = path_trace(v, above(v), st);
  const double radiance = 18 * 0.5 / (4 * kPi), tau = 0.25 * 8;
  const auto [mean, se] = mean_and_se(r, 0);
  INFO("mean " << mean << " se " << se);
  CHECK(std::fabs(mean - radiance * (1 - std::exp(-tau))) < 4 * se + 1e-9);
  // A sky of level S: radiance 9 S / (2 pi) from above only; an absorbing medium shows less.
  PathTraceSettings sky = st;
  sky.ambient = 0;
  sky.sky = 1.0;
  const auto [sky_mean, sky_se] = mean_and_se(path_trace(v, above(v), sky), 0);
  CHECK(sky_mean < 9 / (2 * kPi) * (1 - std::exp(-tau)));
  CHECK(sky_mean > 0.1 * 9 / (2 * kPi) * (1 - std::exp(-tau)));
  (void)sky_se;
}

TEST_CASE("path_trace: the same image for any thread count, and stops at its target error", "[render]") {
  RenderVolume v = box(10, 8, 6, 0.7f, {0.05, 0.4, 0.5});
  for (std::size_t i = 0; i < v.density.size(); i += 3) v.density[i] = 0.2f;
  Camera c = above(v);
  c.fov_degrees = 40;
  c.width = 12;
  c.height = 10;
  PathTraceSettings st;
  st.toward_sun = {0.3, 0.2, 0.9};
  st.sky = 0.1;
  st.max_samples = 24;
  st.threads = 1;
  const ReferenceImage one = path_trace(v, c, st);
  st.threads = 2;
  const ReferenceImage two = path_trace(v, c, st);
  CHECK(one.image.rgba == two.image.rgba);
  CHECK(one.std_error == two.std_error);
  CHECK(one.samples == 24);
  st.target_error = 0.5;
  st.max_samples = 100000;
  const ReferenceImage stopped = path_trace(v, c, st);
  CHECK(stopped.relative_error <= 0.5);
  CHECK(stopped.samples < 100000);
}
