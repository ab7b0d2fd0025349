#include "lblight/io/nanovdb_io.h"

#include <iostream>  // nanovdb/util/GridValidator.h uses std::cerr without including it
#include <string>
#include <vector>

#include <nanovdb/util/GridValidator.h>
#include <nanovdb/util/IO.h>
#include <nanovdb/util/OpenToNanoVDB.h>

#include "lblight/core/error.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/vdb_common.h"

namespace lblight {

NanoVdbWritten write_nanovdb(const std::filesystem::path& vdb, const std::filesystem::path& nvdb, const RunContext& ctx) {
  vdb_detail::ensure_initialized();
  const nlohmann::json info = inspect_vdb(vdb, ctx);
  std::vector<nanovdb::GridHandle<nanovdb::HostBuffer>> handles;
  for (const auto& g : info.at("grids")) {
    const std::string name = g.at("name");
    const Location where{vdb.string(), name, {}};
    const openvdb::GridBase::Ptr grid = vdb_detail::open_grid(vdb, name, where, ctx);
    if (!grid->isType<openvdb::FloatGrid>() && !grid->isType<openvdb::Vec3fGrid>())
      throw_invalid("grid '" + name + "' is of type " + grid->valueType() + "; NanoVDB output takes float and vec3s grids",
                    where);
    // The typed converters of the two grid types lblight writes: the GridBase overload compiles
    // one for every OpenVDB type (about a minute of this file's build).
    nanovdb::GridHandle<nanovdb::HostBuffer> handle =
        grid->isType<openvdb::FloatGrid>() ? nanovdb::openToNanoVDB(*openvdb::gridConstPtrCast<openvdb::FloatGrid>(grid))
                                           : nanovdb::openToNanoVDB(*openvdb::gridConstPtrCast<openvdb::Vec3fGrid>(grid));
    const bool valid = grid->isType<openvdb::FloatGrid>() ? nanovdb::isValid(*handle.grid<float>(), /*detailed=*/true)
                                                          : nanovdb::isValid(*handle.grid<nanovdb::Vec3f>(), true);
    if (!valid) throw Error(ErrorCategory::Internal, "NanoVDB's validator refused the converted grid", where);
    handles.push_back(std::move(handle));
    ctx.check_cancelled();
  }
  NanoVdbWritten out;
  out.grids = static_cast<int>(handles.size());
  write_file_atomically(nvdb, [&](const std::filesystem::path& tmp) {
    try {
      nanovdb::io::writeGrids(tmp.string(), handles, nanovdb::io::Codec::NONE);
    } catch (const std::exception& e) {
      throw_io(std::string("cannot write NanoVDB file: ") + e.what(), {nvdb.string(), {}, {}});
    }
    out.bytes = std::filesystem::file_size(tmp);
  });
  return out;
}

}  // namespace lblight
