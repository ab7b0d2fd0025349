// NanoVDB output (docs/output-format.md, "NanoVDB"): every grid of an lblight .vdb converted with
// NanoVDB's own converter (Debian's libnanovdb-dev) into one .nvdb that GPU renderers and
// real-time engines load as a flat buffer. NanoVDB keeps each grid's name, class, value type,
// voxel size and transform, not OpenVDB's free metadata: the materials and units stay in the .vdb.
#pragma once

#include <cstdint>
#include <filesystem>

#include "lblight/core/run_context.h"

namespace lblight {

struct NanoVdbWritten {
  int grids = 0;
  std::uint64_t bytes = 0;
};

// Converts `vdb` into `nvdb` (written whole or not at all), each grid checked with NanoVDB's own
// validator (GridValidator, as nanovdb_validate) before it is written. Error(InvalidInput) naming
// the file when it is not a readable OpenVDB file or holds a grid type NanoVDB cannot take.
NanoVdbWritten write_nanovdb(const std::filesystem::path& vdb, const std::filesystem::path& nvdb,
                             const RunContext& ctx = {});

}  // namespace lblight
