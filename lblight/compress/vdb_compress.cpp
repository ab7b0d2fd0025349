#include "lblight/compress/vdb_compress.h"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "lblight/core/error.h"
#include "lblight/core/input_file.h"
#include "lblight/core/system_info.h"
#include "lblight/core/version.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/vdb_io.h"
#include "readers/lbh/lbh_reader.h"

namespace lblight {

LbhFileContents compress_vdb(const std::filesystem::path& file, const LbhSettings& threshold,
                             const std::vector<std::string>& wanted, int threads) {
  const Location where{file.string(), {}, {}};
  const nlohmann::json info = inspect_vdb(file);
  std::vector<std::string> names;
  for (const auto& g : info["grids"])
    if (g["type"] == "vec3s") names.push_back(g["name"].get<std::string>());
  std::sort(names.begin(), names.end());
  if (!wanted.empty()) {
    for (const std::string& w : wanted)
      if (std::find(names.begin(), names.end(), w) == names.end()) {
        std::string list;
        for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
        throw_invalid("no Vec3f grid named '" + w + "'; Vec3f grids in the file: " + (list.empty() ? "(none)" : list),
                      where);
      }
    names = wanted;
  }
  // A .vdb may hold two grids of one name (OpenVDB would then read the first twice); an .lbh
  // names each solution once.
  std::vector<std::string> sorted = names;
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t i = 1; i < sorted.size(); ++i)
    if (sorted[i] == sorted[i - 1])
      throw_invalid("more than one Vec3f grid named '" + sorted[i] + "' (in the file or in --grids); allowed: each "
                    "name once (an .lbh names each solution once)",
                    where);
  if (names.empty()) throw_invalid("the file holds no Vec3f grid to compress (expected B00..B18 or light)", where);

  LbhFileContents out;
  for (std::size_t i = 0; i < names.size(); ++i) {
    const DenseGridIn g = read_vdb_grid_dense(file, names[i]);
    if (g.type != "vec3s") throw_invalid("grid '" + names[i] + "' is not a Vec3f grid", where);
    if (const char* why = lbh::name_problem(names[i].data(), names[i].size()))
      throw_invalid("grid name '" + names[i] + "' " + why + "; allowed: 1..15 printable ASCII characters (the .lbh "
                    "format's rule)",
                    where);
    const DenseFrame& frame = g.frame;
    if (i == 0) out.frame = frame;
    else if (!(frame == out.frame))
      throw_invalid("grid '" + names[i] + "' does not share the lattice (dims, index box, transform) of grid '" +
                        names[0] + "'; one .lbh holds solutions on one lattice",
                    where);
    LbhSolutionIn in;
    in.name = names[i];
    in.rgb = &g.values;
    // A base-solution grid written by another tool: Bnn is index nn (-1: not such a name).
    const std::string& n = names[i];
    const int named = n.size() == 3 && n[0] == 'B' && std::isdigit(static_cast<unsigned char>(n[1])) &&
                              std::isdigit(static_cast<unsigned char>(n[2]))
                          ? std::stoi(n.substr(1))
                          : -1;
    if (g.metadata.contains("lblight_solution") && g.metadata["lblight_solution"].is_number_integer())
      in.index = g.metadata["lblight_solution"].get<int>();
    else
      in.index = named;
    if (in.index < -1 || in.index > 18) in.index = -1;
    // A grid whose tags disagree (its name, its solution index, its direction) would decompress
    // and relight as another solution: refuse it here, as the reader refuses such a file.
    const int m = in.index < 0 ? 0 : in.index;
    const std::array<int, 3> want{lbh::lattice_cx(m), lbh::lattice_cy(m), lbh::lattice_cz(m)};
    in.direction = want;
    if (g.metadata.contains("lblight_direction") && g.metadata["lblight_direction"].is_array() &&
        g.metadata["lblight_direction"].size() == 3)
      for (int a = 0; a < 3; ++a) in.direction[a] = std::clamp(g.metadata["lblight_direction"][a].get<int>(), -1, 1);
    if (in.direction != want)
      throw_invalid("grid '" + n + "': lblight_direction (" + std::to_string(in.direction[0]) + ", " +
                        std::to_string(in.direction[1]) + ", " + std::to_string(in.direction[2]) +
                        ") is not the direction of solution " + std::to_string(in.index) + "; allowed: (" +
                        std::to_string(want[0]) + ", " + std::to_string(want[1]) + ", " + std::to_string(want[2]) + ")",
                    {file.string(), {}, {}});
    if (in.index >= 0 && named >= 0 && named != in.index)
      throw_invalid("grid '" + n + "' is tagged as base solution " + std::to_string(in.index) +
                        " (lblight_solution); a grid named Bnn must hold solution nn",
                    {file.string(), {}, {}});
    try {
      out.solutions.push_back(encode_lbh_solution(frame, in, threshold, threads));
    } catch (const Error& e) {  // name the file the values came from
      if (e.category() != ErrorCategory::InvalidInput) throw;
      throw_invalid("grid '" + in.name + "': " + e.message(), {file.string(), {}, e.where().voxel});
    }
  }
  return out;
}

