// lblight render from the command line: a bake renders to an OpenEXR with camera and sun in its
// header and a PNG preview, the sunlit side brighter than the shaded one; a relit .vdb needs its
// material named; a forest bake is sent through relight first.
#include <catch2/catch.hpp>

#include <filesystem>

#include "lblight/io/image_io.h"
#include "lblight/io/vdb_io.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {

const char* kScene = R"({"version": 1, "models": [{"name": "tree", "density": {"type": "procedural", "shape": "plant",
  "resolution": 16, "seed": 4}, "material": "leaf", "wood_material": "bark"}],
  "lighting": {"mode": "base", "sun_range": {"min_elevation": 0, "max_elevation": 90}}, "solver": {"tolerance": 1e-3}})";

// Mean red of the left and right halves of the lit pixels.
std::pair<double, double> halves(const std::vector<float>& rgba, int w, int h) {
  double l = 0, r = 0;
  int nl = 0, nr = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float* p = &rgba[(static_cast<std::size_t>(y) * w + x) * 4];
      if (p[3] < 0.05f) continue;
      (x < w / 2 ? l : r) += p[0];
      ++(x < w / 2 ? nl : nr);
    }
  return {l / std::max(nl, 1), r / std::max(nr, 1)};
}

}  // namespace

TEST_CASE("render: a bake to EXR + PNG, camera and sun in the header, the sunlit side brighter", "[cli][render]") {
  TempDir tmp;
  write_text(tmp / "scene.json", kScene);
  REQUIRE(run_cli("bake scene.json -o bake --backend cpu -q", tmp.path()).exit_code == 0);
  // Sun low from +x, camera in front (from -y): +x is the image's right half.
  const CliResult r = run_cli("render bake --sun-elevation 10 --sun-azimuth 0 --sky 0.02 --orbit front --size 64x48 -o tree.exr",
                              tmp.path());
  INFO(r.out << r.err);
  REQUIRE(r.exit_code == 0);
  CHECK(std::filesystem::exists(tmp.path() / "tree.png"));
  int w = 0, h = 0;
  std::map<std::string, std::string> attrs;
  const std::vector<float> rgba = read_exr(tmp / "tree.exr", w, h, &attrs);
  CHECK(w == 64);
  CHECK(h == 48);
  CHECK(attrs.count("lblight_camera_position") == 1);
  CHECK(attrs["lblight_sun"].find("elevation 10") != std::string::npos);
  const auto [left, right] = halves(rgba, w, h);
  INFO("left " << left << ", right " << right);
  CHECK(right > 1.3 * left);
  // Each term alone; together they are their sum (the renderer adds them per sample).
  REQUIRE(run_cli("render bake --sun-elevation 10 --orbit front --size 32x24 --term direct -o d.exr", tmp.path()).exit_code == 0);
  REQUIRE(run_cli("render bake --sun-elevation 10 --orbit front --size 32x24 --term indirect -o i.exr", tmp.path()).exit_code == 0);
  REQUIRE(run_cli("render bake --sun-elevation 10 --orbit front --size 32x24 --float -o a.exr", tmp.path()).exit_code == 0);
  const auto d = read_exr(tmp / "d.exr", w, h), i = read_exr(tmp / "i.exr", w, h), a = read_exr(tmp / "a.exr", w, h);
  for (std::size_t k = 0; k < a.size(); k += 4) CHECK(a[k] == Approx(d[k] + i[k]).margin(2e-3 * (a[k] + 1e-3)));
}

