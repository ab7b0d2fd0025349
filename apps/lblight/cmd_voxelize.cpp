// lblight voxelize: a triangle mesh to an OpenVDB density grid ([Steele2009] sec. 5.1) with a `brown`
// grid marking wood nodes ([Steele2009] sec. 4.1), the same voxelisation a scene's `mesh` source runs.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <iostream>
#include <sstream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/core/error.h"
#include "lblight/core/version.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/vdb_io.h"
#include "lblight/scene/mesh_source.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct VoxelizeArgs {
  std::string mesh, out;
  int resolution = 64, supersample = 8, padding = 0, threads = 0;
  std::vector<double> bounds;
  std::vector<std::string> leaf_patterns, wood_patterns;
  std::string fill = "none";
  bool json = false;
};

int run_voxelize(const VoxelizeArgs& a, const GlobalOptions& global) {
  MeshSource src;
  src.path = a.mesh;
  src.resolution = a.resolution;
  src.supersample = a.supersample;
  src.leaf_patterns = a.leaf_patterns;
  src.wood_patterns = a.wood_patterns;
  src.fill = a.fill;
  if (!a.bounds.empty()) {
    for (int i = 0; i < 3; ++i) {
      src.bounds_min[i] = a.bounds[static_cast<std::size_t>(i)];
      src.bounds_max[i] = a.bounds[static_cast<std::size_t>(i + 3)];
      if (!(src.bounds_max[i] > src.bounds_min[i]))
        throw_invalid("--bounds: max must exceed min on every axis (XMIN YMIN ZMIN XMAX YMAX ZMAX)");
    }
    src.has_bounds = true;
  }
  fs::path out = a.out.empty() ? fs::path(fs::path(a.mesh).stem().string() + ".vdb") : fs::path(a.out);
  const fs::path folder = out.has_parent_path() ? out.parent_path() : fs::path(".");
  if (!fs::is_directory(folder)) throw_invalid("output folder " + folder.string() + " does not exist");
  check_output_file(a.mesh, out, ".vdb");

  const MeshVoxels mv = voxelize_mesh_source(src, a.padding, {}, {&g_interrupted, usable_threads(a.threads), {}});
  const ModelGrid& g = mv.voxels.grid;
  const VoxelizeStats& st = mv.voxels.stats;

  std::vector<float> brown(g.dims.count(), 0.0f);
  for (std::size_t i = 0; i < brown.size(); ++i)
    if (g.material[i] == kMaterialWood && g.density[i] > 0.0f) brown[i] = 1.0f;
  const nlohmann::json frame_box = {{"lblight_lattice_min", g.index_min},
                                    {"lblight_lattice_dims", {g.dims.nx, g.dims.ny, g.dims.nz}}};
  const double voxel = g.voxel_size()[0];
  nlohmann::json meta = {{"lblight_version", kVersion},
                         {"lblight_command", global.command_line},
                         {"lblight_mesh", fs::path(a.mesh).filename().string()},
                         {"lblight_resolution", a.resolution},
                         {"lblight_supersample", a.supersample},
                         {"lblight_padding", a.padding},
                         {"lblight_fill", a.fill},
                         {"lblight_voxel_size", voxel},
                         {"lblight_triangles", mv.triangles},
                         {"lblight_leaf_triangles", mv.classes.leaf_triangles},
                         {"lblight_wood_triangles", mv.classes.wood_triangles},
                         {"lblight_unmatched_triangles", mv.classes.unmatched_triangles},
                         {"lblight_degenerate_triangles", st.degenerate},
                         {"lblight_outside_triangles", st.outside},
                         {"lblight_occupied_nodes", st.occupied_nodes},
                         {"lblight_brown_nodes", st.brown_nodes},
                         {"lblight_fine_occupied", st.fine_occupied},
                         {"lblight_voxelize_seconds", st.seconds}};
  const DenseFrame frame = g.frame();
  nlohmann::json dmeta = frame_box;
  dmeta["lblight_meaning"] = "fraction of the node's supersample^3 fine cells touched by the mesh";
  nlohmann::json bmeta = frame_box;
  bmeta["lblight_meaning"] = "1 where wood touches more fine cells of the node than leaves ([Steele2009] sec. 4.1)";
  const std::vector<DenseGridOut> grids = {{"density", &g.density, nullptr, true, dmeta},
                                           {"brown", &brown, nullptr, false, bmeta}};
  // Written under a temporary name and renamed: the output appears complete or not at all.
  write_file_atomically(out, [&](const fs::path& tmp) {
    write_vdb(tmp, frame, grids, meta);
    throw_if_interrupted();
  });

  nlohmann::json summary = meta;
  summary["output"] = out.string();
  summary["dims"] = {g.dims.nx, g.dims.ny, g.dims.nz};
  summary["index_to_world"] = g.index_to_world;
  summary["read_seconds"] = mv.read_seconds;
  if (a.json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::ostringstream s;
    s << a.mesh << ": " << mv.triangles << " triangles (" << mv.classes.leaf_triangles << " leaf, "
      << mv.classes.wood_triangles << " wood, " << mv.classes.unmatched_triangles << " unmatched counted as leaf, "
      << st.degenerate << " degenerate skipped)\n";
    s << "grid " << g.dims.nx << "x" << g.dims.ny << "x" << g.dims.nz << " nodes of " << voxel << " (supersample "
      << a.supersample << ": fine grid " << st.fine_dims[0] << "x" << st.fine_dims[1] << "x" << st.fine_dims[2]
      << "), " << st.occupied_nodes << " occupied, " << st.brown_nodes << " brown\n";
    s << "voxelized in " << format_seconds(st.seconds) << " s on " << st.threads << " thread(s) (reading "
      << format_seconds(mv.read_seconds) << " s); wrote " << out.string() << " (grids density, brown)\n";
    std::cout << s.str();
  }
  return 0;
}

}  // namespace

