#include "lblight/io/vdb_io.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/GridDescriptor.h>
#if LBLIGHT_SILENCE_OPENVDB
#include <log4cplus/logger.h>
#endif
#include <openvdb/tools/Dense.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <mutex>
#include <set>
#include <tuple>
#include <utility>

// lblight's dense arrays have x fastest: OpenVDB calls that LayoutXYZ (offset i + j*mY + k*mZ),
// not its default LayoutZYX (z fastest).

#include "lblight/core/input_file.h"
#include "lblight/core/isolated_call.h"
#include "lblight/core/system_info.h"
#include "lblight/io/vdb_common.h"

namespace lblight {

namespace vdb_detail {

void ensure_initialized() {
  static std::once_flag once;
  std::call_once(once, [] {
    openvdb::initialize();
    // OpenVDB would print its own (coloured) warnings about the files it reads; lblight turns
    // what matters into its own errors, naming the file. Debian's OpenVDB logs through log4cplus
    // (its headers: liblog4cplus-dev); without them its warnings still show.
#if LBLIGHT_SILENCE_OPENVDB
    log4cplus::Logger::getInstance(LOG4CPLUS_TEXT("openvdb")).setLogLevel(log4cplus::FATAL_LOG_LEVEL);
#endif
  });
}

openvdb::math::Transform::Ptr to_vdb_transform(const std::array<double, 16>& m) {
  openvdb::math::Mat4d mat;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) mat(c, r) = m[static_cast<std::size_t>(r * 4 + c)];
  return openvdb::math::Transform::createLinearTransform(mat);
}

void set_metadata(openvdb::MetaMap& meta, const nlohmann::json& j) {
  for (auto it = j.begin(); it != j.end(); ++it) {
    const auto& v = it.value();
    const std::string& key = it.key();
    if (v.is_boolean()) meta.insertMeta(key, openvdb::BoolMetadata(v.get<bool>()));
    else if (v.is_number_integer()) meta.insertMeta(key, openvdb::Int64Metadata(v.get<long long>()));
    else if (v.is_number()) {
      const double d = v.get<double>();
      // Infinity (an unknown error estimate) is written as -1 so every reader can parse it.
      meta.insertMeta(key, openvdb::DoubleMetadata(std::isfinite(d) ? d : -1.0));
    } else if (v.is_string()) meta.insertMeta(key, openvdb::StringMetadata(v.get<std::string>()));
    else if (v.is_array() && v.size() == 3 && v[0].is_number_integer())
      meta.insertMeta(key, openvdb::Vec3IMetadata(openvdb::Vec3i(v[0].get<int>(), v[1].get<int>(), v[2].get<int>())));
    else meta.insertMeta(key, openvdb::StringMetadata(v.dump()));
  }
}

openvdb::CoordBBox frame_bbox(const DenseFrame& f) {
  const openvdb::Coord lo(f.index_min[0], f.index_min[1], f.index_min[2]);
  return {lo, lo.offsetBy(f.dims.nx - 1, f.dims.ny - 1, f.dims.nz - 1)};
}

}  // namespace vdb_detail

