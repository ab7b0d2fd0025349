// The command-line contract: help, exit codes, no partial output, readable errors.
#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include <cmath>
#include <limits>

#include "lblight/io/vdb_io.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;
namespace fs = std::filesystem;

namespace {
const char* kTinyScene = R"({
  "version": 1, "name": "tiny",
  "models": [{"name": "cloud", "density": {"type": "procedural", "shape": "cloud", "resolution": 10},
              "material": "cloud", "crop": false}],
  "lighting": {"mode": "base", "solutions": "0,1,5"},
  "solver": {"iterations": "paper"}
})";

std::string model_with(const std::string& density, const std::string& material) {
  return R"({"version": 1, "solver": {"model": "paper"}, "models": [{"name": "m", "density": )" + density + R"(, "material": )" + material + "}]}";
}
const std::string kProc = R"({"type": "procedural", "resolution": 8})";

// Runs bake on `scene_text` and checks it is rejected as invalid input without output.
void expect_rejected(const std::string& scene_text, const std::string& must_mention) {
  TempDir tmp;
  write_text(tmp / "bad.json", scene_text);
  const CliResult r = run_cli("bake bad.json -o out", tmp.path());
  INFO(scene_text << "\nstderr: " << r.err);
  CHECK(r.exit_code == 2);
  CHECK(r.err.find(must_mention) != std::string::npos);
  CHECK(r.err.find("bad.json") != std::string::npos);
  CHECK_FALSE(fs::exists(tmp / "out"));
  int leftovers = 0;
  for (const auto& e : fs::directory_iterator(tmp.path())) leftovers += e.path().filename() != "bad.json";
  CHECK(leftovers == 0);
}
}  // namespace

TEST_CASE("--help and --version", "[cli]") {
  const CliResult h = run_cli("--help");
  CHECK(h.exit_code == 0);
  for (const char* sub : {"bake", "validate", "inspect", "bench"}) CHECK(h.out.find(sub) != std::string::npos);
  const CliResult b = run_cli("bake --help");
  CHECK(b.exit_code == 0);
  for (const char* opt : {"--iterations", "--tolerance", "--solutions", "--backend", "--threads", "-o"})
    CHECK(b.out.find(opt) != std::string::npos);
  const CliResult v = run_cli("--version");
  CHECK(v.exit_code == 0);
  CHECK(v.out.find("lblight 0.") != std::string::npos);
  CHECK(run_cli("").exit_code == 2);
  CHECK(run_cli("bake").exit_code == 2);
  CHECK(run_cli("bake x.json --backend gpu").exit_code == 2);
}