void decompress_lbh(const std::filesystem::path& lbh_path, const std::filesystem::path& vdb) {
  lbh::Stream s;
  check_host_memory(static_cast<double>(check_regular_file(lbh_path, ".lbh file")) * 2.0,
                    "reading " + lbh_path.string(), "decompress a smaller file", {lbh_path.string(), {}, {}});
  if (const lbh::Status st = s.open_file(lbh_path.string()); st != lbh::Status::Ok) {
    if (st == lbh::Status::IoError) throw_io(s.error());
    throw_invalid(s.error());
  }
  const lbh::Header& h = s.header();
  DenseFrame frame;
  frame.dims = {h.dims[0], h.dims[1], h.dims[2]};
  frame.index_min = {h.index_min[0], h.index_min[1], h.index_min[2]};
  std::copy(h.index_to_world, h.index_to_world + 16, frame.index_to_world.begin());
  const Location where{lbh_path.string(), {}, {}};
  frame.check("the lattice of the stream", where);
  // every solution densely, plus one decoded in interleaved form, and OpenVDB's copy of one
  check_host_memory(static_cast<double>(frame.dims.count()) * 12.0 * static_cast<double>(s.solution_count() + 2),
                    "decompressing " + std::to_string(s.solution_count()) + " solution(s) of a " +
                        std::to_string(frame.dims.nx) + "x" + std::to_string(frame.dims.ny) + "x" +
                        std::to_string(frame.dims.nz) + " lattice",
                    "decompress on a machine with more memory", where);
  const nlohmann::json lattice_box = {{"lblight_lattice_min", frame.index_min},
                                      {"lblight_lattice_dims", {frame.dims.nx, frame.dims.ny, frame.dims.nz}}};

  std::vector<std::array<std::vector<float>, 3>> values(s.solution_count());
  std::vector<DenseGridOut> grids;
  for (std::size_t slot = 0; slot < s.solution_count(); ++slot) {
    const lbh::SolutionInfo& info = s.info(slot);
    const std::vector<float> rgb = s.decode_all(slot);
    for (int c = 0; c < 3; ++c) {
      values[slot][c].resize(frame.dims.count());
      for (std::size_t i = 0; i < frame.dims.count(); ++i) values[slot][c][i] = rgb[3 * i + c];
    }
    DenseGridOut g;
    g.name = info.name;
    g.rgb = &values[slot];
    g.metadata = lattice_box;
    if (info.index >= 0) g.metadata["lblight_solution"] = info.index;
    g.metadata["lblight_direction"] = {info.direction[0], info.direction[1], info.direction[2]};
    g.metadata["lblight_lbh_threshold"] = static_cast<double>(info.threshold);
    grids.push_back(g);
  }
  const nlohmann::json file_meta = {{"creator", std::string("lblight ") + kVersion + " decompress"},
                                    {"lblight_source", lbh_path.filename().string()}};
  write_file_atomically(vdb, [&](const std::filesystem::path& tmp) { write_vdb(tmp, frame, grids, file_meta); });
}

}  // namespace lblight