namespace {

using vdb_detail::ensure_initialized;

// The dims of an OpenVDB box, checked (check_index_box) before any dense array or copy is made:
// near 2^31 both the dims and OpenVDB's own dense copy overflow.
Dims checked_dims(const openvdb::CoordBBox& bbox, const std::string& what, const Location& where) {
  const std::array<std::int64_t, 3> lo{bbox.min().x(), bbox.min().y(), bbox.min().z()};
  const std::array<std::int64_t, 3> hi{bbox.max().x(), bbox.max().y(), bbox.max().z()};
  check_index_box(lo, hi, what, where);
  return {static_cast<int>(hi[0] - lo[0] + 1), static_cast<int>(hi[1] - lo[1] + 1), static_cast<int>(hi[2] - lo[2] + 1)};
}

std::array<double, 16> from_vdb_transform(const openvdb::math::Transform& t, const std::string& what,
                                          const Location& where) {
  if (!t.isLinear()) throw_invalid(what + " has a non-linear (frustum) transform; lblight needs a linear one", where);
  const openvdb::math::Mat4d mat = t.baseMap()->getAffineMap()->getMat4();
  std::array<double, 16> m{};
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m[static_cast<std::size_t>(r * 4 + c)] = mat(c, r);
  return m;
}

// Walks the length-prefixed fields OpenVDB is about to read at `is` without reading them, and
// refuses a length that runs past the end of the file: OpenVDB allocates each field's claimed
// size before reading it, gigabytes for one damaged length. `strings`: uint32-length strings;
// `meta`: a MetaMap (int32 count, then name, type and a uint32-sized value per entry).
void check_lengths(std::istream& is, std::int64_t file_size, int strings, bool meta, const Location& where) {
  const std::streampos start = is.tellg();
  // Reads a length and returns it (the field skipped), or with `keep`, the field itself.
  auto take = [&](const char* what, std::string* keep = nullptr) {
    std::uint32_t n = 0;
    is.read(reinterpret_cast<char*>(&n), sizeof n);
    const std::int64_t at = static_cast<std::int64_t>(is.tellg());
    if (!is || at < 0 || static_cast<std::int64_t>(n) > file_size - at)
      throw_invalid(std::string("not a readable OpenVDB file (truncated or corrupt?): a ") + what + " of " +
                        std::to_string(n) + " bytes runs past the end of the file",
                    where);
    if (keep) {
      keep->assign(n, '\0');
      is.read(keep->data(), static_cast<std::streamsize>(n));
    } else {
      is.seekg(static_cast<std::streamoff>(n), std::ios::cur);
    }
    return n;
  };
  if (meta) {
    std::int32_t count = 0;
    is.read(reinterpret_cast<char*>(&count), sizeof count);
    if (!is || count < 0 || count > file_size)
      throw_invalid("not a readable OpenVDB file: it claims " + std::to_string(count) + " metadata entries", where);
    for (std::int32_t i = 0; i < count; ++i) {
      std::string name, type;
      take("metadata name", &name);
      take("metadata type", &type);
      const std::uint32_t bytes = take("metadata value");
      // A value of a fixed-size type is read at its type's size whatever the file says: a
      // mismatch would leave OpenVDB reading the rest of the file from the wrong offset.
      if (type != "string" && openvdb::Metadata::isRegisteredType(type)) {
        const openvdb::Index32 expected = openvdb::Metadata::createMetadata(type)->size();
        if (bytes != expected)
          throw_invalid("not a readable OpenVDB file (corrupt?): metadata '" + name + "' of type " + type + " has " +
                            std::to_string(bytes) + " bytes where its type has " + std::to_string(expected),
                        where);
      }
    }
  }
  for (int i = 0; i < strings; ++i) take("grid name or type");
  is.clear();
  is.seekg(start);
}

// Reads a .vdb's header and grid descriptors (as io::File::open does) and checks that every grid
// ends inside the file. OpenVDB itself lists a truncated file's grids as if whole, and reading
// one can take gigabytes from the garbage sizes at the cut. Archive's header reader is protected:
// this subclass exists to call it.
class CompletenessCheck : public openvdb::io::Archive {
 public:
  void run(const std::filesystem::path& path, const Location& where) {
    std::error_code ec;
    const auto size = static_cast<std::int64_t>(std::filesystem::file_size(path, ec));
    if (ec) throw_io("cannot read file: " + ec.message(), where);
    std::ifstream is(path, std::ios::binary);
    if (!is) throw_io("cannot open file", where);
    try {
      readHeader(is);
      if (!is) throw_invalid("not a readable OpenVDB file: the header is cut short", where);
      if (fileVersion() > openvdb::OPENVDB_FILE_VERSION)
        throw_invalid("written in OpenVDB file format " + std::to_string(fileVersion()) + ", newer than the " +
                          std::to_string(openvdb::OPENVDB_FILE_VERSION) + " this lblight reads",
                      where);
      setFormatVersion(is);
      setLibraryVersion(is);
      setDataCompression(is);
      if (!is) throw_invalid("not a readable OpenVDB file: the header is cut short", where);
      if (!inputHasGridOffsets()) return;  // very old files: nothing to check against
      check_lengths(is, size, 0, true, where);
      openvdb::MetaMap meta;
      meta.readMeta(is);
      const std::int32_t count = readGridCount(is);
      if (!is || count < 0 || count > 100000)
        throw_invalid("not a readable OpenVDB file: it claims " + std::to_string(count) + " grids", where);
      for (std::int32_t i = 0; i < count; ++i) {
        check_lengths(is, size, fileVersion() >= openvdb::OPENVDB_FILE_VERSION_GRID_INSTANCING ? 3 : 2, false, where);
        openvdb::io::GridDescriptor gd;
        gd.read(is);
        if (!is || gd.getEndPos() > size || gd.getEndPos() < gd.getGridPos() || gd.getGridPos() < 0 ||
            gd.getBlockPos() < gd.getGridPos() || gd.getBlockPos() > gd.getEndPos())
          throw_invalid("the file is truncated or corrupt: grid '" + gd.gridName() + "' ends at byte " +
                            std::to_string(gd.getEndPos()) + " of a " + std::to_string(size) + "-byte file",
                        where);
        names_.push_back(gd.gridName());
        is.seekg(gd.getEndPos());
      }
    } catch (const Error&) {
      throw;
    } catch (const std::exception& e) {  // OpenVDB's own, and allocations a corrupt size asked for
      const bool size = dynamic_cast<const std::bad_alloc*>(&e) || dynamic_cast<const std::length_error*>(&e);
      throw_invalid(std::string("not a readable OpenVDB file (truncated or corrupt?): ") +
                        (size ? "it asks for an impossible amount of memory" : e.what()),
                    where);
    }
    if (!is) throw_invalid("not a readable OpenVDB file (truncated or corrupt?)", where);
  }
  const std::vector<std::string>& names() const { return names_; }