TEST_CASE("bake writes a manifest, a vdb and a summary that inspect reads back", "[cli]") {
  TempDir tmp;
  write_text(tmp / "tiny.json", kTinyScene);
  const CliResult r = run_cli("bake tiny.json -o out --backend cpu", tmp.path());
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  CHECK(r.out.find("B05") != std::string::npos);
  CHECK(r.out.find("error estimate") != std::string::npos);
  CHECK(r.err.find("[3/3]") != std::string::npos);
  const nlohmann::json m = nlohmann::json::parse(read_text(tmp / "out" / "manifest.json"));
  CHECK(m["lblight_version"].get<std::string>().rfind("0.", 0) == 0);
  CHECK(m["models"][0]["lattice"]["dims"] == nlohmann::json({12, 10, 8}));
  const auto& sol = m["models"][0]["solutions"];
  REQUIRE(sol.size() == 3);
  CHECK(sol[2]["index"] == 5);
  CHECK(sol[2]["direction"] == nlohmann::json({0, 0, 1}));
  CHECK(sol[2]["iterations"] == 24);  // paper: 2 x longest edge (12)
  CHECK(sol[2]["grid"] == "B05");
  CHECK(sol[2].contains("error_estimate"));  // null: 24 steps are too few to estimate
  // peak memory counts the systems' state (two time levels of 19 float32 values per node, at
  // least one system), not only the lattice's density and material (9 bytes per node)
  CHECK(m["models"][0]["peak_memory_bytes"].get<std::size_t>() >= 2u * 19u * 4u * (12u * 10u * 8u));
  CHECK(fs::exists(tmp / "out" / "cloud.vdb"));

  const CliResult i = run_cli("inspect out", tmp.path());
  CHECK(i.exit_code == 0);
  CHECK(i.out.find("B01") != std::string::npos);
  // the manifest itself names the same output (it is not read as a scene)
  const CliResult im = run_cli("inspect out/manifest.json --json", tmp.path());
  INFO(im.err);
  CHECK(im.exit_code == 0);
  CHECK(nlohmann::json::parse(im.out)["kind"] == "output");
  const CliResult iv = run_cli("inspect out/cloud.vdb --json", tmp.path());
  CHECK(iv.exit_code == 0);
  CHECK(nlohmann::json::parse(iv.out)["grids"].size() == 4 + 3 * 3);  // density, B00..B02 and their flux grids
  const CliResult is = run_cli("inspect tiny.json", tmp.path());
  CHECK(is.exit_code == 0);
  CHECK(is.out.find("cloud") != std::string::npos);

  // a second bake replaces the previous output; an unrelated folder is never replaced
  CHECK(run_cli("bake tiny.json -o out --solutions 1 --iterations auto -q", tmp.path()).exit_code == 0);
  const auto again = nlohmann::json::parse(read_text(tmp / "out" / "manifest.json"))["models"][0]["solutions"];
  REQUIRE(again.size() == 1);
  CHECK(again[0]["converged"] == true);
  CHECK(again[0]["error_estimate"].get<double>() < 1e-4);
  fs::create_directories(tmp / "precious");
  write_text(tmp / "precious" / "notes.txt", "keep me");
  const CliResult p = run_cli("bake tiny.json -o precious", tmp.path());
  CHECK(p.exit_code == 2);
  CHECK(read_text(tmp / "precious" / "notes.txt") == "keep me");
}

TEST_CASE("bake and report replace only their own earlier output, never a folder holding anything else",
          "[cli]") {
  TempDir tmp;
  write_text(tmp / "tiny.json", kTinyScene);
  const std::string report = " --solutions 5 --runs plain:float32 -q";
  REQUIRE(run_cli("bake tiny.json -o b -q", tmp.path()).exit_code == 0);
  REQUIRE(run_cli("report tiny.json -o r" + report, tmp.path()).exit_code == 0);
  CHECK(fs::exists(tmp / "r" / "report.json"));
  CHECK(run_cli("report tiny.json -o r" + report, tmp.path()).exit_code == 0);  // its own output
  CHECK(run_cli("bake tiny.json -o b -q", tmp.path()).exit_code == 0);

  // each command refuses the other's output
  CHECK(run_cli("report tiny.json -o b" + report, tmp.path()).exit_code == 2);
  CHECK(fs::exists(tmp / "b" / "manifest.json"));
  CHECK(run_cli("bake tiny.json -o r -q", tmp.path()).exit_code == 2);
  CHECK(fs::exists(tmp / "r" / "report.json"));

  // a file lblight did not write beside a real manifest: replacing would delete it
  write_text(tmp / "b" / "notes.txt", "keep me");
  const CliResult extra = run_cli("bake tiny.json -o b -q", tmp.path());
  CHECK(extra.exit_code == 2);
  CHECK(extra.err.find("notes.txt") != std::string::npos);
  CHECK(read_text(tmp / "b" / "notes.txt") == "keep me");

  // a manifest.json from anything else (a browser extension's, say) does not make a folder ours
  fs::create_directories(tmp / "ext" / "src");
  write_text(tmp / "ext" / "manifest.json", R"({"name": "my-extension", "manifest_version": 3})");
  write_text(tmp / "ext" / "src" / "main.js", "code");
  CHECK(run_cli("bake tiny.json -o ext -q", tmp.path()).exit_code == 2);
  CHECK(read_text(tmp / "ext" / "src" / "main.js") == "code");
}