TEST_CASE("render: a relit .vdb brings its materials or needs them named, unknown presets and sizes are refused by name",
          "[cli][render]") {
  TempDir tmp;
  write_text(tmp / "scene.json", kScene);
  REQUIRE(run_cli("bake scene.json -o bake --backend cpu -q", tmp.path()).exit_code == 0);
  REQUIRE(run_cli("relight bake --sun-elevation 40 -o relit.vdb", tmp.path()).exit_code == 0);
  // The relit file's own description (its density's material metadata) is the bake's materials.
  REQUIRE(run_cli("render relit.vdb --sun-elevation 40 --size 16x16 -o own.exr", tmp.path()).exit_code == 0);
  REQUIRE(run_cli("render relit.vdb --material leaf --wood-material bark --sun-elevation 40 --size 16x16 -o named.exr",
                  tmp.path()).exit_code == 0);
  int w = 0, h = 0;
  CHECK(read_exr(tmp / "own.exr", w, h) == read_exr(tmp / "named.exr", w, h));
  // Stripped of that metadata, the materials must be named.
  const DenseGridIn light = read_vdb_grid_dense(tmp / "relit.vdb", "light");
  const DenseGridIn density = read_vdb_grid_dense(tmp / "relit.vdb", "density");
  write_vdb(tmp / "stripped.vdb", light.frame,
            {{"light", nullptr, &light.values, false, {}}, {"density", &density.values[0], nullptr, true, {}}}, {});
  const CliResult no = run_cli("render stripped.vdb --sun-elevation 40 --size 16x16 -o x.exr", tmp.path());
  CHECK(no.exit_code == 2);
  CHECK(no.err.find("--material") != std::string::npos);
  CHECK(!std::filesystem::exists(tmp.path() / "x.exr"));
  CHECK(run_cli("render relit.vdb --material leaf --sun-elevation 40 --size 16x16 -o ok.exr", tmp.path()).exit_code == 0);
  const CliResult other_sun = run_cli("render relit.vdb --material leaf --sun-elevation 20 --size 16x16 -o s.exr", tmp.path());
  CHECK(other_sun.exit_code == 2);
  CHECK(other_sun.err.find("relit for a sun at elevation 40") != std::string::npos);
  const CliResult bad = run_cli("render relit.vdb --material glass --sun-elevation 40 --size 16x16 -o y.exr", tmp.path());
  CHECK(bad.exit_code == 2);
  CHECK(bad.err.find("glass") != std::string::npos);
  CHECK(run_cli("render bake --size 16by16 -o z.exr", tmp.path()).exit_code == 2);
}

TEST_CASE("render --sheet: one labelled tile per base solution of the bake, in one SVG", "[cli][render]") {
  TempDir tmp;
  write_text(tmp / "scene.json", kScene);
  REQUIRE(run_cli("bake scene.json -o bake --backend cpu -q", tmp.path()).exit_code == 0);
  const CliResult r = run_cli("render bake --sheet --size 24x24 -o sheet.svg", tmp.path());
  INFO(r.out << r.err);
  REQUIRE(r.exit_code == 0);
  const std::string svg = read_text(tmp / "sheet.svg");
  std::size_t images = 0;
  for (std::size_t p = svg.find("<image "); p != std::string::npos; p = svg.find("<image ", p + 1)) ++images;
  // sun_range from elevation 0 with no rotation declared: B00 and the 13 level-or-downward directions
  CHECK(images == 14);
  CHECK(svg.find(">B06 (0,0,-1)<") != std::string::npos);
  CHECK(svg.find(">B05 ") == std::string::npos);  // left out by the bake
  CHECK(svg.find("data:image/png;base64,iVBORw0KGgo") != std::string::npos);  // PNG signature
}

TEST_CASE("render --grid: any grid in false colour with a scale bar under the PNG, an unknown grid is refused with the list",
          "[cli][render]") {
  TempDir tmp;
  write_text(tmp / "scene.json", kScene);
  REQUIRE(run_cli("bake scene.json -o bake --backend cpu -q", tmp.path()).exit_code == 0);
  const CliResult r = run_cli("render bake --grid B06 --size 64x48 -o b06.exr", tmp.path());
  INFO(r.out << r.err);
  REQUIRE(r.exit_code == 0);
  CHECK(r.out.find("grid 'B06' from 0 to ") != std::string::npos);
  int w = 0, h = 0;
  std::map<std::string, std::string> attrs;
  const std::vector<float> rgba = read_exr(tmp / "b06.exr", w, h, &attrs);
  CHECK(w == 64);
  CHECK(h == 48);
  CHECK(attrs["lblight_term"] == "grid B06");
  CHECK(attrs["lblight_units"].find("false colour (viridis) of grid 'B06' from 0 to ") == 0);
  const std::string png = read_text(tmp / "b06.png");
  REQUIRE(png.size() > 24);
  const auto be32 = [&](std::size_t at) {
    return (static_cast<unsigned char>(png[at]) << 24) | (static_cast<unsigned char>(png[at + 1]) << 16) |
           (static_cast<unsigned char>(png[at + 2]) << 8) | static_cast<unsigned char>(png[at + 3]);
  };
  CHECK(be32(16) == 64);
  CHECK(be32(20) > 48);  // the legend band under the picture
  const CliResult log = run_cli("render bake --grid density --log --range 0.01,1 --size 16x16 -o d.exr", tmp.path());
  INFO(log.out << log.err);
  CHECK(log.exit_code == 0);
  CHECK(log.out.find("from 0.01 to 1 (log)") != std::string::npos);
  const CliResult bad = run_cli("render bake --grid nope --size 16x16 -o x.exr", tmp.path());
  CHECK(bad.exit_code != 0);
  CHECK(bad.err.find("no grid 'nope' in this file; it has: ") != std::string::npos);
  CHECK(bad.err.find("density") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(tmp.path() / "x.exr"));
  const CliResult range = run_cli("render bake --grid density --log --range 0,1 --size 16x16 -o y.exr", tmp.path());
  CHECK(range.exit_code != 0);
  CHECK(range.err.find("--range") != std::string::npos);
}