 private:
  std::vector<std::string> names_;  // of every grid, in file order
};

// The grid names of a complete file, in file order.
std::vector<std::string> check_complete(const std::filesystem::path& path, const Location& where) {
  CompletenessCheck c;
  c.run(path, where);
  return c.names();
}

// Every grid of `path` read once in a child process (run_isolated) before this process reads
// any: OpenVDB crashes, or allocates without end, on some corrupt files that pass the
// completeness check, and that must be an input error here, not a crash. Reading and walking
// the leaves are serial (no TBB in a forked child). Once per file and size.
void probe_readable(const std::filesystem::path& path, const Location& where, const RunContext& ctx) {
  static std::mutex mutex;
  // A file is the same file while its path, size and modification time are (a rewrite of the
  // same size is probed again).
  static std::set<std::tuple<std::string, std::uintmax_t, std::int64_t>> probed;
  std::error_code ec;
  const auto mtime = std::filesystem::last_write_time(path, ec).time_since_epoch().count();
  const auto key = std::make_tuple(std::filesystem::absolute(path, ec).string(), std::filesystem::file_size(path, ec),
                                   static_cast<std::int64_t>(mtime));
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (probed.count(key)) return;
  }
  // What reading may take: what this process may use, but no more than 512 MiB + 256 x the file's
  // size (far beyond any compression ratio): a damaged length field must not make a small file
  // take gigabytes, here or in this process after the probe.
  const MemoryLimit limit = host_memory_limit();
  const double proportional = 512.0 * 1048576.0 + 256.0 * static_cast<double>(std::get<1>(key));
  const std::size_t budget =
      limit.bytes > 0 ? static_cast<std::size_t>(std::min<double>(static_cast<double>(limit.bytes), proportional))
                      : static_cast<std::size_t>(proportional);
  // And how long: 30 s plus a second per MiB (reading runs at hundreds of MiB/s; a corrupt file
  // can make OpenVDB loop for ever).
  const double timeout = 30.0 + static_cast<double>(std::get<1>(key)) / 1048576.0;
  const auto read_all = [&] {
    openvdb::io::File file(path.string());
    file.open(/*delayLoad=*/false);
    for (auto it = file.beginName(); it != file.endName(); ++it) {
      try {
        const openvdb::GridBase::Ptr g = file.readGrid(it.gridName());
        g->apply<openvdb::GridTypes>([](const auto& grid) {
          std::size_t leaves = 0;
          for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf) leaves += leaf->onVoxelCount() > 0;
          (void)leaves;
        });
      } catch (const std::exception& e) {
        throw std::runtime_error("grid '" + it.gridName() + "' cannot be read (damaged data?): " + e.what());
      }
    }
    file.close();
  };
  IsolatedOutcome o = run_isolated(read_all, timeout, ctx, budget);
  // A child forked while another thread held a lock (the allocator's, under a sanitizer) can hang
  // for no fault of the file: one more try before the file is blamed.
  if (o.kind == IsolatedOutcome::Kind::TimedOut) o = run_isolated(read_all, timeout, ctx, budget);
  switch (o.kind) {
    case IsolatedOutcome::Kind::Ok: break;
    case IsolatedOutcome::Kind::Threw: throw_invalid(path.string() + ": " + o.message, where);
    case IsolatedOutcome::Kind::Crashed:
      throw_invalid("the grid data of " + path.string() + " cannot be read (damaged data?): OpenVDB failed reading it (" +
                        o.message + "; a corrupt file, or one that needs more than " + gib(static_cast<double>(budget)) +
                        " of memory to read)",
                    where);
    case IsolatedOutcome::Kind::TimedOut:
      throw_invalid("the grid data of " + path.string() + " cannot be read: reading it took more than " + o.message,
                    where);
    case IsolatedOutcome::Kind::Cancelled: throw Error(ErrorCategory::Cancelled, "interrupted", where);
  }
  std::lock_guard<std::mutex> lock(mutex);
  probed.insert(key);
}

