// OpenVDB-side helpers shared by the VDB reader and writer (internal: includes openvdb.h, so only
// the io/ translation units that already compile OpenVDB include it).
#pragma once

#include <array>

#include <nlohmann/json.hpp>
#include <openvdb/openvdb.h>

#include "lblight/io/vdb_io.h"

namespace lblight::vdb_detail {

void ensure_initialized();  // openvdb::initialize(), once per process

// Our matrices act on column vectors (translation in the 4th column); OpenVDB's Mat4d acts on
// row vectors (translation in the 4th row): one is the transpose of the other.
openvdb::math::Transform::Ptr to_vdb_transform(const std::array<double, 16>& m);

// JSON values as OpenVDB metadata: bool, int64, double (infinity as -1), string, Vec3i for a
// 3-integer array, anything else as its JSON text.
void set_metadata(openvdb::MetaMap& meta, const nlohmann::json& j);

// lblight arrays are x fastest, index (z * ny + y) * nx + x: OpenVDB's LayoutXYZ (its LayoutZYX,
// the Dense default, is z fastest and would scramble every grid for other OpenVDB readers).
openvdb::CoordBBox frame_bbox(const DenseFrame& f);

// Grid `name` of the file at `path`, read whole after the checks every lblight reader makes (a
// regular, complete file, read once in an isolated child first); Error(InvalidInput) naming the
// file and grid otherwise.
openvdb::GridBase::Ptr open_grid(const std::filesystem::path& path, const std::string& name, const Location& where,
                                 const RunContext& ctx);

}  // namespace lblight::vdb_detail
