// lblight render: a picture of a bake for a sun (docs/rendering.md): single scattering of the sun
// with shadows plus the LB solution's multiple scattering, ray marched, to OpenEXR and a PNG preview.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/core/error.h"
#include "lblight/core/version.h"
#include "lblight/io/image_io.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/run_paths.h"
#include "lblight/lattice/d3q19.h"
#include "lblight/pipeline/manifest.h"
#include "lblight/pipeline/relight.h"
#include "lblight/pipeline/render_bake.h"
#include "lblight/render/path_trace.h"
#include "lblight/render/picture_metrics.h"
#include "lblight/render/scale_bar.h"
#include "lblight/solve/plan.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct RenderArgs {
  std::string input, model, output = "render.exr", png, orbit = "three-quarter", size = "512x512", term = "all",
              scattering = "phase";
  std::string material, wood_material, grid;
  std::vector<double> camera, look_at, range;
  double opacity = 0.5;
  bool log = false;
  double fov = 35, elevation = 45, azimuth = 0, intensity = 1, ambient = 0, sky = 0, exposure = 0, step = 0.5;
  bool half = true, full_float = false, sheet = false;
  int threads = 0;
  bool reference = false;  // path-traced reference (render/path_trace.h)
  double target_error = 0.02, time_budget = 0;
  int samples = 4096;
  long long seed = 1;
  int max_scatterings = 0;
  std::string against;  // a reference EXR to compare the picture with (picture_metrics.h)
};

Vec3d vec3(const std::vector<double>& v, const char* option) {
  if (v.size() != 3) throw_invalid(std::string(option) + " takes three numbers x,y,z");
  return {v[0], v[1], v[2]};
}

std::string format3(const Vec3d& v) {
  std::ostringstream s;
  s << v.x << " " << v.y << " " << v.z;
  return s.str();
}

// Linear radiance to 8-bit sRGB over a dark grey: exposure so the 99.5th percentile of the lit
// pixels maps to 0.9 unless given.
std::vector<std::uint8_t> tone_map(const Image& img, double exposure) {
  const std::size_t n = static_cast<std::size_t>(img.width) * img.height;
  if (!(exposure > 0)) {
    std::vector<float> lum;
    for (std::size_t i = 0; i < n; ++i)
      if (img.rgba[4 * i + 3] > 1e-3f) lum.push_back((img.rgba[4 * i] + img.rgba[4 * i + 1] + img.rgba[4 * i + 2]) / 3.0f);
    exposure = 1.0;
    if (!lum.empty()) {
      const float p = upper_percentile(lum);
      if (p > 0) exposure = 0.9 / p;
    }
  }
  std::vector<std::uint8_t> out(3 * n);
  for (std::size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      const double alpha = img.rgba[4 * i + 3];
      double v = std::clamp(exposure * img.rgba[4 * i + c] + (1 - alpha) * 0.05, 0.0, 1.0);
      v = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
      out[3 * i + c] = static_cast<std::uint8_t>(std::lround(255 * v));
    }
  return out;
}

