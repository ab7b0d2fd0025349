// Work units (lblight/pipeline/work_units.h, docs/scale-out.md): `bake --only` partials merge into
// exactly a one-machine bake (models and coarse forest lattices), `--resume` skips finished units
// and recomputes changed or damaged ones, and `merge` refuses damaged, foreign, missing and
// duplicated parts without writing anything. The Slurm side is tests/slurm/check_submit.py.
#include <catch2/catch.hpp>

#include <fstream>
#include <map>

#include <nlohmann/json.hpp>

#include "lblight/pipeline/slurm.h"
#include "lblight/pipeline/work_units.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;
namespace fs = std::filesystem;

namespace {

// Two models placed in a forest: five units (tree, puff, forest, forest.alone.tree,
// forest.alone.puff), with .lbh output; `tolerance` changes the inputs.
std::string forest_scene(const std::string& name = "units", const std::string& tolerance = "1e-3") {
  return R"({"version": 1, "name": ")" + name + R"(",
    "models": [{"name": "tree", "density": {"type": "procedural", "shape": "plant", "resolution": 10, "seed": 4,
                                            "size": 1.2}, "material": "leaf", "wood_material": "bark"},
               {"name": "puff", "density": {"type": "procedural", "shape": "cloud", "resolution": 8, "size": 1.0},
                "material": "cloud"}],
    "lighting": {"mode": "base", "solutions": "0,1,6"},
    "solver": {"iterations": "auto", "tolerance": )" + tolerance + R"(, "max_iterations": 200},
    "output": {"lbh": {"threshold": 0.01, "relative": true}},
    "forest": {"instances": [{"model": "tree", "position": [0, 0, 0]}, {"model": "puff", "position": [3, 0, 0]}]}})";
}
const std::vector<std::string> kUnits = {"tree", "puff", "forest", "forest.alone.tree", "forest.alone.puff"};

void bake_units(const TempDir& tmp, const std::string& scene, const std::string& parts) {
  for (const std::string& u : kUnits) {
    const CliResult r = run_cli("-q bake " + scene + " --backend cpu --only " + u + " -o " + parts + "/" + u, tmp.path());
    INFO(r.err);
    REQUIRE(r.exit_code == 0);
  }
}

std::string part_list(const std::string& parts) {
  std::string s;
  for (const std::string& u : kUnits) s += " " + parts + "/" + u;
  return s;
}

void flip_last_byte(const fs::path& file) {
  std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
  f.seekg(-1, std::ios::end);
  const char c = static_cast<char>(f.get() ^ 0x5a);
  f.seekp(-1, std::ios::end);
  f.put(c);
}

}  // namespace

TEST_CASE("bake --only partials merge into exactly the one-machine bake", "[cli][units]") {
  TempDir tmp;
  write_text(tmp / "scene.json", forest_scene());
  REQUIRE(run_cli("-q bake scene.json --backend cpu -o whole", tmp.path()).exit_code == 0);
  bake_units(tmp, "scene.json", "parts");

  const nlohmann::json part = nlohmann::json::parse(read_text(tmp / "parts" / "forest" / "manifest.json"));
  CHECK(part["unit"]["name"] == "forest");
  CHECK(part["unit"]["units"] == nlohmann::json(kUnits));
  CHECK(part["unit"]["hash"].get<std::string>().rfind("fnv1a64:", 0) == 0);
  CHECK(part["unit"]["files"].contains("forest.vdb"));
  CHECK(part["unit"]["files"].contains("forest.lbh"));
  CHECK(part.contains("forest"));  // the coarse lattices carry the forest's table
  CHECK_FALSE(nlohmann::json::parse(read_text(tmp / "parts" / "tree" / "manifest.json")).contains("forest"));

  const CliResult m = run_cli("merge --scene scene.json" + part_list("parts") + " -o merged", tmp.path());
  INFO(m.err);
  REQUIRE(m.exit_code == 0);
  const CliResult same = run_cli("compare --exact whole merged", tmp.path());
  INFO(same.out);
  CHECK(same.exit_code == 0);
  CHECK(same.out.find("identical") != std::string::npos);
  const nlohmann::json merged = nlohmann::json::parse(read_text(tmp / "merged" / "manifest.json"));
  CHECK_FALSE(merged.contains("unit"));
  CHECK(merged["models"].size() == kUnits.size());

  // --exact sees a difference beyond the run record.
  REQUIRE(run_cli("-q bake scene.json --backend cpu --tolerance 1e-2 -o looser", tmp.path()).exit_code == 0);
  const CliResult other = run_cli("compare --exact whole looser", tmp.path());
  CHECK(other.exit_code == 1);
  CHECK(other.out.find("differs: manifest") != std::string::npos);
}