TEST_CASE("A signal stops a bake with exit 130 and leaves nothing behind", "[cli][slow]") {
  TempDir tmp;
  write_text(tmp / "slow.json", R"({"version": 1, "models": [{"name": "c", "material": "cloud",
      "density": {"type": "procedural", "resolution": 40}}], "solver": {"iterations": 1000000}})");
  // INT and TERM from a user or scheduler, HUP from a closed terminal, PIPE from a reader that
  // went away: each must remove the staging folder (the default action would kill it in place)
  for (const char* sig : {"INT", "TERM", "HUP", "PIPE"}) {
    INFO("SIG" << sig);
    const CliResult r = run_cli(std::string("bake slow.json -o out -q >/dev/null 2>&1 & p=$!; sleep 1; kill -") + sig +
                                    " $p; wait $p",
                                tmp.path());
    CHECK(r.exit_code == 130);
    std::vector<std::string> left;
    for (const auto& e : fs::directory_iterator(tmp.path())) left.push_back(e.path().filename().string());
    CHECK(left == std::vector<std::string>{"slow.json"});
  }
}

TEST_CASE("validate prints the plan without writing anything", "[cli]") {
  TempDir tmp;
  write_text(tmp / "tiny.json", kTinyScene);
  const CliResult r = run_cli("validate tiny.json --no-timing", tmp.path());
  INFO(r.err);
  CHECK(r.exit_code == 0);
  CHECK(r.out.find("lattice 12x10x8") != std::string::npos);
  CHECK(r.out.find("scene is valid") != std::string::npos);
  const CliResult j = run_cli("validate tiny.json --json", tmp.path());
  REQUIRE(j.exit_code == 0);
  const auto plan = nlohmann::json::parse(j.out);
  CHECK(plan["models"][0]["solutions"].size() == 3);
  CHECK(plan["estimated_seconds"].get<double>() > 0);
  int entries = 0;
  for (const auto& e : fs::directory_iterator(tmp.path())) entries += e.exists();
  CHECK(entries == 1);
}

TEST_CASE("Every validation rule of docs/model.md sec. 6 exits 2 and writes nothing", "[cli][validate]") {
  expect_rejected(model_with(kProc, R"({"sigma_a": -0.01, "sigma_s": 0.5, "g": 0})"), "sigma_a");
  expect_rejected(model_with(kProc, R"({"sigma_a": 0.01, "sigma_s": [0.5, 0.5, -0.5], "g": 0})"), "channel blue");
  expect_rejected(model_with(kProc, R"({"sigma_a": 0.01, "sigma_s": 0.5, "g": -1.01})"), "-1 <= g <= 1");
  expect_rejected(model_with(kProc, R"({"sigma_a": 1e999, "sigma_s": 0.5, "g": 0})"), "1e999");
  expect_rejected(model_with(R"({"type": "procedural", "resolution": 8, "density_scale": 2.5})", R"("cloud")"),
                  "after density_scale");
  expect_rejected(model_with(kProc, R"({"sigma_a": 0.2, "sigma_s": 1.9, "g": 0.5})"), "rho * sigma_t < 2");
  // backscattering just past the limit rho (sigma_a + 2 sigma_s) < 2 of g = -1: spectral radius
  // 1.004 at density 1 (rho * sigma_t = 1.002 passes the rule above)
  const std::string box = R"({"type": "procedural", "shape": "box", "resolution": 6})";
  expect_rejected(model_with(box, R"({"sigma_a": 0, "sigma_s": 1.002, "g": -1})"), "amplifies a pattern");
  TempDir tmp;
  write_text(tmp / "edge.json", model_with(box, R"({"sigma_a": 0, "sigma_s": 0.999, "g": -1})"));  // radius 1
  CHECK(run_cli("validate edge.json", tmp.path()).exit_code == 0);
  expect_rejected(R"({"version": 1, "models": [{"name": "m", "density": {"type": "procedural"}, "material": "cloud",
      "extra": true}]})", "unknown field 'extra'");
  expect_rejected("{ not json", "not valid JSON");
}