// The contact sheet: every base solution of a bake rendered as light of its own (its total,
// emitted by the medium's scattering, each tile exposed on its own), labelled, in one SVG.
int run_sheet(const RenderArgs& a, const RenderSource& src_in, int width, int height, const fs::path& out,
              const RunContext& ctx) {
  RenderSource src = src_in;
  src.light = false;
  RenderVolume volume = load_render_volume(src, {}, ctx);
  fs::path vdb = a.input;
  if (fs::is_directory(vdb)) {
    const nlohmann::json m = read_manifest(vdb);
    std::string model = a.model;
    if (model.empty())
      for (const auto& e : m["models"])
        if (e["file"].is_string()) model = e["name"].get<std::string>();
    vdb = manifest_file(vdb, model + ".vdb", "/models");
  }
  const BaseSolutions base(vdb, std::nullopt, "the contact sheet", ctx);
  std::vector<int> solutions;
  for (int j = 0; j < 19; ++j)
    if (base.has(j)) solutions.push_back(j);
  if (solutions.empty()) throw_invalid("no base solutions (B00..B18) in this file: a static bake has one 'light' grid", {vdb.string(), {}, {}});
  const std::optional<Camera> cam = orbit_camera(volume, a.orbit, width, height);
  if (!cam) throw_invalid("--orbit '" + a.orbit + "'; allowed: " + kOrbitPresets);
  RenderSettings st;
  st.intensity = 0;  // nothing to take out: each tile shows its solution's whole light
  st.term = RenderTerm::Indirect;
  st.step = a.step;
  st.threads = usable_threads(a.threads);
  const std::vector<std::uint8_t> near = near_medium(volume.frame.dims, volume.density, 1);
  const int columns = std::min<int>(5, static_cast<int>(solutions.size()));
  const int rows = (static_cast<int>(solutions.size()) + columns - 1) / columns;
  const int label = 22;
  std::ostringstream svg;
  svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << columns * width << "\" height=\"" << rows * (height + label)
      << "\" font-family=\"sans-serif\" font-size=\"14\">\n<rect width=\"100%\" height=\"100%\" fill=\"#202020\"/>\n";
  for (std::size_t k = 0; k < solutions.size(); ++k) {
    const int j = solutions[k];
    std::array<std::vector<float>, 3> light;
    for (auto& c : light) c.assign(volume.frame.dims.count(), 0.0f);
    base.combine({{j, 1.0}}, light);
    for (int c = 0; c < 3; ++c)
      for (std::size_t i = 0; i < light[c].size(); ++i)
        if (!near[i]) light[c][i] = 0.0f;
    volume.light = std::move(light);
    const Image img = render_volume(volume, *cam, st, ctx);
    const std::string png = encode_png(width, height, tone_map(img, 0));
    const int x = static_cast<int>(k) % columns * width, y = static_cast<int>(k) / columns * (height + label);
    svg << "<image x=\"" << x << "\" y=\"" << y + label << "\" width=\"" << width << "\" height=\"" << height
        << "\" href=\"data:image/png;base64," << base64(png) << "\"/>\n";
    svg << "<text x=\"" << x + 6 << "\" y=\"" << y + 16 << "\" fill=\"#e0e0e0\">" << base_grid_name(j) << " ("
        << d3q19::cx(j) << "," << d3q19::cy(j) << "," << d3q19::cz(j) << ")" << (j == 0 ? " ambient" : "") << "</text>\n";
  }
  svg << "</svg>\n";
  write_file_atomically(out, svg.str());
  std::cout << "contact sheet of " << solutions.size() << " base solution(s), tiles " << width << "x" << height
            << " (each exposed on its own): " << out.string() << "\n";
  return 0;
}

// --against: the picture's numbers against a reference picture of the same camera.
void print_metrics(const Image& img, const std::string& file, const Camera& cam, const Vec3d& toward_sun) {
  Image ref;
  std::vector<float> se;
  ref.rgba = read_exr(file, ref.width, ref.height, nullptr, &se);
  const PictureMetrics m = compare_pictures(img, ref, se, cam, toward_sun);
  std::cout << "against " << file << ": mean " << message_number(m.mean_ratio) << " x the reference's; 4x4-block L1 "
            << message_number(m.block_l1) << " (the reference's own noise " << message_number(m.reference_noise)
            << "); sun/shade " << message_number(m.sun_shade) << " (reference " << message_number(m.reference_sun_shade)
            << "); top/bottom " << message_number(m.top_bottom) << " (reference "
            << message_number(m.reference_top_bottom) << ")\n";
}