nlohmann::json metadata_to_json(const openvdb::MetaMap& meta) {
  nlohmann::json j = nlohmann::json::object();
  for (auto it = meta.beginMeta(); it != meta.endMeta(); ++it) {
    const auto& m = it->second;
    const std::string type = m->typeName();
    if (type == "bool") j[it->first] = static_cast<const openvdb::BoolMetadata&>(*m).value();
    else if (type == "int32") j[it->first] = static_cast<const openvdb::Int32Metadata&>(*m).value();
    else if (type == "int64") j[it->first] = static_cast<const openvdb::Int64Metadata&>(*m).value();
    else if (type == "float") j[it->first] = static_cast<const openvdb::FloatMetadata&>(*m).value();
    else if (type == "double") j[it->first] = static_cast<const openvdb::DoubleMetadata&>(*m).value();
    else if (type == "string") j[it->first] = static_cast<const openvdb::StringMetadata&>(*m).value();
    else if (type == "vec3i") {
      const auto v = static_cast<const openvdb::Vec3IMetadata&>(*m).value();
      j[it->first] = {v[0], v[1], v[2]};
    } else j[it->first] = m->str();
  }
  return j;
}

}  // namespace

namespace vdb_detail {

openvdb::GridBase::Ptr open_grid(const std::filesystem::path& path, const std::string& name, const Location& where,
                                 const RunContext& ctx) {
  ensure_initialized();
  check_regular_file(path, "VDB file", where);
  const std::vector<std::string> names = check_complete(path, {path.string(), {}, {}});
  if (std::count(names.begin(), names.end(), name) > 1)
    throw_invalid("VDB file " + path.string() + " holds more than one grid named '" + name +
                      "'; allowed: one grid of each name (which one is meant is not clear)",
                  where);
  probe_readable(path, where, ctx);
  openvdb::io::File file(path.string());
  try {
    file.open(/*delayLoad=*/false);  // read every leaf in readGrid below, where errors are caught
  } catch (const openvdb::Exception& e) {
    throw_invalid("cannot open " + path.string() + " as OpenVDB: " + e.what(), where);
  }
  if (!file.hasGrid(name)) {
    std::string names;
    for (auto it = file.beginName(); it != file.endName(); ++it) names += (names.empty() ? "" : ", ") + it.gridName();
    file.close();
    throw_invalid("VDB file " + path.string() + " has no grid named '" + name + "'; grids in it: " +
                      (names.empty() ? "(none)" : names),
                  where);
  }
  // Damaged grid data (not its length: check_complete saw that) surfaces here as OpenVDB's or
  // Blosc's error; name the file and grid. Some damage crashes inside OpenVDB instead, which no
  // reader of the format can catch.
  openvdb::GridBase::Ptr g;
  try {
    g = file.readGrid(name);
  } catch (const std::exception& e) {
    throw_invalid("grid '" + name + "' of " + path.string() + " cannot be read (damaged data?): " + e.what(), where);
  }
  file.close();
  return g;
}

}  // namespace vdb_detail

using vdb_detail::open_grid;