TEST_CASE("bake --only --resume skips a finished unit and recomputes a changed or damaged one", "[cli][units]") {
  TempDir tmp;
  write_text(tmp / "scene.json", forest_scene());
  REQUIRE(run_cli("-q bake scene.json --backend cpu --only tree -o p", tmp.path()).exit_code == 0);
  const std::string created = nlohmann::json::parse(read_text(tmp / "p" / "manifest.json"))["created"];
  const std::string bake = "bake scene.json --backend cpu --only tree --resume -o p";

  const CliResult again = run_cli(bake, tmp.path());
  INFO(again.err);
  REQUIRE(again.exit_code == 0);
  CHECK(again.err.find("unit 'tree': finished in p (inputs hash fnv1a64:") != std::string::npos);
  CHECK(again.err.find("not recomputed") != std::string::npos);
  CHECK(again.out.find("already done") != std::string::npos);
  CHECK(nlohmann::json::parse(read_text(tmp / "p" / "manifest.json"))["created"] == created);

  flip_last_byte(tmp / "p" / "tree.lbh");
  const CliResult damaged = run_cli(bake, tmp.path());
  INFO(damaged.err);
  REQUIRE(damaged.exit_code == 0);
  CHECK(damaged.err.find("tree.lbh does not match its checksum") != std::string::npos);
  CHECK(damaged.err.find("baking it") != std::string::npos);

  write_text(tmp / "scene.json", forest_scene("units", "2e-3"));
  const CliResult changed = run_cli(bake, tmp.path());
  INFO(changed.err);
  REQUIRE(changed.exit_code == 0);
  CHECK(changed.err.find("is not this bake's") != std::string::npos);
  CHECK(changed.err.find("baking it") != std::string::npos);
}

TEST_CASE("bake --resume without --only bakes unit by unit and keeps finished ones", "[cli][units]") {
  TempDir tmp;
  write_text(tmp / "scene.json", forest_scene());
  REQUIRE(run_cli("-q bake scene.json --backend cpu -o whole", tmp.path()).exit_code == 0);
  // An interrupted bake --resume: two units finished.
  for (const char* u : {"tree", "forest"})
    REQUIRE(run_cli(std::string("-q bake scene.json --backend cpu --only ") + u + " -o out.parts/" + u, tmp.path())
                .exit_code == 0);
  const CliResult r = run_cli("bake scene.json --backend cpu --resume -o out", tmp.path());
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  CHECK(r.err.find("unit 'tree': finished in out.parts/tree") != std::string::npos);
  CHECK(r.err.find("unit 'forest': finished in out.parts/forest") != std::string::npos);
  CHECK(r.err.find("unit 'puff': no partial output yet") != std::string::npos);
  CHECK_FALSE(fs::exists(tmp / "out.parts"));
  CHECK(run_cli("compare --exact whole out", tmp.path()).exit_code == 0);
}