// --reference: every order of scattering path traced through the same volume, sun, sky and
// ambient light (docs/rendering.md sec. 4); the EXR carries the standard errors as se.R/G/B.
int run_reference(const RenderArgs& a, const GlobalOptions& global, const RenderVolume& volume, const Camera& cam,
                  const fs::path& exr, const fs::path& png, const RunContext& ctx) {
  PathTraceSettings pt;
  pt.toward_sun = toward_sun_from_angles(a.elevation, a.azimuth);
  pt.intensity = a.intensity;
  pt.sky = a.sky;
  pt.ambient = a.ambient;
  pt.target_error = a.target_error;
  pt.time_budget = a.time_budget;
  pt.max_samples = a.samples;
  pt.max_scatterings = a.max_scatterings;
  pt.seed = static_cast<std::uint64_t>(a.seed);
  pt.threads = usable_threads(a.threads);
  pt.progress = [](int samples, double error) {
    spdlog::info("reference: {} path(s) per pixel and channel, relative standard error {:.4f}", samples, error);
  };
  const ReferenceImage ref = path_trace(volume, cam, pt, ctx);
  const std::map<std::string, std::string> attrs = {
      {"lblight_version", kVersion},
      {"lblight_command", global.command_line},
      {"lblight_source", a.input},
      {"lblight_camera_position", format3(cam.position)},
      {"lblight_camera_look_at", format3(cam.look_at)},
      {"lblight_camera_fov_degrees", std::to_string(cam.fov_degrees)},
      {"lblight_sun", "elevation " + std::to_string(a.elevation) + " azimuth " + std::to_string(a.azimuth) +
                          " intensity " + std::to_string(a.intensity) + " ambient " + std::to_string(a.ambient) +
                          " sky " + std::to_string(a.sky)},
      {"lblight_term", "reference"},
      {"lblight_reference", "path traced, every order: " + std::to_string(ref.samples) +
                                " paths per pixel and channel, relative standard error " +
                                message_number(ref.relative_error) + ", seed " + std::to_string(a.seed)},
      {"lblight_units", "radiance; 1 = a unit sun's irradiance per steradian; se.R/G/B: standard error of the mean"}};
  write_file_atomically(exr, [&](const fs::path& tmp) {
    write_exr(tmp, cam.width, cam.height, ref.image.rgba, !a.full_float, attrs, &ref.std_error);
  });
  write_file_atomically(png, [&](const fs::path& tmp) { write_png(tmp, cam.width, cam.height, tone_map(ref.image, a.exposure)); });
  std::cout << "reference " << cam.width << "x" << cam.height << ": " << ref.samples
            << " paths per pixel and channel, relative standard error " << message_number(ref.relative_error) << ", "
            << ref.seconds << " s: " << exr.string() << ", preview " << png.string() << "\n";
  return 0;
}

