// write_brick_vdb (vdb_io.h): bricks become OpenVDB leaf nodes directly, so a volume of millions
// of active voxels is written without a dense copy or per-voxel tree lookups.
#include <openvdb/openvdb.h>

#include "lblight/io/vdb_common.h"
#include "lblight/io/vdb_io.h"

namespace lblight {

namespace {

template <typename GridT, typename Fill>
typename GridT::Ptr brick_grid(const BrickVolumeOut& v, const std::string& name, Fill fill) {
  auto grid = GridT::create(typename GridT::ValueType(0));
  grid->setName(name);
  grid->setTransform(openvdb::math::Transform::createLinearTransform(v.voxel_size));
  auto& tree = grid->tree();
  for (const VolumeBrick* b : v.bricks) {
    typename GridT::ValueType scratch;
    bool any = false;
    for (int n = 0; n < kBrickVoxels && !any; ++n) any = fill(*b, n, scratch);
    if (!any) continue;  // no leaf for a brick with nothing active in this grid
    auto* leaf = tree.touchLeaf(openvdb::Coord(b->origin[0], b->origin[1], b->origin[2]));
    for (int z = 0; z < kBrickEdge; ++z)
      for (int y = 0; y < kBrickEdge; ++y)
        for (int x = 0; x < kBrickEdge; ++x) {
          const int n = x + kBrickEdge * (y + kBrickEdge * z);
          typename GridT::ValueType value;
          const bool on = fill(*b, n, value);
          const openvdb::Index offset = GridT::TreeType::LeafNodeType::coordToOffset(
              openvdb::Coord(b->origin[0] + x, b->origin[1] + y, b->origin[2] + z));
          if (on) leaf->setValueOn(offset, value);
        }
  }
  tree.prune();
  return grid;
}

}  // namespace

void write_brick_vdb(const std::filesystem::path& file, const BrickVolumeOut& v, const nlohmann::json& file_metadata) {
  vdb_detail::ensure_initialized();
  openvdb::GridPtrVec grids;
  auto density = brick_grid<openvdb::FloatGrid>(v, "density", [](const VolumeBrick& b, int n, float& out) {
    out = b.density[static_cast<std::size_t>(n)];
    return out > 0.0f;
  });
  density->setGridClass(openvdb::GRID_FOG_VOLUME);
  vdb_detail::set_metadata(*density, v.density_metadata);
  auto light = brick_grid<openvdb::Vec3SGrid>(v, "light", [](const VolumeBrick& b, int n, openvdb::Vec3f& out) {
    const auto i = static_cast<std::size_t>(n);
    out = openvdb::Vec3f(b.light[0][i], b.light[1][i], b.light[2][i]);
    return b.active.test(i);
  });
  vdb_detail::set_metadata(*light, v.light_metadata);
  grids.push_back(light);
  grids.push_back(density);
  if (v.with_wood)
    grids.push_back(brick_grid<openvdb::FloatGrid>(v, "brown", [](const VolumeBrick& b, int n, float& out) {
      out = b.wood[static_cast<std::size_t>(n)];
      return out > 0.0f;
    }));
  openvdb::MetaMap meta;
  vdb_detail::set_metadata(meta, file_metadata);
  openvdb::io::File f(file.string());
  f.write(grids, meta);
  f.close();
}

}  // namespace lblight