TEST_CASE("NaN and Inf in a density grid are rejected with their voxel", "[cli][validate]") {
  TempDir tmp;
  std::vector<float> density(4 * 4 * 4, 0.5f);
  // Inf rather than NaN: OpenVDB's dense-to-sparse copy treats NaN as background and drops it,
  // so our own writer cannot produce a NaN voxel. Both go through the same isfinite check.
  density[21] = std::numeric_limits<float>::infinity();
  write_density_vdb(tmp / "nan.vdb", cube_frame(4, 0.1), density);
  write_text(tmp / "bad.json", model_with(R"({"type": "vdb", "path": "nan.vdb"})", R"("cloud")"));
  const CliResult r = run_cli("bake bad.json -o out", tmp.path());
  CHECK(r.exit_code == 2);
  CHECK(r.err.find("inf") != std::string::npos);
  CHECK(r.err.find("voxel (1, 1, 1)") != std::string::npos);
  CHECK_FALSE(fs::exists(tmp / "out"));

  write_text(tmp / "missing.json", model_with(R"({"type": "vdb", "path": "nope.vdb"})", R"("cloud")"));
  const CliResult m = run_cli("bake missing.json -o out2", tmp.path());
  CHECK(m.exit_code == 2);
  CHECK(m.err.find("nope.vdb") != std::string::npos);
}

TEST_CASE("bench runs the collision's two forms side by side", "[cli]") {
  TempDir tmp;
  const CliResult r = run_cli(
      "bench --backend cpu --size 12 --steps 4 --time-block 1 --no-in-place --bandwidth-mib 4 --collision cubic pairs "
      "--json",
      tmp.path());
  REQUIRE(r.exit_code == 0);
  const nlohmann::json j = nlohmann::json::parse(r.out);
  REQUIRE(j["runs"].size() == 2);
  CHECK(j["runs"][0]["collision"] == "cubic");
  CHECK(j["runs"][1]["collision"] == "pairs");
  for (const auto& run : j["runs"]) CHECK(run["updates_per_second_per_channel"].get<double>() > 0);
  CHECK(run_cli("bench --backend cpu --size 8 --collision dense", tmp.path()).exit_code == 2);
}

TEST_CASE("Missing files and bad options are invalid input", "[cli]") {
  TempDir tmp;
  const CliResult r = run_cli("bake does-not-exist.json -o out", tmp.path());
  CHECK(r.exit_code == 2);
  CHECK(r.err.find("does-not-exist.json") != std::string::npos);
  write_text(tmp / "tiny.json", kTinyScene);
  for (const char* args : {
           "bake tiny.json --iterations forever", "bake tiny.json --solutions 0,25",
           "bake tiny.json --precision float8 --backend cpu", "validate tiny.json --tolerance 0",
           // NaN passes every range comparison: number options check finiteness themselves
           "bench --backend cpu --size 8 --bandwidth-mib nan",
           // an empty value (an unset shell variable) is an error, not the default
           "validate tiny.json --solutions ''", "bake tiny.json -o ''",
           // a precision nobody stores is an error, not an empty table with exit 0
           "bench --backend cpu --size 8 --precision float8",
           "report tiny.json --backend cpu --runs plain:float8 -o rep"}) {
    INFO(args);
    CHECK(run_cli(args, tmp.path()).exit_code == 2);
  }
  CHECK_FALSE(fs::exists(tmp / "tiny-bake"));
  CHECK_FALSE(fs::exists(tmp / "rep"));
  const CliResult nan = run_cli("validate tiny.json --iterations auto --tolerance nan", tmp.path());
  CHECK(nan.exit_code == 2);
  CHECK(nan.err.find("not a finite number") != std::string::npos);
  // what bake would refuse, validate refuses too (tiny.json runs "paper" steps)
  const CliResult krylov = run_cli("validate tiny.json --method bicgstab", tmp.path());
  CHECK(krylov.exit_code == 2);
  CHECK(krylov.err.find("/solver/method") != std::string::npos);
}