TEST_CASE("merge refuses damaged, foreign, missing and repeated parts and writes nothing", "[cli][units]") {
  TempDir tmp;
  write_text(tmp / "scene.json", forest_scene());
  write_text(tmp / "other.json", forest_scene("other", "2e-3"));
  bake_units(tmp, "scene.json", "parts");
  REQUIRE(run_cli("-q bake other.json --backend cpu --only puff -o foreign", tmp.path()).exit_code == 0);
  REQUIRE(run_cli("-q bake scene.json --backend cpu --solutions 0 -o whole", tmp.path()).exit_code == 0);
  fs::copy(tmp / "parts" / "tree", tmp / "damaged");
  flip_last_byte(tmp / "damaged" / "tree.vdb");

  const std::string rest = " parts/puff parts/forest parts/forest.alone.tree parts/forest.alone.puff";
  const struct {
    std::string args, expect;
  } cases[] = {
      {"damaged" + rest, "refused part damaged: tree.vdb does not match its checksum"},
      {"parts/tree foreign parts/forest parts/forest.alone.tree parts/forest.alone.puff",
       "refused part foreign: it is a bake of scene 'other'"},
      {"--scene other.json" + part_list("parts"), "refused part parts/tree: it is a bake of scene 'units'"},
      {"parts/tree" + rest + " parts/tree", "unit 'tree' is also given as parts/tree"},
      {rest, "missing unit(s) tree"},
      {"whole" + rest, "refused part whole: not a partial output"},
      {"nowhere" + rest, "refused part nowhere: no partial output there"},
  };
  for (const auto& c : cases) {
    const CliResult r = run_cli("merge " + c.args + " -o merged", tmp.path());
    INFO(c.args << "\n" << r.err);
    CHECK(r.exit_code == 2);
    CHECK(r.err.find(c.expect) != std::string::npos);
    CHECK_FALSE(fs::exists(tmp / "merged"));
  }
  // Damage after the size check (same size, other bytes) is caught while copying, before anything
  // is put in place.
  CHECK(run_cli("merge" + part_list("parts") + " -o merged", tmp.path()).exit_code == 0);
}

TEST_CASE("A model baked in shares of its solutions merges into exactly the one-machine bake", "[cli][units]") {
  // tree: 3 distinct channels (a batch is one solution); puff: one channel (a batch is 3 solutions).
  // All 19 solutions: B00 is the sum of B01..B18, which only the merge has.
  TempDir tmp;
  write_text(tmp / "scene.json", R"({"version": 1, "name": "shares",
    "models": [{"name": "tree", "density": {"type": "procedural", "shape": "plant", "resolution": 10, "seed": 4,
                                            "size": 1.2}, "material": "leaf", "wood_material": "bark"},
               {"name": "puff", "density": {"type": "procedural", "shape": "cloud", "resolution": 8, "size": 1.0},
                "material": "cloud"}],
    "lighting": {"mode": "base", "solutions": "all"},
    "solver": {"iterations": "auto", "tolerance": 1e-3, "max_iterations": 200},
    "output": {"lbh": {"threshold": 0.01, "relative": true}}})");
  REQUIRE(run_cli("-q bake scene.json --backend cpu -o whole", tmp.path()).exit_code == 0);
  for (const char* share : {"tree:1-5", "tree:6-18", "puff:1-9", "puff:10-18"}) {
    const std::string dir = std::string("share-") + share;
    const CliResult r = run_cli(std::string("-q bake scene.json --backend cpu --only ") + share + " -o " + dir, tmp.path());
    INFO(r.err);
    REQUIRE(r.exit_code == 0);
  }
  const nlohmann::json share = nlohmann::json::parse(read_text(tmp / "share-tree:1-5" / "manifest.json"));
  CHECK(share["unit"]["solutions"] == nlohmann::json({1, 2, 3, 4, 5}));
  CHECK(share["unit"]["totals"]["B03"] == "tree.B03.totals");
  CHECK(share["models"][0]["solutions"].size() == 5);
  CHECK(share["unit"]["hash"] != share["unit"]["model_hash"]);

  const std::string all = " share-tree:6-18 share-puff:10-18 share-tree:1-5 share-puff:1-9";
  const CliResult m = run_cli("merge" + all + " -o merged", tmp.path());
  INFO(m.err);
  REQUIRE(m.exit_code == 0);
  CHECK(m.err.find("unit 'tree': assembled from 2 part(s)") != std::string::npos);
  CHECK_FALSE(fs::exists(tmp / "merged.assembling"));
  const CliResult same = run_cli("compare --exact whole merged", tmp.path());
  INFO(same.out);
  CHECK(same.exit_code == 0);

  // Shares must be whole batches, never the summed B00, and every solution exactly once.
  const CliResult split = run_cli("bake scene.json --backend cpu --only puff:1-2 -o x", tmp.path());
  CHECK(split.exit_code == 2);
  CHECK(split.err.find("split a batch of model 'puff'") != std::string::npos);
  CHECK(split.err.find("B01,B02,B03 | B04,B05,B06") != std::string::npos);
  const CliResult b00 = run_cli("bake scene.json --backend cpu --only tree:0-5 -o x", tmp.path());
  CHECK(b00.exit_code == 2);
  CHECK(b00.err.find("B00 of model 'tree' is the sum of B01..B18") != std::string::npos);
  CHECK_FALSE(fs::exists(tmp / "x"));
  const CliResult lacking = run_cli("merge share-tree:1-5 share-puff:1-9 share-puff:10-18 -o m2", tmp.path());
  CHECK(lacking.exit_code == 2);
  CHECK(lacking.err.find("no part holds its solution(s) [6,7,8,9,10,11,12,13,14,15,16,17,18]") != std::string::npos);
  REQUIRE(run_cli("-q bake scene.json --backend cpu --only tree:5-6 -o overlap", tmp.path()).exit_code == 0);
  const CliResult twice = run_cli("merge" + all + " overlap -o m2", tmp.path());
  CHECK(twice.exit_code == 2);
  CHECK(twice.err.find("refused part overlap: its solutions [6] of unit 'tree' are also in part share-tree:6-18") !=
        std::string::npos);
  CHECK_FALSE(fs::exists(tmp / "m2"));
}

