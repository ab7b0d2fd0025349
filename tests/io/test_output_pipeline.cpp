// The bake's output path: grids streamed into the .vdb one solution at a time, on a background
// worker when the solver leaves the host's cores free (GPU backends).
#include <catch2/catch.hpp>
#include <sys/stat.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <random>
#include <thread>

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include "lblight/core/error.h"
#include "lblight/core/serial_worker.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/vdb_io.h"
#include "lblight/io/vdb_stream_writer.h"
#include "lblight/pipeline/manifest.h"
#include "tests/support/expect_error.h"
#include "tests/support/test_support.h"

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
      std::atomic<bool> go{false};
      w.post([&go] {
        while (!go) std::this_thread::yield();  // fail only once the next task is queued
        throw std::runtime_error("disk full");
      });
      w.post([&after] { ++after; });  // builds on the failed task: must not run
      go = true;
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

TEST_CASE("SerialWorker holds back a producer that runs ahead of it", "[io]") {
  SerialWorker w(true);
  std::atomic<bool> go{false};
  std::vector<int> seen;
  w.post([&go, &seen] {
    while (!go) std::this_thread::yield();
    seen.push_back(0);
  });
  // the first task may not have started yet: kMaxQueued more posts may or may not fill the queue
  for (std::size_t i = 1; i < SerialWorker::kMaxQueued; ++i) w.post([&seen, i] { seen.push_back(static_cast<int>(i)); });
  std::atomic<int> returned{0};
  std::thread producer([&] {
    for (std::size_t i = SerialWorker::kMaxQueued; i < SerialWorker::kMaxQueued + 2; ++i) {
      w.post([&seen, i] { seen.push_back(static_cast<int>(i)); });
      ++returned;
    }
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  CHECK(returned <= 1);  // at most one more fits while the first task holds the worker
  go = true;
  producer.join();
  w.wait();
  CHECK(returned == 2);
  REQUIRE(seen.size() == SerialWorker::kMaxQueued + 2);
  for (std::size_t i = 0; i < seen.size(); ++i) CHECK(seen[i] == static_cast<int>(i));
}

TEST_CASE("SerialWorker abandoned with work queued stops after the running task", "[io]") {
  std::atomic<int> ran{0};
  {
    SerialWorker w(true);
    w.post([&ran] {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      ++ran;
    });
    for (std::size_t i = 1; i < SerialWorker::kMaxQueued; ++i) w.post([&ran] { ++ran; });  // fits the queue
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

TEST_CASE("VdbStreamWriter compressing grids in parallel writes io::File::write's bytes, in order", "[io]") {
  // Grids of very different fill, so they finish compressing out of order.
  TempDir tmp;
  const DenseFrame frame{{24, 20, 18}, {-3, 5, 0}, {0.5, 0, 0, 1, 0, 0.5, 0, 2, 0, 0, 0.5, 3, 0, 0, 0, 1}};
  const std::size_t n = frame.dims.count();
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> value(0.0f, 1.0f);
  std::vector<DenseGridOut> grids;
  // the lattice box, as the bake records it, so grids read back over the whole frame
  const nlohmann::json box = {{"lblight_lattice_min", frame.index_min},
                              {"lblight_lattice_dims", {frame.dims.nx, frame.dims.ny, frame.dims.nz}}};
  std::vector<std::vector<float>> scalars(3);
  std::vector<std::array<std::vector<float>, 3>> rgbs(9);
  for (std::size_t k = 0; k < scalars.size(); ++k) {
    scalars[k].assign(n, 0.0f);
    for (std::size_t i = 0; i < n; i += k + 1) scalars[k][i] = value(rng);
    grids.push_back({"s" + std::to_string(k), &scalars[k], nullptr, k == 0, box});
  }
  for (std::size_t k = 0; k < rgbs.size(); ++k) {
    const float fill = k % 3 == 0 ? 1.0f : 0.05f * static_cast<float>(k);
    for (auto& ch : rgbs[k]) {
      ch.assign(n, 0.0f);
      for (float& v : ch)
        if (value(rng) < fill) v = value(rng);
    }
    grids.push_back({"B" + std::to_string(10 + k), nullptr, &rgbs[k], false, box});
    grids.back().metadata["lblight_converged"] = k % 2 == 0;
  }
  const nlohmann::json meta = {{"creator", "test"}};
  for (int parallel : {1, 4}) {
    VdbStreamWriter w(tmp / ("p" + std::to_string(parallel) + ".vdb"), frame, static_cast<int>(grids.size()), meta,
                      parallel);
    for (const DenseGridOut& g : grids) w.add(g);
    w.close();
    CHECK(w.grids_written() == static_cast<int>(grids.size()));
  }
  // The serial writer's grids written again, in the same order, by OpenVDB's own File::write:
  // the same bytes.
  openvdb::io::File in((tmp / "p1.vdb").string());
  in.open();
  openvdb::GridPtrVec read;
  for (const DenseGridOut& g : grids) read.push_back(in.readGrid(g.name));
  openvdb::MetaMap::Ptr file_meta = in.getMetadata();
  in.close();
  openvdb::io::File out((tmp / "openvdb.vdb").string());
  out.write(read, *file_meta);
  out.close();

  const std::string serial = read_bytes(tmp / "p1.vdb"), parallel = read_bytes(tmp / "p4.vdb"),
                    reference = read_bytes(tmp / "openvdb.vdb");
  for (const std::string* other : {&parallel, &reference}) {
    INFO((other == &parallel ? "4 grids at once" : "io::File::write"));
    REQUIRE(other->size() == serial.size());
    CHECK(other->substr(0, 21) == serial.substr(0, 21));  // all but the UUID at [21, 57)
    CHECK(other->substr(57) == serial.substr(57));
  }
  // Each grid found through its descriptor's (relocated) stream positions.
  for (const DenseGridOut& g : grids) {
    const DenseGridIn back = read_vdb_grid_dense(tmp / "p4.vdb", g.name);
    if (g.scalar) {
      CHECK(back.values[0] == *g.scalar);
    } else {
      for (int c = 0; c < 3; ++c) CHECK(back.values[static_cast<std::size_t>(c)] == (*g.rgb)[static_cast<std::size_t>(c)]);
    }
  }
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
      "output": {"lbh": {"threshold": 0.01, "relative": true}, "full_box": true}})",
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

TEST_CASE("A committed output replaces the earlier one and leaves no copy of it behind", "[io]") {
  // the earlier output is moved aside while the new one moves in; once in place, the old one goes
  TempDir tmp;
  const fs::path target = tmp / "out";
  fs::create_directories(target);
  write_text(target / "manifest.json", R"({"lblight_version": "0.1", "models": []})");
  write_text(target / "old.vdb", std::string(1000, 'x'));
  {
    StagedDirectory dir(target, OutputKind::Bake);
    write_text(dir.path("manifest.json"), R"({"lblight_version": "0.2", "models": []})");
    dir.commit();
  }
  CHECK_FALSE(fs::exists(target / "old.vdb"));
  CHECK(read_text(target / "manifest.json").find("0.2") != std::string::npos);
  std::vector<std::string> beside;
  for (const auto& e : fs::directory_iterator(tmp.path())) beside.push_back(e.path().filename().string());
  CHECK(beside == std::vector<std::string>{"out"});
}

TEST_CASE("Only a marker file with lblight's own keys makes a folder an earlier output", "[io]") {
  // a manifest.json or report.json written by anything else is not ours to delete, even alone
  TempDir tmp;
  const auto folder_with = [&](const std::string& name, const std::string& file, const std::string& text) {
    fs::create_directories(tmp / name);
    write_text(tmp / name / file, text);
    return tmp / name;
  };
  const auto refused = [](const fs::path& target, OutputKind kind) {
    expect_invalid_input([&] { StagedDirectory::check_target(target, kind); }, "refusing to replace it");
  };
  const fs::path extension = folder_with("ext", "manifest.json", R"({"name": "my-extension", "manifest_version": 3})");
  refused(extension, OutputKind::Bake);
  refused(folder_with("half", "manifest.json", R"({"lblight_version": "0.1"})"), OutputKind::Bake);
  refused(folder_with("rep", "report.json", R"({"curves": []})"), OutputKind::Report);
  // lblight's own markers are accepted
  const fs::path bake = folder_with("bake", "manifest.json", R"({"lblight_version": "0.1", "models": []})");
  CHECK_NOTHROW(StagedDirectory::check_target(bake, OutputKind::Bake));
  const fs::path report = folder_with("report", "report.json", R"({"curves": [], "references": []})");
  CHECK_NOTHROW(StagedDirectory::check_target(report, OutputKind::Report));
  CHECK(fs::exists(extension / "manifest.json"));
}

TEST_CASE("write_file_atomically refuses a folder and a FIFO and replaces a symlink's target, not the link",
          "[io]") {
  TempDir tmp;
  std::filesystem::create_directory(tmp.path() / "folder");
  CHECK_THROWS_WITH(write_file_atomically(tmp.path() / "folder", std::string("x")), Catch::Contains("is a folder"));
  // A FIFO is refused at once (opening it for writing blocks until a reader comes) and stays a
  // FIFO (renaming over it would replace it, as it once replaced /dev/null).
  const std::filesystem::path fifo = tmp.path() / "pipe";
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  CHECK_THROWS_WITH(write_file_atomically(fifo, std::string("through")), Catch::Contains("FIFO"));
  CHECK(std::filesystem::is_fifo(fifo));
  write_text(tmp / "target.json", "old");
  std::filesystem::create_symlink("target.json", tmp.path() / "link.json");
  write_file_atomically(tmp.path() / "link.json", std::string("new"));
  CHECK(std::filesystem::is_symlink(tmp.path() / "link.json"));
  CHECK(read_text(tmp / "target.json") == "new");
}

TEST_CASE("A manifest entry names delta-M scaled light for every calibrated model name, not the papers'", "[manifest]") {
  // LbModel::name() is "calibrated" or, with switches off their defaults, "calibrated (...)": the
  // default scene's first_collision made it the second, which a plain string compare missed and
  // render then drew its cumulus 1.7x too bright.
  const auto entry = [](const char* name, bool delta_m) {
    return nlohmann::json{{"lb_model", name}, {"lb_calibration", {{"delta_m", delta_m}}}};
  };
  CHECK(lblight::solved_with_delta_m(entry("calibrated", true)));
  CHECK(lblight::solved_with_delta_m(entry("calibrated (with first_collision)", true)));
  CHECK_FALSE(lblight::solved_with_delta_m(entry("calibrated (no delta_m)", false)));
  CHECK_FALSE(lblight::solved_with_delta_m(entry("paper", true)));
}
