// Writes an OpenVDB file one grid at a time, so a bake can write each solution's grid while the
// next is being solved (on a GPU the host would otherwise sit idle, then write everything at the
// end). The bytes are those openvdb::io::File::write produces for the same grids in the same
// order (same header, compression and grid statistics), so every OpenVDB reader opens it.
//
// Compressing a grid (Blosc, serial inside OpenVDB) is most of the cost. With parallel_grids > 1,
// up to that many grids compress at once on TBB threads (and one more on the caller's thread when
// they are all busy), each into a buffer of its own whose stream positions are shifted to its
// place in the file when it is appended; grids still land in the order they were added. With 1
// (the default) add() compresses and writes before returning.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>

#include <nlohmann/json.hpp>

#include "lblight/io/vdb_io.h"

namespace lblight {

class VdbStreamWriter {
 public:
  // Creates `file` (a staging path; see output_dir.h) and writes the header, the file metadata
  // and the number of grids that will follow. Throws Error(Io) when the file cannot be created.
  VdbStreamWriter(const std::filesystem::path& file, const DenseFrame& frame, int grid_count,
                  const nlohmann::json& file_metadata, int parallel_grids = 1);
  VdbStreamWriter(const VdbStreamWriter&) = delete;
  VdbStreamWriter& operator=(const VdbStreamWriter&) = delete;
  ~VdbStreamWriter();  // waits for running grids; an unclosed file is left incomplete (the
                       // staging folder goes with it)

  // Converts the dense arrays to a sparse grid (zero background) and appends it. The arrays are
  // not used after add() returns. Names must be unique; at most grid_count grids. Rethrows an
  // earlier grid's write failure.
  void add(const DenseGridOut& grid);
  // Waits for the grids still compressing, flushes and closes; throws Error(Io) on a write
  // failure or when fewer grids were added than announced.
  void close();

  std::uint64_t bytes_written() const;
  int grids_written() const;  // appended to the file so far
  // Time spent compressing (serialising) grids so far, summed over the threads that did it:
  // with parallel_grids > 1 it is CPU time, not wall time.
  double compress_seconds() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lblight