TEST_CASE("The unit bake --only names must be a lattice of the scene", "[cli][units]") {
  TempDir tmp;
  write_text(tmp / "scene.json", forest_scene());
  const CliResult r = run_cli("bake scene.json --only trunk -o p", tmp.path());
  CHECK(r.exit_code == 2);
  CHECK(r.err.find("--only 'trunk' is not a lattice of this scene; allowed: tree, puff, forest, forest.alone.tree, "
                   "forest.alone.puff") != std::string::npos);
  CHECK_FALSE(fs::exists(tmp / "p"));
}

TEST_CASE("submit --dry-run writes the scripts, and status reads the parts and state files", "[cli][units]") {
  TempDir tmp;
  write_text(tmp / "scene.json", forest_scene());
  const std::string submit = "submit scene.json --slurm --dry-run --no-timing --cpus-per-task 1 -o run";
  const CliResult dry = run_cli(submit, tmp.path());
  INFO(dry.err);
  REQUIRE(dry.exit_code == 0);
  CHECK(dry.out.find("--array=0-4 ") != std::string::npos);
  CHECK(dry.out.find("--dependency=afterok:") != std::string::npos);
  const std::string units = read_text(tmp / "run" / "slurm" / "units.sbatch");
  CHECK(units.find("units=(tree puff forest forest.alone.tree forest.alone.puff)") != std::string::npos);
  CHECK(units.find("#SBATCH --time=0-00:10:00") != std::string::npos);  // no estimate: the floor
  CHECK(units.find("#SBATCH --mem=") != std::string::npos);
  CHECK(units.find("--only \"$unit\" --backend cpu") != std::string::npos);
  CHECK(units.find("gpus") == std::string::npos);
  const std::string merge = read_text(tmp / "run" / "slurm" / "merge.sbatch");
  CHECK(merge.find("#SBATCH --kill-on-invalid-dep=yes") != std::string::npos);
  CHECK(merge.find("merge --scene") != std::string::npos);

  // What the jobs leave: one unit done, one failed, one running.
  REQUIRE(run_cli("-q bake scene.json --backend cpu --only tree -o run/parts/tree", tmp.path()).exit_code == 0);
  write_text(tmp / "run" / "state" / "puff.json",
             R"({"state": "failed", "job": "7_1", "host": "n1", "time": "t", "log": "L", "exit_code": 2})");
  write_text(tmp / "run" / "state" / "forest.json", R"({"state": "running", "job": "7_2", "host": "n2", "time": "t"})");
  const CliResult st = run_cli("status run --json", tmp.path());
  INFO(st.err);
  REQUIRE(st.exit_code == 0);
  const nlohmann::json j = nlohmann::json::parse(st.out);
  std::map<std::string, std::string> states;
  for (const auto& u : j["units"]) states[u["name"]] = u["state"];
  CHECK(states == std::map<std::string, std::string>{{"tree", "done"}, {"puff", "failed"}, {"forest", "running"},
                                                     {"forest.alone.tree", "missing"}, {"forest.alone.puff", "missing"}});
  CHECK(j["merged"].is_null());
  const CliResult text = run_cli("status run", tmp.path());
  CHECK(text.out.find("exit code 2, job 7_1 on n1") != std::string::npos);
  CHECK(text.out.find("1 done, 1 running, 0 queued, 1 failed, 2 missing") != std::string::npos);

  const CliResult resume = run_cli(submit + " --resume", tmp.path());
  CHECK(resume.exit_code == 0);
  CHECK(resume.out.find("done: skipped") != std::string::npos);
  CHECK(resume.out.find("--array=1-4 ") != std::string::npos);

  // One byte of the finished unit changed, its size kept: by content, it is not done any more.
  flip_last_byte(tmp / "run" / "parts" / "tree" / "tree.lbh");
  const nlohmann::json after = nlohmann::json::parse(run_cli("status run --json", tmp.path()).out);
  CHECK(after["units"][0]["name"] == "tree");
  CHECK(after["units"][0]["state"] == "missing");
  CHECK(after["units"][0]["detail"].get<std::string>().find("does not match its checksum") != std::string::npos);
  const CliResult redo = run_cli(submit + " --resume", tmp.path());
  CHECK(redo.exit_code == 0);
  CHECK(redo.out.find("done: skipped") == std::string::npos);
  CHECK(redo.out.find("--array=0-4 ") != std::string::npos);

  write_text(tmp / "other.json", forest_scene("other"));
  CHECK(run_cli("submit other.json --slurm --dry-run --no-timing -o run", tmp.path()).exit_code == 2);
  const CliResult gpu = run_cli("submit scene.json --slurm --dry-run --backend cpu --gpus-per-task 1 -o g", tmp.path());
  CHECK(gpu.exit_code == 2);
  CHECK(gpu.err.find("--gpus-per-task 1 with --backend cpu") != std::string::npos);
  CHECK(run_cli("submit scene.json --dry-run -o g", tmp.path()).exit_code == 2);  // --slurm is required
}