ModelGrid read_vdb_density(const std::filesystem::path& file, const std::string& density_grid,
                            const std::string& wood_grid, const Location& where, const RunContext& ctx) {
  auto base = open_grid(file, density_grid, where, ctx);
  auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(base);
  if (!grid)
    throw_invalid("grid '" + density_grid + "' in " + file.string() + " is of type " + base->valueType() +
                      "; allowed: a float grid",
                  where);
  if (grid->background() != 0.0f)
    throw_invalid("grid '" + density_grid + "' in " + file.string() + " has background " +
                      std::to_string(grid->background()) + "; allowed: background 0 (empty space)",
                  where);
  const openvdb::CoordBBox bbox = grid->evalActiveVoxelBoundingBox();
  if (bbox.empty()) throw_invalid("grid '" + density_grid + "' in " + file.string() + " has no active voxels", where);
  ModelGrid g;
  g.dims = checked_dims(bbox, "the active voxels of grid '" + density_grid + "' in " + file.string(), where);
  check_host_memory(static_cast<double>(g.dims.count()) * 5.0,
                    "grid '" + density_grid + "' (" + std::to_string(g.dims.nx) + "x" + std::to_string(g.dims.ny) +
                        "x" + std::to_string(g.dims.nz) + " voxels as a dense density and material grid)",
                    "crop the grid to the medium or resample it coarser", where);
  g.index_min = {bbox.min().x(), bbox.min().y(), bbox.min().z()};
  g.index_to_world = from_vdb_transform(grid->transform(), "grid '" + density_grid + "'", where);
  g.density.assign(g.dims.count(), 0.0f);
  g.material.assign(g.dims.count(), kMaterialMedium);
  openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(bbox, g.density.data());
  openvdb::tools::copyToDense(*grid, dense);

  if (!wood_grid.empty()) {
    auto wbase = open_grid(file, wood_grid, where, ctx);
    if (wbase->transform() != grid->transform())
      throw_invalid("wood grid '" + wood_grid + "' does not share the transform of density grid '" + density_grid + "'",
                    where);
    std::vector<float> wood(g.dims.count(), 0.0f);
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> wdense(bbox, wood.data());
    if (auto wf = openvdb::gridPtrCast<openvdb::FloatGrid>(wbase)) openvdb::tools::copyToDense(*wf, wdense);
    else if (auto wi = openvdb::gridPtrCast<openvdb::Int32Grid>(wbase)) {
      std::vector<int> tmp(g.dims.count(), 0);
      openvdb::tools::Dense<int, openvdb::tools::LayoutXYZ> idense(bbox, tmp.data());
      openvdb::tools::copyToDense(*wi, idense);
      for (std::size_t i = 0; i < tmp.size(); ++i) wood[i] = static_cast<float>(tmp[i]);
    } else if (auto wb = openvdb::gridPtrCast<openvdb::BoolGrid>(wbase)) {
      for (auto it = wb->cbeginValueOn(); it; ++it) {
        const openvdb::Coord c = it.getCoord();
        if (bbox.isInside(c) && *it)
          wood[g.dims.index(c.x() - bbox.min().x(), c.y() - bbox.min().y(), c.z() - bbox.min().z())] = 1.0f;
      }
    } else {
      throw_invalid("wood grid '" + wood_grid + "' is of type " + wbase->valueType() +
                        "; allowed: float, int32 or bool",
                    where);
    }
    for (std::size_t i = 0; i < wood.size(); ++i)
      if (wood[i] > 0.5f) g.material[i] = kMaterialWood;
  }
  g.description = "grid '" + density_grid + "' of " + file.string();
  return g;
}