TEST_CASE("compare: identical bakes pass, a different precision fails at tolerance 0, mismatches are invalid",
          "[cli]") {
  TempDir tmp;
  write_text(tmp / "tiny.json", kTinyScene);
  REQUIRE(run_cli("bake tiny.json -o a --backend cpu -q", tmp.path()).exit_code == 0);
  REQUIRE(run_cli("bake tiny.json -o b --backend cpu -q", tmp.path()).exit_code == 0);
  REQUIRE(run_cli("bake tiny.json -o f64 --backend cpu --precision float64 -q", tmp.path()).exit_code == 0);

  const CliResult same = run_cli("compare a b --tolerance 0", tmp.path());
  INFO(same.out << same.err);
  CHECK(same.exit_code == 0);
  CHECK(same.out.find("cloud B05: max relative difference 0\n") != std::string::npos);
  CHECK(same.out.find("largest over 3 grid(s): 0 (within 0)") != std::string::npos);

  // one copy of the state updated in place: the same bits, and validate says which layout runs
  REQUIRE(run_cli("bake tiny.json -o aa --backend cpu --state in-place -q", tmp.path()).exit_code == 0);
  const CliResult in_place = run_cli("compare a aa --tolerance 0", tmp.path());
  INFO(in_place.out << in_place.err);
  CHECK(in_place.exit_code == 0);
  CHECK(in_place.out.find("largest over 3 grid(s): 0 (within 0)") != std::string::npos);
  const CliResult plan = run_cli("validate tiny.json --backend cpu --state in-place", tmp.path());
  CHECK(plan.out.find("state in-place") != std::string::npos);
  CHECK(run_cli("validate tiny.json --backend cpu", tmp.path()).out.find("state two-levels") != std::string::npos);
  CHECK(run_cli("validate tiny.json --state halfway", tmp.path()).exit_code == 2);

  // float64 storage rounds differently: a small, nonzero difference
  const CliResult strict = run_cli("compare a f64 --tolerance 0", tmp.path());
  INFO(strict.out);
  CHECK(strict.exit_code == 1);
  CHECK(strict.out.find("ABOVE") != std::string::npos);
  CHECK(run_cli("compare a f64 --tolerance 1e-4", tmp.path()).exit_code == 0);

  CHECK(run_cli("compare a missing", tmp.path()).exit_code == 2);
  // kTinyScene with `from` replaced by `to`, baked on the CPU into directory `name`
  const auto bake_variant = [&](const std::string& name, const std::string& from, const std::string& to) {
    std::string text = kTinyScene;
    const std::size_t at = text.find(from);
    REQUIRE(at != std::string::npos);
    write_text(tmp / (name + ".json"), text.replace(at, from.size(), to));
    REQUIRE(run_cli("bake " + name + ".json -o " + name + " --backend cpu -q", tmp.path()).exit_code == 0);
  };
  // another lattice (other resolution) does not match up
  bake_variant("other", R"("resolution": 10)", R"("resolution": 12)");
  const CliResult lattice = run_cli("compare a other", tmp.path());
  CHECK(lattice.exit_code == 2);
  CHECK(lattice.err.find("another lattice") != std::string::npos);

  // a bake that differs in the blue channel alone is told apart (every channel is compared)
  const std::string cloud = R"("material": "cloud")";
  bake_variant("grey", cloud, R"("material": {"sigma_a": 0.01, "sigma_s": 0.79, "g": 0.5})");
  bake_variant("blue", cloud, R"("material": {"sigma_a": 0.01, "sigma_s": [0.79, 0.79, 0.6], "g": 0.5})");
  const CliResult channels = run_cli("compare grey blue --tolerance 1e-3", tmp.path());
  INFO(channels.out << channels.err);
  CHECK(channels.exit_code == 1);
  CHECK(channels.out.find("ABOVE") != std::string::npos);
}