Command add_voxelize_command(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<VoxelizeArgs>();
  CLI::App* cmd = app.add_subcommand(
      "voxelize",
      "Voxelize a triangle mesh (Wavefront OBJ) into an OpenVDB file with a float 'density' grid (fraction of "
      "each node covered by the mesh, [Steele2009] sec. 5.1) and a float 'brown' grid (1 where wood outweighs leaves, "
      "[Steele2009] sec. 4.1). Leaf and wood triangles are told apart by material, group or object name.");
  cmd->add_option("mesh", args->mesh, "Mesh file (.obj)")->required();
  cmd->add_option("-o,--output", args->out, "Output .vdb file (default: <mesh name>.vdb here)")->check(kNonEmpty);
  cmd->add_option("-r,--resolution", args->resolution, "Nodes along the longest edge of the box")
      ->default_val(64)
      ->check(CLI::Range(1, 8192));
  cmd->add_option("--supersample", args->supersample, "Fine cells per node edge for the exact overlap test")
      ->default_val(8)
      ->check(CLI::Range(1, 64));
  cmd->add_option("--padding", args->padding, "Empty nodes added on every side of the box")
      ->default_val(0)
      ->check(CLI::Range(0, 1024));
  cmd->add_option("--bounds", args->bounds, "World box to voxelize instead of the mesh's: XMIN YMIN ZMIN XMAX YMAX ZMAX")
      ->expected(6);
  cmd->add_option("--leaf-pattern", args->leaf_patterns,
                  "Name pattern of leaf (green) parts; repeatable; default: leaf leaves foliage needle")
      ->check(kNonEmpty);
  cmd->add_option("--wood-pattern", args->wood_patterns,
                  "Name pattern of wood (brown) parts; repeatable; default: bark trunk branch wood stem")
      ->check(kNonEmpty);
  cmd->add_option("--fill", args->fill, "Fill closed solids: none (surface only), parity or winding")
      ->default_val("none")
      ->check(CLI::IsMember({"none", "parity", "winding"}));
  cmd->add_option("--threads", args->threads, "Threads (default: all cores)")->check(CLI::Range(0, 4096));
  cmd->add_flag("--json", args->json, "Print the summary as JSON");
  return {cmd, [args, &global] { return run_voxelize(*args, global); }};
}

}  // namespace lblight::cli