TEST_CASE("the run record: fields two runs of one bake may differ in", "[units]") {
  nlohmann::json m = {{"created", "x"}, {"command", "y"}, {"total_seconds", 1.0}, {"unit", {{"name", "tree"}}},
                      {"backend", {{"name", "cpu"}, {"description", "2 threads"}}},
                      {"models", {{{"name", "tree"}, {"peak_memory_bytes", 5},
                                   {"solutions", {{{"seconds", 1.5}, {"iterations", 10},
                                                   {"residual_history", {{13, 0.5, 1.0}}},
                                                   {"compression", {{"encode_seconds", 0.1}, {"ratio", 3.0}}}}}}}}}};
  const nlohmann::json kept = {{"backend", {{"name", "cpu"}}},
                               {"models", {{{"name", "tree"},
                                            {"solutions", {{{"iterations", 10},
                                                            {"residual_history", {{13, nullptr, 1.0}}},
                                                            {"compression", {{"ratio", 3.0}}}}}}}}}};
  CHECK(without_run_record(m) == kept);
}

TEST_CASE("Slurm values: time limits, memory and array ranges", "[units]") {
  CHECK(slurm_time(59) == "0-00:01:00");
  CHECK(slurm_time(3601) == "0-01:01:00");
  CHECK(slurm_time(2 * 86400 + 60) == "2-00:01:00");
  CHECK(slurm_mem(1048576.0 * 1.5) == "2M");
  CHECK(task_time_limit(0) == 600);
  CHECK(task_time_limit(1000) == 2120);
  CHECK(array_ranges({0, 1, 2, 5, 7, 8}) == "0-2,5,7-8");
  CHECK(array_ranges({3}) == "3");
}
