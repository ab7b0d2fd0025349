// The calibrated LB model's collision matrix and boundary values (docs/model.md sec. 8): each
// correction does what it claims, and the papers' model is untouched.
#include <catch2/catch.hpp>

#include <cmath>

#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/lb_model.h"

using namespace lblight;
using namespace lblight::d3q19;

namespace {
double at(const OmegaMatrix& om, int m, int n) { return om[static_cast<std::size_t>(m) * kQ + n]; }
LbModel calibrated() {
  LbModel m;
  m.calibrated = true;
  return m;
}
LbModel only(const char* correction) {
  LbModel m = calibrated();
  for (int k = 0; k < static_cast<int>(kCalibrationNames.size()); ++k)
    *calibration_switch(m, k) = std::string(kCalibrationNames[k]) == correction;
  return m;
}
}  // namespace

TEST_CASE("The papers' model builds the papers' Omega, whatever the switches say") {
  LbModel paper;
  paper.path_length = paper.delta_m = true;
  for (const OpticalParams p : {OpticalParams{0.008, 0.792, 0.9}, OpticalParams{0.3, 0.3, 0.0}, OpticalParams{0.1, 0.9, -1}})
    CHECK(build_model_omega(p, paper) == build_omega(p));
  CHECK(ambient_boundary(paper)[0] == 1.0);
  CHECK(paper.name() == "paper");
  CHECK(calibrated().name() == "calibrated");
  CHECK(only("delta_m").name() ==
        "calibrated (no path_length, phase_moment, isotropic_ambient, remove_absorbed, voxel_average, diffusion_match, "
        "decay_match)");
  CHECK(only("path_absorption").name() ==
        "calibrated (no path_length, phase_moment, delta_m, isotropic_ambient, remove_absorbed, voxel_average, "
        "diffusion_match, decay_match; with path_absorption)");
}

TEST_CASE("Calibrated with every correction off is the papers' Omega") {
  const OpticalParams p{0.05, 0.6, 0.4};
  const OmegaMatrix a = build_model_omega(p, only("none")), b = build_omega(p);
  for (std::size_t i = 0; i < a.size(); ++i) CHECK(a[i] == Approx(b[i]).margin(1e-15));
}

TEST_CASE("path_length: an absorber passes exp(-sigma_t |c_j|) per step along every direction") {
  const OpticalParams p{0.7, 0.0, 0.0};
  const OmegaMatrix om = build_model_omega(p, only("path_length"));
  for (int j = 1; j < kQ; ++j) {
    CAPTURE(j);
    CHECK(1.0 + at(om, j, j) == Approx(std::exp(-0.7 * std::sqrt(double(length_sq(j))))).epsilon(1e-14));
    for (int i = 1; i < kQ; ++i)
      if (i != j) CHECK(at(om, i, j) == 0.0);
  }
  // Dense media no longer overshoot: the diagonal gain stays positive even at sigma_t = 3.
  CHECK(min_diagonal_gain(build_model_omega({0.5, 2.5, 0.0}, calibrated()), 1.0) >= 0.0);  // f_0's own 1 - 1
  CHECK(min_diagonal_gain(build_omega({0.5, 2.5, 0.0}), 1.0) < 0.0);
}

TEST_CASE("phase_moment: the discrete phase function's mean cosine equals g") {
  // The papers' discrete HG is far more forward than g (docs/truth.md: 0.995 for g = 0.9).
  CHECK(discrete_mean_cosine(0.9, 5) > 0.98);
  for (double g : {-0.6, -0.2, 0.0, 0.3, 0.5, 0.8, 0.9, 0.97})
    for (int j : {1, 6, 7, 16}) {
      CAPTURE(g, j);
      const double gm = moment_matched_g(g, j);
      CHECK(discrete_mean_cosine(gm, j) == Approx(g).margin(1e-9));
      if (g >= 0.8) CHECK(gm < g);  // strong forward peaks need a weaker discrete g
    }
}

TEST_CASE("delta_m: a forward peak of g^2 passes unscattered, keeping sigma_s (1 - g)") {
  const OpticalParams p{0.0, 0.8, 0.9};
  const OmegaMatrix om = build_model_omega(p, only("delta_m"));
  // The papers' form with sigma_s (1 - g^2) and g / (1 + g).
  const OmegaMatrix ref = build_omega({0.0, 0.8 * (1 - 0.81), 0.9 / 1.9});
  for (std::size_t i = 0; i < om.size(); ++i) CHECK(om[i] == Approx(ref[i]).margin(1e-14));
  // Backward peaks are left alone.
  const OmegaMatrix back = build_model_omega({0.1, 0.5, -0.5}, only("delta_m")), paper = build_omega({0.1, 0.5, -0.5});
  for (std::size_t i = 0; i < back.size(); ++i) CHECK(back[i] == Approx(paper[i]).margin(1e-15));
}

