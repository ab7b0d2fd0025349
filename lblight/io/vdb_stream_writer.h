// Writes an OpenVDB file one grid at a time, so a bake can write each solution's grid while the
// next is being solved (on a GPU the host would otherwise sit idle, then write everything at the
// end). The bytes are those openvdb::io::File::write produces for the same grids in the same
// order (same header, compression and grid statistics), so every OpenVDB reader opens it.
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
                  const nlohmann::json& file_metadata);
  VdbStreamWriter(const VdbStreamWriter&) = delete;
  VdbStreamWriter& operator=(const VdbStreamWriter&) = delete;
  ~VdbStreamWriter();  // an unclosed file is left incomplete (the staging folder goes with it)

  // Converts the dense arrays to a sparse grid (zero background) and appends it. Names must be
  // unique; at most grid_count grids.
  void add(const DenseGridOut& grid);
  // Flushes and closes; throws Error(Io) on a write failure or when fewer grids were added than
  // announced.
  void close();

  std::uint64_t bytes_written() const;
  int grids_written() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lblight
