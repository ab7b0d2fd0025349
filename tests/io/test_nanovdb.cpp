// NanoVDB output (io/nanovdb_io.h, docs/output-format.md): a bake with "output": {"nanovdb": true}
// writes <model>.nvdb beside <model>.vdb, named in the manifest; every grid is there with the
// same values, NanoVDB's own validator (nanovdb_validate) accepts the file, and `lblight nanovdb`
// converts a .vdb by itself, refusing to overwrite its input.
#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <iostream>  // nanovdb/util/GridValidator.h needs std::cerr

#include <nanovdb/util/IO.h>
#include <nlohmann/json.hpp>

#include "lblight/io/vdb_io.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {

const char* kScene = R"({"version": 1, "models": [{"name": "tree", "density": {"type": "procedural", "shape": "plant",
  "resolution": 12, "seed": 4}, "material": "leaf"}], "lighting": {"mode": "base", "solutions": [0, 5, 6]},
  "output": {"nanovdb": true}})";

}  // namespace

TEST_CASE("nanovdb: a bake's .nvdb holds every grid of its .vdb with the same values", "[io][nanovdb]") {
  TempDir tmp;
  write_text(tmp / "scene.json", kScene);
  const CliResult b = run_cli("bake scene.json -o bake -q", tmp.path());
  INFO(b.out << b.err);
  REQUIRE(b.exit_code == 0);
  const nlohmann::json manifest = nlohmann::json::parse(read_text(tmp / "bake" / "manifest.json"));
  CHECK(manifest["models"][0]["nanovdb_file"] == "tree.nvdb");
  const std::filesystem::path vdb = tmp / "bake" / "tree.vdb", nvdb = tmp / "bake" / "tree.nvdb";
  auto handles = nanovdb::io::readGrids(nvdb.string());
  const nlohmann::json info = inspect_vdb(vdb);
  REQUIRE(handles.size() == info["grids"].size());
  int compared = 0;
  for (auto& h : handles) {
    const std::string name = h.gridMetaData()->shortGridName();
    const DenseGridIn dense = read_vdb_grid_dense(vdb, name);
    const Dims& d = dense.frame.dims;
    for (int z = 0; z < d.nz; ++z)
      for (int y = 0; y < d.ny; ++y)
        for (int x = 0; x < d.nx; ++x) {
          const nanovdb::Coord ijk(x + dense.frame.index_min[0], y + dense.frame.index_min[1], z + dense.frame.index_min[2]);
          const std::size_t i = d.index(x, y, z);
          if (auto* g = h.grid<float>()) {
            CHECK(g->getAccessor().getValue(ijk) == dense.values[0][i]);
          } else {
            auto* v = h.grid<nanovdb::Vec3f>();
            REQUIRE(v != nullptr);
            const nanovdb::Vec3f got = v->getAccessor().getValue(ijk);
            for (int c = 0; c < 3; ++c) CHECK(got[c] == dense.values[c][i]);
          }
          ++compared;
        }
    // the same voxel size and placement
    CHECK(h.gridMetaData()->voxelSize()[0] == Approx(dense.frame.index_to_world[0]));
  }
  CHECK(compared > 1000);
#ifdef NANOVDB_VALIDATE_EXE
  CHECK(std::system((std::string(NANOVDB_VALIDATE_EXE) + " '" + nvdb.string() + "'").c_str()) == 0);
#else
  WARN("nanovdb_validate not found (apt-get install libnanovdb-tools): the file was checked by lblight's own validator only");
#endif

  // The command alone: default name beside the input, its input never overwritten.
  const CliResult c = run_cli("nanovdb bake/tree.vdb -o alone.nvdb", tmp.path());
  INFO(c.out << c.err);
  CHECK(c.exit_code == 0);
  CHECK(std::filesystem::file_size(tmp / "alone.nvdb") == std::filesystem::file_size(nvdb));
  const CliResult same = run_cli("nanovdb bake/tree.vdb -o bake/tree.vdb", tmp.path());
  CHECK(same.exit_code == 2);
  const CliResult not_vdb = run_cli("nanovdb scene.json", tmp.path());
  CHECK(not_vdb.exit_code == 2);
  CHECK(not_vdb.err.find("scene.json") != std::string::npos);
  // nanovdb needs the .vdb it converts
  write_text(tmp / "novdb.json", std::string(kScene).replace(std::string(kScene).find(R"("nanovdb": true)"), 15,
                                                              R"("nanovdb": true, "vdb": false, "lbh": true)"));
  const CliResult refused = run_cli("bake novdb.json -o x -q", tmp.path());
  CHECK(refused.exit_code == 2);
  CHECK(refused.err.find("nanovdb") != std::string::npos);
}