TEST_CASE("remove_absorbed: nothing enters f_0, so absorbed light leaves and the total is the moving part") {
  const OmegaMatrix om = build_model_omega({0.2, 0.5, 0.3}, calibrated());
  for (int j = 1; j < kQ; ++j) CHECK(at(om, 0, j) == 0.0);
  CHECK(model_absorbs(false, calibrated()));
  CHECK_FALSE(model_absorbs(false, LbModel{}));
  // Each column loses the absorbed share of what it removes (and, with path_length, the
  // difference of step lengths between the directions it scatters into).
  const OmegaMatrix pure = build_model_omega({0.2, 0.5, 0.3}, only("remove_absorbed"));
  for (int j = 1; j < kQ; ++j) {
    double sum = 0;
    for (int i = 0; i < kQ; ++i) sum += at(pure, i, j);
    CHECK(sum == Approx(-0.2).epsilon(1e-12));
  }
}

TEST_CASE("A calibrated collision keeps the light it does not absorb") {
  // Lossless: every column sums to 0 (sec. 2.2 holds as for the papers' model); absorbing: a
  // column loses the absorbed share of what its direction removes, 1 - exp(-sigma_t |c_j|).
  for (const OpticalParams p : {OpticalParams{0.0, 0.8, 0.0}, OpticalParams{0.0, 2.5, 0.7}, OpticalParams{0.3, 0.3, 0.2}}) {
    const OmegaMatrix om = build_model_omega(p, calibrated());
    for (int j = 1; j < kQ; ++j) {
      double sum = 0;
      for (int i = 0; i < kQ; ++i) sum += at(om, i, j);
      CAPTURE(p.sigma_a, p.sigma_s, p.g, j);
      double st = p.sigma_a + p.sigma_s, ss = p.sigma_s;
      if (p.g > 0) ss *= 1 - p.g * p.g, st = p.sigma_a + ss;  // delta_m
      const double removed = 1 - std::exp(-st * std::sqrt(double(length_sq(j))));
      CHECK(sum == Approx(-removed * p.sigma_a / st).margin(1e-14));
    }
  }
}

TEST_CASE("isotropic_ambient: B00's boundary is 18 w_i, as much light in every direction per solid angle") {
  const auto f = ambient_boundary(calibrated());
  double sum = 0;
  for (int i = 1; i < kQ; ++i) sum += f[static_cast<std::size_t>(i)];
  CHECK(sum == Approx(18.0));
  CHECK(f[0] == 0.0);
  CHECK(f[1] == Approx(1.5));
  CHECK(f[7] == Approx(0.75));
  // Flux through a face: 4.5 units per node, as isotropic light of fluence 18 gives (18 / 4), not the papers' 5.
  double flux = 0, paper = 0;
  for (int i = 1; i < kQ; ++i)
    if (cz(i) > 0) flux += f[static_cast<std::size_t>(i)], paper += 1.0;
  CHECK(flux == Approx(4.5));
  CHECK(paper == 5.0);
}

TEST_CASE("The lattice's diffusion coefficient: the papers' eq. (4), and the physical one under diffusion_match") {
  std::array<double, kQ> removed{};
  for (double st : {0.1, 0.8, 1.5}) {
    removed.fill(st);
    CHECK(lattice_diffusion(build_omega({0.0, st, 0.0}), removed) == Approx((1.0 / st - 0.5) / 2.0).epsilon(1e-12));
  }
  // diffusion_match: the lattice's coefficient is 1 / (3 (sigma_a + sigma_s (1 - g))), for thin and
  // dense media, forward and isotropic scattering.
  for (const OpticalParams p : {OpticalParams{0.008, 0.792, 0.0}, OpticalParams{0.3, 0.3, 0.0},
                                OpticalParams{0.01, 0.09, 0.5}, OpticalParams{0.008, 0.792, 0.9}}) {
    CAPTURE(p.sigma_a, p.sigma_s, p.g);
    double ss = p.sigma_s;
    if (p.g > 0) ss *= 1 - p.g * p.g;  // delta_m
    const double st = p.sigma_a + ss;
    for (int k = 1; k < kQ; ++k) removed[static_cast<std::size_t>(k)] = 1 - std::exp(-st * std::sqrt(double(length_sq(k))));
    const double physical = 1.0 / (3.0 * (p.sigma_a + p.sigma_s * (1 - p.g)));
    LbModel matched = calibrated();
    matched.decay_match = false;  // (tested below)
    CHECK(lattice_diffusion(build_model_omega(p, matched), removed) == Approx(physical).epsilon(1e-6));
    // without it (mean cosine g) the lattice diffuses differently
    LbModel moment = calibrated();
    moment.diffusion_match = false;
    CHECK(std::abs(lattice_diffusion(build_model_omega(p, moment), removed) / physical - 1) > 0.05);
  }
}
