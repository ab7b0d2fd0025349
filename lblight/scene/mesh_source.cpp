#include "lblight/scene/mesh_source.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <stdexcept>

#include "lblight/mesh/obj_reader.h"

namespace lblight {

FillMode parse_fill_mode(const std::string& text) {
  if (text == "none") return FillMode::None;
  if (text == "parity") return FillMode::Parity;
  if (text == "winding") return FillMode::Winding;
  throw std::invalid_argument("unknown fill mode '" + text + "'; allowed: none, parity, winding");
}

MeshVoxels voxelize_mesh_source(const MeshSource& source, int padding, const Location& where,
                                const RunContext& ctx) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string name = source.path.string();
  MeshVoxels out;
  TriangleMesh mesh = read_mesh(source.path, where);
  out.vertices = mesh.vertices.size();
  out.triangles = mesh.triangles.size();
  out.polygons = mesh.polygons;
  out.classes = classify_parts(mesh, source.leaf_patterns, source.wood_patterns);
  out.read_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (out.classes.unmatched_triangles > 0) {
    std::string parts;
    for (std::size_t i = 0; i < out.classes.unmatched_parts.size() && i < 5; ++i)
      parts += (i ? "; " : "") + out.classes.unmatched_parts[i];
    if (out.classes.unmatched_parts.size() > 5) parts += "; ...";
    spdlog::warn("{}: {} triangle(s) in {} part(s) match no leaf or wood pattern and count as leaf: {}", name,
                 out.classes.unmatched_triangles, out.classes.unmatched_parts.size(), parts);
  }
  if (mesh.ignored_lines > 0) spdlog::warn("{}: {} line/point element(s) have no area and are ignored", name, mesh.ignored_lines);
  if (mesh.unknown_statements > 0)
    spdlog::warn("{}: {} statement(s) of kinds the reader does not use (curves, surfaces, ...) are ignored", name,
                 mesh.unknown_statements);

  VoxelizeOptions opt;
  opt.resolution = source.resolution;
  opt.supersample = source.supersample;
  opt.has_bounds = source.has_bounds;
  opt.bounds_min = source.bounds_min;
  opt.bounds_max = source.bounds_max;
  opt.padding = padding;
  opt.fill = parse_fill_mode(source.fill);
  out.voxels = voxelize(mesh, out.classes.part_class, opt, where, ctx);
  const VoxelizeStats& st = out.voxels.stats;
  if (st.degenerate > 0) spdlog::warn("{}: {} degenerate (zero-area) triangle(s) skipped", name, st.degenerate);
  if (st.outside > 0) spdlog::warn("{}: {} triangle(s) lie outside the bounds and are skipped", name, st.outside);
  if (st.open_columns > 0)
    spdlog::warn("{}: fill: {} fine column(s) cross the surface an unbalanced number of times (mesh not closed or "
                 "not consistently oriented there); their open ends are left empty",
                 name, st.open_columns);
  const Dims& d = out.voxels.grid.dims;
  spdlog::info("{}: {} triangles ({} leaf, {} wood) -> {}x{}x{} nodes (supersample {}, fine {}x{}x{}), {} occupied, "
               "{} brown, in {:.2f} s on {} thread(s)",
               name, out.triangles, out.classes.leaf_triangles, out.classes.wood_triangles, d.nx, d.ny, d.nz,
               source.supersample, st.fine_dims[0], st.fine_dims[1], st.fine_dims[2], st.occupied_nodes,
               st.brown_nodes, st.seconds, st.threads);
  out.voxels.grid.description = "mesh " + name + " (" + std::to_string(out.triangles) + " triangles, " +
                                std::to_string(out.classes.wood_triangles) + " wood; resolution " +
                                std::to_string(source.resolution) + ", supersample " +
                                std::to_string(source.supersample) + ")";
  return out;
}

ModelGrid load_mesh_density(const MeshSource& source, const Location& where, const RunContext& ctx) {
  return std::move(voxelize_mesh_source(source, 0, where, ctx).voxels.grid);
}

}  // namespace lblight