TEST_CASE("render: outputs checked before the render (same EXR and PNG, missing folder), grid options need --grid",
          "[cli][render]") {
  TempDir tmp;
  write_text(tmp / "scene.json", kScene);
  REQUIRE(run_cli("bake scene.json -o bake --backend cpu -q", tmp.path()).exit_code == 0);
  const CliResult same = run_cli("render bake --size 16x16 -o pic.png", tmp.path());
  CHECK(same.exit_code == 2);
  CHECK(same.err.find("would be written to the same place") != std::string::npos);
  const CliResult nodir = run_cli("render bake --size 16x16 -o a.exr --png nodir/a.png", tmp.path());
  CHECK(nodir.exit_code == 2);
  CHECK(nodir.err.find("does not exist") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(tmp.path() / "a.exr"));  // nothing half-written
  const CliResult range = run_cli("render bake --size 16x16 --range 0,1 -o b.exr", tmp.path());
  CHECK(range.exit_code == 2);
  CHECK(range.err.find("--range and --log set the colour scale of a --grid picture") != std::string::npos);
}

TEST_CASE("render: a bake without flux grids is refused by name, never rendered isotropic unasked", "[cli][render][moments]") {
  TempDir tmp;
  std::string scene = kScene;
  scene.replace(scene.find("\"solver\""), 0, R"("output": {"moments": false}, )");
  write_text(tmp / "scene.json", scene);
  REQUIRE(run_cli("bake scene.json -o bake --backend cpu -q", tmp.path()).exit_code == 0);
  REQUIRE(run_cli("relight bake --sun-elevation 30 -o relit.vdb", tmp.path()).exit_code == 0);
  for (const std::string input : {"bake", "relit.vdb --material leaf"}) {
    const CliResult r = run_cli("render " + input + " --sun-elevation 30 --orbit front --size 16x16 -o p.exr", tmp.path());
    INFO(input << ": " << r.out << r.err);
    CHECK(r.exit_code == 2);
    CHECK(r.err.find("no flux grids") != std::string::npos);
    CHECK(r.err.find("--scattering isotropic") != std::string::npos);
    CHECK(r.err.find(input == "bake" ? "tree.vdb" : "relit.vdb") != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(tmp.path() / "p.exr"));
    const CliResult iso = run_cli("render " + input + " --sun-elevation 30 --orbit front --size 16x16 --scattering isotropic -o p.exr",
                                  tmp.path());
    INFO(iso.out << iso.err);
    CHECK(iso.exit_code == 0);
    std::filesystem::remove(tmp.path() / "p.exr");
    std::filesystem::remove(tmp.path() / "p.png");
  }
  // --term direct needs no light, --term lb no flux
  CHECK(run_cli("render bake --sun-elevation 30 --orbit front --size 16x16 --term direct -o d.exr", tmp.path()).exit_code == 0);
  CHECK(run_cli("render bake --sun-elevation 30 --orbit front --size 16x16 --term lb -o l.exr", tmp.path()).exit_code == 0);
}
