// The bake's output path: grids streamed into the .vdb one solution at a time, on a background
// worker when the solver leaves the host's cores free (GPU backends).
#include <catch2/catch.hpp>

#include <atomic>
#include <chrono>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <thread>

#include "lblight/core/serial_worker.h"
#include "lblight/io/vdb_io.h"
#include "lblight/io/vdb_stream_writer.h"
#include "tests/test_support.h"

using namespace lblight;
using namespace lblight::test;
namespace fs = std::filesystem;

namespace {
std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}
// Manifest without the wall times, which differ from run to run.
nlohmann::json without_times(nlohmann::json j) {
  if (j.is_object()) {
    for (const char* key : {"seconds", "encode_seconds", "total_seconds", "created", "residual_history"}) j.erase(key);
    for (auto& [k, v] : j.items()) v = without_times(v);
  } else if (j.is_array()) {
    for (auto& v : j) v = without_times(v);
  }
  return j;
}
}  // namespace

TEST_CASE("SerialWorker runs tasks in order and reports the first failure", "[io]") {
  for (bool background : {false, true}) {
    INFO("background " << background);
    SerialWorker w(background);
    std::vector<int> seen;
    for (int i = 0; i < 50; ++i) w.post([&seen, i] { seen.push_back(i); });
    w.wait();
    REQUIRE(seen.size() == 50);
    for (int i = 0; i < 50; ++i) CHECK(seen[static_cast<std::size_t>(i)] == i);

    std::atomic<int> after{0};
    if (background) {
      w.post([] { throw std::runtime_error("disk full"); });
      w.post([&after] { ++after; });  // builds on the failed task: must not run
      CHECK_THROWS_WITH(w.wait(), "disk full");
      CHECK(after == 0);
      CHECK_THROWS_WITH(w.post([&after] { ++after; }), "disk full");  // the bake stops here
      CHECK_THROWS_WITH(w.wait(), "disk full");
      CHECK(after == 0);
    } else {
      CHECK_THROWS_WITH(w.post([] { throw std::runtime_error("disk full"); }), "disk full");
    }
  }
}

TEST_CASE("SerialWorker abandoned with work queued stops after the running task", "[io]") {
  std::atomic<int> ran{0};
  {
    SerialWorker w(true);
    w.post([&ran] {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      ++ran;
    });
    for (int i = 0; i < 20; ++i) w.post([&ran] { ++ran; });
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // the first task is running
  }
  CHECK(ran == 1);
}

TEST_CASE("VdbStreamWriter writes exactly the announced grids", "[io]") {
  TempDir tmp;
  const DenseFrame frame{{3, 2, 2}, {0, 0, 0}, {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}};
  std::vector<float> a(12, 1.0f);
  {
    VdbStreamWriter w(tmp / "short.vdb", frame, 2, nlohmann::json::object());
    w.add({"a", &a, nullptr, false, {}});
    CHECK_THROWS_AS(w.add({"a", &a, nullptr, false, {}}), Error);  // a name twice
    CHECK_THROWS_AS(w.close(), Error);                             // one of two
  }
  VdbStreamWriter w(tmp / "ok.vdb", frame, 1, {{"creator", "test"}});
  w.add({"a", &a, nullptr, true, {}});
  CHECK_THROWS_AS(w.add({"b", &a, nullptr, false, {}}), Error);  // more than announced
  w.close();
  CHECK(w.bytes_written() == fs::file_size(tmp / "ok.vdb"));
  const DenseGridIn g = read_vdb_grid_dense(tmp / "ok.vdb", "a");
  CHECK(g.values[0] == a);
  CHECK(inspect_vdb(tmp / "ok.vdb")["file_metadata"]["creator"] == "test");
}

TEST_CASE("Output written on a background worker equals output written inline", "[io][lbh]") {
  // All 18 directions and B00 summed from them (arrives last), .lbh at 1%: every grid, the .lbh
  // bytes and the manifest must not depend on which thread wrote them.
  TempDir tmp;
  const Scene scene = parse_scene(R"({"version": 1, "name": "t",
      "models": [{"name": "shrub", "density": {"type": "procedural", "shape": "plant", "resolution": 10, "size": 2.0},
                  "material": "leaf", "wood_material": "bark"}],
      "lighting": {"mode": "base", "solutions": "all", "ambient_from_sum": true},
      "solver": {"iterations": 10},
      "output": {"lbh": {"threshold": 0.01, "relative": true}}})",
                                  tmp / "scene.json");
  const BakedModel inline_bake = bake_first_model(scene, tmp / "inline", false);
  const BakedModel background_bake = bake_first_model(scene, tmp / "background", true);

  CHECK(read_bytes(tmp / "inline" / "shrub.lbh") == read_bytes(tmp / "background" / "shrub.lbh"));
  // Same grids in the same order: the files differ only in the 36-character UUID that OpenVDB
  // writes at byte 21 of every file.
  std::string a = read_bytes(tmp / "inline" / "shrub.vdb"), b = read_bytes(tmp / "background" / "shrub.vdb");
  REQUIRE(a.size() == b.size());
  REQUIRE(a.size() > 57);
  CHECK(a.substr(0, 21) == b.substr(0, 21));
  CHECK(a.substr(57) == b.substr(57));

  REQUIRE(inspect_vdb(tmp / "background" / "shrub.vdb")["grids"].size() == 2 + 19);
  // File order (OpenVDB's own listing is by name): each grid descriptor starts with its name as a
  // 4-byte length and the characters, then its tree type.
  const auto at = [&b](const std::string& name, const std::string& tree) {
    const std::string key = std::string(1, static_cast<char>(name.size())) + std::string(3, '\0') + name +
                            std::string(1, static_cast<char>(tree.size())) + std::string(3, '\0') + tree;
    return b.find(key);
  };
  const std::size_t density = at("density", "Tree_float_5_4_3"), brown = at("brown", "Tree_float_5_4_3");
  const std::size_t b01 = at("B01", "Tree_vec3s_5_4_3"), b18 = at("B18", "Tree_vec3s_5_4_3"),
                    b00 = at("B00", "Tree_vec3s_5_4_3");
  REQUIRE(b00 != std::string::npos);
  CHECK(density < brown);
  CHECK(brown < b01);
  CHECK(b01 < b18);
  CHECK(b18 < b00);  // summed last, written last
  for (const SolutionResult& r : inline_bake.kept) {
    const DenseGridIn g = read_vdb_grid_dense(tmp / "background" / "shrub.vdb", r.plan.grid_name);
    for (int c = 0; c < 3; ++c) CHECK(g.values[c] == r.totals[c]);
  }
  const auto ma = nlohmann::json::parse(read_text(tmp / "inline" / "manifest.json"));
  const auto mb = nlohmann::json::parse(read_text(tmp / "background" / "manifest.json"));
  CHECK(without_times(ma["models"]) == without_times(mb["models"]));
  CHECK(ma["models"][0]["solutions"][0]["grid"] == "B00");  // the manifest stays in index order
}