int run_render(const RenderArgs& a, const GlobalOptions& global) {
  int width = 0, height = 0;
  char x = 0;
  std::istringstream ss(a.size);
  if (!(ss >> width >> x >> height) || x != 'x' || !ss.eof() || width < 1 || height < 1 || width > 16384 || height > 16384)
    throw_invalid("--size '" + a.size + "': expected WIDTHxHEIGHT, each 1..16384");
  RelightRequest sun;
  sun.toward_sun = toward_sun_from_angles(a.elevation, a.azimuth);
  sun.intensity = a.intensity;
  sun.ambient = a.ambient;
  sun.sky = a.sky;
  RenderSource src;
  src.input = a.input;
  src.model = a.model;
  if (!a.material.empty()) src.material = a.material;
  if (!a.wood_material.empty()) src.wood_material = a.wood_material;
  RenderSettings st;
  st.toward_sun = sun.toward_sun;
  st.intensity = a.intensity;
  st.step = a.step;
  st.threads = usable_threads(a.threads);
  st.term = a.term == "direct"     ? RenderTerm::Direct
            : a.term == "indirect" ? RenderTerm::Indirect
            : a.term == "lb"       ? RenderTerm::Lb
                                   : RenderTerm::All;
  src.light = st.term != RenderTerm::Direct && !a.reference;
  // --term lb in-scatters the whole light isotropically (the add-on's old formula): no flux needed
  src.scattering = a.scattering == "isotropic" || st.term == RenderTerm::Lb ? Scattering::Isotropic : Scattering::PhaseP1;
  if (a.reference && (a.sheet || !a.grid.empty())) throw_invalid("--reference draws the lit volume: leave out --sheet and --grid");
  src.grid = a.grid;
  if (!a.grid.empty() && a.sheet) throw_invalid("--grid and --sheet draw different pictures: choose one");
  if (a.grid.empty() && (!a.range.empty() || a.log))
    throw_invalid("--range and --log set the colour scale of a --grid picture; add --grid NAME or leave them out");
  if (!a.range.empty() && !(std::isfinite(a.range[0]) && std::isfinite(a.range[1])))
    throw_invalid("--range " + message_number(a.range[0]) + "," + message_number(a.range[1]) +
                  ": expected two finite numbers LOW,HIGH");
  // Both outputs checked before the render: a refusal after it would leave the first file behind.
  const fs::path exr = a.sheet && a.output == "render.exr" ? fs::path("sheet.svg") : fs::path(a.output);
  const fs::path png = a.png.empty() ? fs::path(exr).replace_extension(".png") : fs::path(a.png);
  RunPaths paths;
  paths.input(a.input, "the input").output_file(exr, "-o");
  if (!a.sheet) paths.output_file(png, a.png.empty() ? "the preview (-o's name with .png)" : "--png");
  paths.check();
  RunContext ctx;
  ctx.cancel = &g_interrupted;
  if (a.sheet) return run_sheet(a, src, width, height, exr, ctx);
  const RenderVolume volume = load_render_volume(src, sun, ctx);
  Camera cam;
  if (!a.camera.empty()) {
    cam.position = vec3(a.camera, "--camera");
    cam.look_at = a.look_at.empty() ? Vec3d{0, 0, 0} : vec3(a.look_at, "--look-at");
    cam.fov_degrees = a.fov;
    cam.width = width;
    cam.height = height;
  } else {
    const std::optional<Camera> c = orbit_camera(volume, a.orbit, width, height);
    if (!c) throw_invalid("--orbit '" + a.orbit + "'; allowed: " + kOrbitPresets);
    cam = *c;
  }
  if (a.reference) return run_reference(a, global, volume, cam, exr, png, ctx);
  int last = -1;
  st.progress = [&](double f) {
    const int pct = static_cast<int>(f * 100);
    if (pct / 10 != last / 10) {
      spdlog::info("render: {}% of {} rows", pct, height);
      last = pct;
    }
  };
  FieldSettings field;
  if (!a.grid.empty()) {
    field.log = a.log;
    field.opacity = a.opacity;
    field.step = a.step;
    field.threads = st.threads;
    field.progress = st.progress;
    if (a.range.empty()) {
      choose_field_scale(volume, field);
    } else {
      field.lo = a.range[0];
      field.hi = a.range[1];
      if (!(field.hi > field.lo) || (a.log && !(field.lo > 0)))
        throw_invalid("--range " + message_number(field.lo) + "," + message_number(field.hi) +
                      ": expected LOW,HIGH with LOW < HIGH (and LOW > 0 with --log)");
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  const Image img = a.grid.empty() ? render_volume(volume, cam, st, ctx) : render_field(volume, volume.field, cam, field, ctx);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::map<std::string, std::string> attrs = {
      {"lblight_version", kVersion},
      {"lblight_command", global.command_line},
      {"lblight_source", a.input},
      {"lblight_camera_position", format3(cam.position)},
      {"lblight_camera_look_at", format3(cam.look_at)},
      {"lblight_camera_fov_degrees", std::to_string(cam.fov_degrees)},
      {"lblight_sun", "elevation " + std::to_string(a.elevation) + " azimuth " + std::to_string(a.azimuth) +
                          " intensity " + std::to_string(a.intensity) + " ambient " + std::to_string(a.ambient) +
                          " sky " + std::to_string(a.sky)},
      {"lblight_term", a.grid.empty() ? a.term : "grid " + a.grid},
      {"lblight_units", a.grid.empty() ? "radiance; 1 = a unit sun's irradiance per steradian"
                                       : "false colour (viridis) of grid '" + a.grid + "' from " + message_number(field.lo) +
                                             " to " + message_number(field.hi) + (a.log ? " (log)" : "")}};
  write_file_atomically(exr, [&](const fs::path& tmp) { write_exr(tmp, width, height, img.rgba, !a.full_float, attrs); });
  if (a.grid.empty()) {
    write_file_atomically(png, [&](const fs::path& tmp) { write_png(tmp, width, height, tone_map(img, a.exposure)); });
  } else {
    const Rgb8Image legend = with_scale_bar({width, height, tone_map(img, 1.0)}, field, a.grid);
    write_file_atomically(png, [&](const fs::path& tmp) { write_png(tmp, legend.width, legend.height, legend.rgb); });
    std::cout << "grid '" << a.grid << "' from " << field.lo << " to " << field.hi << (a.log ? " (log)" : "") << "\n";
  }
  if (!a.against.empty()) print_metrics(img, a.against, cam, sun.toward_sun);
  std::cout << "rendered " << width << "x" << height << " (" << (a.grid.empty() ? a.term : "grid " + a.grid) << ") in " << seconds << " s on "
            << (st.threads > 0 ? std::to_string(st.threads) + " thread(s)" : std::string("all cores")) << ": " << exr.string() << ", preview " << png.string() << "\n";
  return 0;
}

}  // namespace

Command add_render_command(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = app.add_subcommand(
      "render",
      "A picture of a bake for a sun: ray marching through the density with single scattering of the sun "
      "(Henyey-Greenstein, shadowed through the same density, [Chen2006] eqs. (1)-(6)) plus the LB solution's "
      "multiple scattering (the relit light less the unscattered sun), into OpenEXR (RGBA, camera and sun in "
      "the header) and a tone-mapped PNG preview. Input: a bake folder (--model), a bake's model .vdb, or a relit "
      ".vdb (lblight relight, one model or a forest) with --material. docs/rendering.md.");
  cmd->add_option("input", args->input, "Bake folder, model .vdb or relit .vdb")->required();
  cmd->add_option("--model", args->model, "Model of a bake folder (needed when it holds several)")->check(kNonEmpty);
  cmd->add_option("--sun-elevation", args->elevation, "Degrees above the horizon")->check(finite_range(-90.0, 90.0))->capture_default_str();
  cmd->add_option("--sun-azimuth", args->azimuth, "Degrees from +x toward +y")->check(finite_range(-360.0, 360.0))->capture_default_str();
  cmd->add_option("--intensity", args->intensity, "Sun intensity (irradiance)")->check(finite_range(0.0, 1e6))->capture_default_str();
  cmd->add_option("--ambient", args->ambient, "Ambient level (x B00) in the LB light")->check(finite_range(0.0, 1e6))->capture_default_str();
  cmd->add_option("--sky", args->sky, "Sky level (upper hemisphere) in the LB light")->check(finite_range(0.0, 1e6))->capture_default_str();
  cmd->add_option("--orbit", args->orbit, std::string("Camera preset framing the volume: ") + kOrbitPresets)->capture_default_str();
  cmd->add_option("--camera", args->camera, "Camera position x,y,z (world), instead of --orbit")->delimiter(',')->expected(3);
  cmd->add_option("--look-at", args->look_at, "Point the camera looks at x,y,z (with --camera)")->delimiter(',')->expected(3);
  cmd->add_option("--fov", args->fov, "Vertical field of view in degrees (with --camera)")->check(finite_range(1.0, 170.0))->capture_default_str();
  cmd->add_option("--size", args->size, "Image size WIDTHxHEIGHT")->capture_default_str();
  cmd->add_option("--term", args->term,
                  "direct (single-scattered sun), indirect (LB multiple scattering), all (both), or lb (the whole LB "
                  "light scattered isotropically: what the Blender add-on renders)")
      ->check(CLI::IsMember({"direct", "indirect", "all", "lb"}))
      ->capture_default_str();
  cmd->add_option("--scattering", args->scattering,
                  "How the LB light's scattered part is in-scattered toward the eye: phase (with the material's "
                  "phase function, from the bake's flux grids, docs/rendering.md sec. 1) or isotropic (bakes "
                  "without moments)")
      ->check(CLI::IsMember({"phase", "isotropic"}))
      ->capture_default_str();
  cmd->add_option("--grid", args->grid,
                  "Show this grid of the file (density, B06, light, ...; a vector grid's channel mean) in false "
                  "colour instead of lighting it, with a scale bar under the PNG")
      ->check(kNonEmpty);
  cmd->add_option("--range", args->range, "Colour scale LOW,HIGH of --grid (default: 0 to the 99.5th percentile)")
      ->delimiter(',')
      ->expected(2);
  cmd->add_flag("--log", args->log, "Logarithmic colour scale for --grid");
  cmd->add_option("--opacity", args->opacity, "Extinction per voxel at density 1 in --grid pictures")
      ->check(finite_range(1e-3, 100.0))
      ->capture_default_str();
  cmd->add_option("--material", args->material, "Material preset of a relit .vdb's medium (leaf, cloud, ...)")->check(kNonEmpty);
  cmd->add_option("--wood-material", args->wood_material, "Material preset of its wood (default: the medium's wood)")->check(kNonEmpty);
  cmd->add_option("--step", args->step, "March step in voxels")->check(finite_range(0.05, 2.0))->capture_default_str();
  cmd->add_flag("--float", args->full_float, "Write 32-bit float EXR channels (default half)");
  cmd->add_flag("--sheet", args->sheet,
                "Contact sheet instead: every base solution of the bake as a labelled tile of --size, in one SVG "
                "(-o, default sheet.svg)");
  cmd->add_option("--exposure", args->exposure, "PNG preview exposure (default: automatic)")->check(finite_range(0.0, 1e9));
  cmd->add_option("-o,--output", args->output, "Output .exr")->capture_default_str()->check(kNonEmpty);
  cmd->add_option("--png", args->png, "Preview .png (default: the .exr's name with .png)")->check(kNonEmpty);
  cmd->add_option("--threads", args->threads, "CPU threads (0 = all cores); the image does not depend on it")->check(CLI::Range(0, 4096));
  cmd->add_option("--against", args->against,
                  "Also print how the picture compares with this reference EXR (render --reference, same camera): "
                  "mean ratio, 4x4-block L1 and the reference's noise in it, sun/shade and top/bottom ratios");
  cmd->add_flag("--reference", args->reference,
                "Path trace the same volume instead (every order of scattering by Monte Carlo, the picture the "
                "others are judged against); the EXR holds each pixel's standard error as se.R, se.G, se.B");
  cmd->add_option("--target-error", args->target_error,
                  "--reference: stop at this relative standard error of the image")
      ->check(finite_range(1e-4, 1.0))
      ->capture_default_str();
  cmd->add_option("--time-budget", args->time_budget, "--reference: or after this many seconds (0: no limit)")
      ->check(finite_range(0.0, 1e7));
  cmd->add_option("--samples", args->samples, "--reference: or after this many paths per pixel and channel")
      ->check(CLI::Range(2, 1 << 24))
      ->capture_default_str();
  cmd->add_option("--max-scatterings", args->max_scatterings,
                  "--reference: only light scattered at most this many times (1: single scattering, what --term "
                  "direct draws; 0: every order)")
      ->check(CLI::Range(0, 1000000))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "--reference: random seed (the image is the same for any thread count)")
      ->check(integer_range(0, std::uint64_t{1} << 62))
      ->capture_default_str();
  return {cmd, [args, &global] { return run_render(*args, global); }};
}

}  // namespace lblight::cli
