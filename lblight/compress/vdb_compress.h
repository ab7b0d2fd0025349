// .vdb <-> .lbh: compress the Vec3f grids of a bake output (or any .vdb with Vec3f grids on one
// lattice), and decode an .lbh back into a .vdb. Used by `lblight compress` / `decompress`.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "lblight/compress/lbh_writer.h"

namespace lblight {

struct LbhFileContents {
  DenseFrame frame;
  std::vector<LbhEncoded> solutions;
};

// Encodes the Vec3f grids named in `grids` (empty: every Vec3f grid, in name order) of `file`.
// All of them must share one lattice (dims, index box and transform). Solution index and
// direction come from the grids' lblight_solution / lblight_direction metadata; without it a grid
// named B00..B18 is that base solution (direction from docs/model.md sec. 1), others get -1 and 0.
LbhFileContents compress_vdb(const std::filesystem::path& file, const LbhSettings& threshold,
                             const std::vector<std::string>& grids = {}, int threads = 0);

// Decodes every solution of an .lbh into a Vec3f grid of the same name over the stored lattice
// and writes them to `vdb` (through a temporary name). Throws Error(InvalidInput) with the
// reader's message when the stream does not validate.
void decompress_lbh(const std::filesystem::path& lbh, const std::filesystem::path& vdb);

}  // namespace lblight