DenseGridIn read_vdb_grid_dense(const std::filesystem::path& file, const std::string& name, const RunContext& ctx) {
  const Location where{file.string(), {}, {}};
  auto base = open_grid(file, name, where, ctx);
  DenseGridIn out;
  out.name = name;
  out.type = base->valueType();
  out.metadata = metadata_to_json(*base);
  // lblight outputs record their lattice box; other files are read over their active voxels.
  openvdb::CoordBBox bbox;
  const std::string box_name = "the lattice box of grid '" + name + "'";
  if (out.metadata.contains("lblight_lattice_min") && out.metadata.contains("lblight_lattice_dims")) {
    const nlohmann::json& lo = out.metadata["lblight_lattice_min"];
    const nlohmann::json& d = out.metadata["lblight_lattice_dims"];
    const auto ints = [](const nlohmann::json& v) {
      return v.is_array() && v.size() == 3 && v[0].is_number_integer() && v[1].is_number_integer() &&
             v[2].is_number_integer();
    };
    if (!ints(lo) || !ints(d))
      throw_invalid("grid '" + name + "': metadata lblight_lattice_min and lblight_lattice_dims must be 3 integers each",
                    where);
    std::array<std::int64_t, 3> l{}, h{};
    for (int a = 0; a < 3; ++a) {
      l[a] = lo[a].get<std::int64_t>();
      h[a] = l[a] + d[a].get<std::int64_t>() - 1;
    }
    check_index_box(l, h, box_name + " (its lblight_lattice_min, lblight_lattice_dims metadata)", where);
    bbox = openvdb::CoordBBox(openvdb::Coord(static_cast<int>(l[0]), static_cast<int>(l[1]), static_cast<int>(l[2])),
                              openvdb::Coord(static_cast<int>(h[0]), static_cast<int>(h[1]), static_cast<int>(h[2])));
  } else {
    bbox = base->evalActiveVoxelBoundingBox();
    if (bbox.empty()) bbox = openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(0));
  }
  const Dims dims = checked_dims(bbox, box_name, where);
  const bool vec3 = out.type == "vec3s";
  check_host_memory(static_cast<double>(dims.count()) * (vec3 ? 24.0 : 4.0),
                    "grid '" + name + "' (" + std::to_string(dims.nx) + "x" + std::to_string(dims.ny) + "x" +
                        std::to_string(dims.nz) + " voxels, read densely)",
                    "read a smaller grid", where);
  out.frame.dims = dims;
  out.frame.index_min = {bbox.min().x(), bbox.min().y(), bbox.min().z()};
  out.frame.index_to_world = from_vdb_transform(base->transform(), "grid '" + name + "'", where);
  const std::size_t n = out.frame.dims.count();
  if (auto fg = openvdb::gridPtrCast<openvdb::FloatGrid>(base)) {
    out.values[0].assign(n, 0.0f);
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(bbox, out.values[0].data());
    openvdb::tools::copyToDense(*fg, dense);
  } else if (auto vg = openvdb::gridPtrCast<openvdb::Vec3SGrid>(base)) {
    std::vector<openvdb::Vec3s> tmp(n);
    openvdb::tools::Dense<openvdb::Vec3s, openvdb::tools::LayoutXYZ> dense(bbox, tmp.data());
    openvdb::tools::copyToDense(*vg, dense);
    for (int c = 0; c < 3; ++c) {
      out.values[c].resize(n);
      for (std::size_t i = 0; i < n; ++i) out.values[c][i] = tmp[i][c];
    }
  } else {
    throw_invalid("grid '" + name + "' is of type " + out.type + "; allowed: float or vec3s", where);
  }
  return out;
}

nlohmann::json inspect_vdb(const std::filesystem::path& file, const RunContext& ctx) {
  ensure_initialized();
  const Location where{file.string(), {}, {}};
  check_regular_file(file, "VDB file", where);
  check_complete(file, where);
  probe_readable(file, where, ctx);
  openvdb::io::File f(file.string());
  try {
    f.open(false);
  } catch (const openvdb::Exception& e) {
    throw_invalid(std::string("cannot open as OpenVDB: ") + e.what(), where);
  }
  nlohmann::json j;
  j["file"] = file.string();
  j["file_metadata"] = metadata_to_json(*f.getMetadata());
  j["grids"] = nlohmann::json::array();
  auto grids = f.readAllGridMetadata();
  for (const auto& g : *grids) {
    nlohmann::json e;
    e["name"] = g->getName();
    e["type"] = g->valueType();
    e["class"] = openvdb::GridBase::gridClassToString(g->getGridClass());
    const auto meta = metadata_to_json(*g);
    if (meta.contains("file_bbox_min") && meta.contains("file_bbox_max")) {
      const nlohmann::json &lo = meta["file_bbox_min"], &hi = meta["file_bbox_max"];
      // an empty grid's box is written as (INT_MAX..INT_MIN): say so rather than show it
      const bool empty = lo.is_array() && hi.is_array() && lo.size() == 3 && hi.size() == 3 &&
                         lo[0].is_number() && hi[0].is_number() && lo[0].get<double>() > hi[0].get<double>();
      e["bbox_min"] = empty ? nlohmann::json("empty") : lo;
      e["bbox_max"] = empty ? nlohmann::json("empty") : hi;
    }
    if (meta.contains("file_voxel_count")) e["active_voxels"] = meta["file_voxel_count"];
    const openvdb::Vec3d vs = g->voxelSize();
    e["voxel_size"] = {vs[0], vs[1], vs[2]};
    const openvdb::Vec3d origin = g->transform().indexToWorld(openvdb::Vec3d(0, 0, 0));
    e["index_origin_world"] = {origin[0], origin[1], origin[2]};
    nlohmann::json user = nlohmann::json::object();
    for (auto it = meta.begin(); it != meta.end(); ++it)
      if (it.key().rfind("file_", 0) != 0 && it.key() != "class" && it.key() != "name" && it.key() != "vector_type")
        user[it.key()] = it.value();
    e["metadata"] = user;
    j["grids"].push_back(e);
  }
  f.close();
  return j;
}

}  // namespace lblight
