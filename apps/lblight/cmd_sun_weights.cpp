// lblight sun-weights: which base solutions a sun selects and with what weights ([Steele2009]
// sec. 4.1, docs/output-format.md "Relighting"), so a shader or script needs no port of the
// 32-face decomposition; --faces prints the polyhedron itself.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/core/error.h"
#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/sun.h"
#include "lblight/pipeline/relight.h"
#include "lblight/solve/plan.h"

namespace lblight::cli {
namespace {

struct SunWeightArgs {
  double elevation = 45, azimuth = 0, intensity = 1, ambient = 0, sky = 0;
  std::vector<double> direction;
  bool json = false, faces = false;
};

std::string velocity(int j) {
  char b[24];
  std::snprintf(b, sizeof b, "(%+d,%+d,%+d)", d3q19::cx(j), d3q19::cy(j), d3q19::cz(j));
  return b;
}

int run_sun_weights(const SunWeightArgs& a) {
  if (a.faces) {
    nlohmann::json out = nlohmann::json::array();
    if (!a.json) std::cout << "| face | grids | lattice directions |\n|---|---|---|\n";
    int k = 0;
    for (const auto& f : polyhedron_faces()) {
      if (a.json) {
        out.push_back({{"face", k}, {"grids", {base_grid_name(f[0]), base_grid_name(f[1]), base_grid_name(f[2])}},
                       {"directions", {{d3q19::cx(f[0]), d3q19::cy(f[0]), d3q19::cz(f[0])},
                                       {d3q19::cx(f[1]), d3q19::cy(f[1]), d3q19::cz(f[1])},
                                       {d3q19::cx(f[2]), d3q19::cy(f[2]), d3q19::cz(f[2])}}}});
      } else {
        std::cout << "| " << k << " | " << base_grid_name(f[0]) << " " << base_grid_name(f[1]) << " " << base_grid_name(f[2]) << " | "
                  << velocity(f[0]) << " " << velocity(f[1]) << " " << velocity(f[2]) << " |\n";
      }
      ++k;
    }
    if (a.json) std::cout << out.dump(1) << "\n";
    return 0;
  }
  RelightRequest req;
  if (!a.direction.empty()) {
    if (a.direction.size() != 3) throw_invalid("--direction takes three numbers x,y,z (toward the sun)");
    req.toward_sun = {a.direction[0], a.direction[1], a.direction[2]};
  } else {
    req.toward_sun = toward_sun_from_angles(a.elevation, a.azimuth);
  }
  req.intensity = a.intensity;
  req.ambient = a.ambient;
  req.sky = a.sky;
  const std::vector<std::pair<int, double>> w = relight_weights(req);
  if (a.json) {
    nlohmann::json out = {{"toward_sun", {req.toward_sun.x, req.toward_sun.y, req.toward_sun.z}}, {"weights", nlohmann::json::array()}};
    for (const auto& [j, weight] : w) out["weights"].push_back({{"grid", base_grid_name(j)}, {"direction", {d3q19::cx(j), d3q19::cy(j), d3q19::cz(j)}}, {"weight", weight}});
    std::cout << out.dump(1) << "\n";
    return 0;
  }
  std::cout << "light = sum of weight x grid (1 = the open-air light of a unit sun):\n";
  for (const auto& [j, weight] : w) std::cout << "  " << base_grid_name(j) << " " << velocity(j) << "  " << weight << "\n";
  return 0;
}

}  // namespace

Command add_sun_weights_command(CLI::App& app, const GlobalOptions&) {
  auto args = std::make_shared<SunWeightArgs>();
  CLI::App* cmd = app.add_subcommand(
      "sun-weights",
      "The base-solution grids and weights that relight a bake for a sun: the three lattice directions (the way the light travels) of the "
      "32-face polyhedron face the sunlight's travel direction hits, with its barycentric weights x intensity "
      "([Steele2009] sec. 4.1), then B00 x ambient and the sky's downward and level directions. --faces prints the "
      "32 faces. Plain text, or JSON with --json.");
  cmd->add_option("--elevation", args->elevation, "Sun elevation in degrees (90 = zenith)")->check(finite_range(-90.0, 90.0))->capture_default_str();
  cmd->add_option("--azimuth", args->azimuth, "Sun azimuth in degrees from +x toward +y")->check(finite_range(-360.0, 360.0))->capture_default_str();
  cmd->add_option("--direction", args->direction, "Or a vector toward the sun x,y,z")->delimiter(',')->expected(3);
  cmd->add_option("--intensity", args->intensity, "Sun intensity")->check(finite_range(0.0, 1e6))->capture_default_str();
  cmd->add_option("--ambient", args->ambient, "Ambient level (x B00)")->check(finite_range(0.0, 1e6))->capture_default_str();
  cmd->add_option("--sky", args->sky, "Sky level (upper hemisphere)")->check(finite_range(0.0, 1e6))->capture_default_str();
  cmd->add_flag("--json", args->json, "Print JSON");
  cmd->add_flag("--faces", args->faces, "Print the 32 faces of the polyhedron instead");
  return {cmd, [args] { return run_sun_weights(*args); }};
}

}  // namespace lblight::cli
