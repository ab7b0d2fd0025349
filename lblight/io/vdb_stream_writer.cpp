#include "lblight/io/vdb_stream_writer.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <chrono>
#include <cstring>
#include <exception>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <string>

#include <openvdb/io/GridDescriptor.h>
#include <openvdb/io/io.h>
#include <openvdb/tools/Dense.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include "lblight/io/vdb_common.h"

namespace lblight {

namespace {

using namespace vdb_detail;

// io::Archive::write(os, grids, ...) split into its header and per-grid halves. writeHeader and
// writeGrid are protected members meant for Archive's own subclasses (File, Stream); this is one.
class IncrementalArchive : public openvdb::io::Archive {
 public:
  void begin(std::ostream& os, int grid_count, const openvdb::MetaMap& meta) {
    openvdb::io::StreamMetadata::Ptr sm = openvdb::io::getStreamMetadataPtr(os);
    if (!sm) {
      stream_metadata_.reset(new openvdb::io::StreamMetadata);
      openvdb::io::setStreamMetadataPtr(os, stream_metadata_, /*transfer=*/false);
    }
    openvdb::io::setDataCompression(os, compression());
    openvdb::io::setWriteGridStatsMetadata(os, isGridStatsMetadataEnabled());
    writeHeader(os, /*seekable=*/true);
    meta.writeMeta(os);
    const std::int32_t count = grid_count;
    os.write(reinterpret_cast<const char*>(&count), sizeof count);
  }

  // The bytes Archive::write appends for `grid`, as if the stream were at position 0, with the
  // stream state begin() sets up (fresh per grid, as Archive::write restores it between grids),
  // and the offset of the descriptor's three stream positions in them (see relocate).
  std::string serialize(const openvdb::GridBase::ConstPtr& grid, std::size_t& positions_at) const {
    std::ostringstream os(std::ios::out | std::ios::binary);
    openvdb::io::StreamMetadata::Ptr sm(new openvdb::io::StreamMetadata);
    openvdb::io::setStreamMetadataPtr(os, sm, /*transfer=*/false);
    openvdb::io::setDataCompression(os, compression());
    openvdb::io::setWriteGridStatsMetadata(os, isGridStatsMetadataEnabled());
    openvdb::io::GridDescriptor gd(grid->getName(), grid->type(), grid->saveFloatAsHalf());
    std::ostringstream header(std::ios::out | std::ios::binary);
    gd.writeHeader(header);
    positions_at = static_cast<std::size_t>(header.tellp());
    writeGrid(gd, grid, os, /*seekable=*/true);
    return std::move(os).str();
  }

  // A serialized grid's descriptor holds three absolute stream positions (grid, blocks, end);
  // moving the bytes to `base` in the file moves those by `base`.
  static void relocate(std::string& bytes, std::size_t positions_at, std::int64_t base) {
    for (int k = 0; k < 3; ++k) {
      std::int64_t pos;
      char* at = bytes.data() + positions_at + k * sizeof pos;
      std::memcpy(&pos, at, sizeof pos);
      pos += base;
      std::memcpy(at, &pos, sizeof pos);
    }
  }

 private:
  openvdb::io::StreamMetadata::Ptr stream_metadata_;
};

openvdb::GridBase::Ptr make_grid(const DenseFrame& frame, const DenseGridOut& spec) {
  const openvdb::CoordBBox bbox = frame_bbox(frame);
  openvdb::GridBase::Ptr g;
  if (spec.scalar) {
    auto fg = openvdb::FloatGrid::create(0.0f);
    openvdb::tools::Dense<const float, openvdb::tools::LayoutXYZ> dense(bbox, spec.scalar->data());
    openvdb::tools::copyFromDense(dense, *fg, 0.0f);
    if (spec.fog_volume) fg->setGridClass(openvdb::GRID_FOG_VOLUME);
    g = fg;
  } else {
    auto vg = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
    std::vector<openvdb::Vec3s> interleaved(frame.dims.count());
    const auto& rgb = *spec.rgb;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, interleaved.size(), 1 << 16), [&](const auto& r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) interleaved[i] = openvdb::Vec3s(rgb[0][i], rgb[1][i], rgb[2][i]);
    });
    openvdb::tools::Dense<const openvdb::Vec3s, openvdb::tools::LayoutXYZ> dense(bbox, interleaved.data());
    openvdb::tools::copyFromDense(dense, *vg, openvdb::Vec3s(0.0f));
    vg->setVectorType(openvdb::VEC_INVARIANT);
    g = vg;
  }
  g->setSaveFloatAsHalf(spec.half);
  g->setName(spec.name);
  set_metadata(*g, spec.metadata);
  return g;
}

}  // namespace

struct VdbStreamWriter::Impl {
  std::filesystem::path file;
  DenseFrame frame;
  openvdb::math::Transform::Ptr transform;
  std::ofstream os;
  IncrementalArchive archive;
  int announced = 0, added = 0;
  std::set<std::string> names;
  bool closed = false;

  // Grids compressing on TBB threads (parallel > 1), and those done but waiting for an earlier one.
  // Tasks are queued and waited for inside one arena: a thread waiting on a task_group runs only
  // tasks it can reach, and close() may come from another thread than add() (with one CPU TBB
  // has no worker threads, so tasks out of reach would never run).
  int parallel = 1;
  tbb::task_arena arena;
  tbb::task_group group;
  std::mutex mutex;  // guards everything below and the stream
  int in_flight = 0, written = 0;
  double compress_seconds = 0;  // serialising, summed over the threads that did it
  struct Serialized {
    std::string bytes;
    std::size_t positions_at = 0;
  };
  std::map<int, Serialized> done;  // by add() order
  std::exception_ptr failure;

  Location where() const { return {file.string(), {}, {}}; }
  void check_stream(const std::string& what) {
    if (!os) throw_io("cannot write VDB file (" + what + "; disk full?)", where());
  }
  // Appends the grids that are next in order (mutex held).
  void append_ready() {
    for (auto it = done.find(written); it != done.end(); it = done.find(written)) {
      Serialized& g = it->second;
      IncrementalArchive::relocate(g.bytes, g.positions_at, static_cast<std::int64_t>(os.tellp()));
      os.write(g.bytes.data(), static_cast<std::streamsize>(g.bytes.size()));
      check_stream("grid " + std::to_string(written));
      done.erase(it);
      ++written;
    }
  }
  void wait_for_grids() {
    arena.execute([this] { group.wait(); });
    std::lock_guard<std::mutex> lock(mutex);
    if (failure) std::rethrow_exception(failure);
  }
  void fail(std::exception_ptr e) {  // sticky: later grids would land at wrong places
    std::lock_guard<std::mutex> lock(mutex);
    if (!failure) failure = e;
  }
};

VdbStreamWriter::VdbStreamWriter(const std::filesystem::path& file, const DenseFrame& frame, int grid_count,
                                 const nlohmann::json& file_metadata, int parallel_grids)
    : impl_(std::make_unique<Impl>()) {
  ensure_initialized();
  frame.check("the lattice of " + file.string(), {file.string(), {}, {}});  // before any dense copy
  Impl& s = *impl_;
  s.parallel = std::max(1, parallel_grids);
  s.file = file;
  s.frame = frame;
  s.transform = to_vdb_transform(frame.index_to_world);
  s.announced = grid_count;
  s.os.open(file, std::ios::out | std::ios::binary | std::ios::trunc);
  if (!s.os) throw_io(std::string("cannot create VDB file: ") + std::strerror(errno), s.where());
  openvdb::MetaMap meta;
  set_metadata(meta, file_metadata);
  try {
    s.archive.begin(s.os, grid_count, meta);
  } catch (const openvdb::Exception& e) {
    throw_io(std::string("cannot write VDB file: ") + e.what(), s.where());
  }
  s.check_stream("header");
}

VdbStreamWriter::~VdbStreamWriter() {
  try {
    impl_->arena.execute([this] { impl_->group.wait(); });  // tasks refer to impl_
  } catch (...) {
  }
}

void VdbStreamWriter::add(const DenseGridOut& spec) {
  Impl& s = *impl_;
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    if (s.failure) std::rethrow_exception(s.failure);
  }
  if (s.closed || s.added >= s.announced)
    throw Error(ErrorCategory::Internal, "VDB writer: more grids than announced for " + s.file.string());
  if (!s.names.insert(spec.name).second)
    throw Error(ErrorCategory::Internal, "VDB writer: grid name '" + spec.name + "' given twice");
  // Isolated: while waiting inside its parallel loops, this thread must not pick up another
  // grid's compression task (add() would then return only after that whole grid is written).
  openvdb::GridBase::Ptr g;
  tbb::this_task_arena::isolate([&] { g = make_grid(s.frame, spec); });
  g->setTransform(s.transform->copy());
  const int seq = s.added++;
  // One grid at a time, or with every slot busy: this thread compresses its grid itself (rather
  // than wait idle) and add() returns once it is in the file, or queued behind earlier ones.
  bool here = s.parallel == 1;
  if (!here) {
    std::lock_guard<std::mutex> lock(s.mutex);
    here = s.in_flight >= s.parallel;
    if (!here) ++s.in_flight;
  }
  auto compress = [&s, g = openvdb::GridBase::ConstPtr(g), seq, here] {
    Impl::Serialized out;
    std::exception_ptr failure;
    const auto t0 = std::chrono::steady_clock::now();
    try {
      try {
        out.bytes = s.archive.serialize(g, out.positions_at);
      } catch (const openvdb::Exception& e) {
        throw_io(std::string("cannot write VDB file: ") + e.what(), s.where());
      }
    } catch (...) {
      failure = std::current_exception();
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::lock_guard<std::mutex> lock(s.mutex);
    s.compress_seconds += seconds;
    try {
      if (!failure) {
        s.done.emplace(seq, std::move(out));
        s.append_ready();
      }
    } catch (...) {
      failure = std::current_exception();
    }
    if (failure && !s.failure) s.failure = failure;
    if (!here) --s.in_flight;
  };
  if (here) {
    tbb::this_task_arena::isolate(compress);  // not the queued grids: add() returns after this one
    std::lock_guard<std::mutex> lock(s.mutex);
    if (s.failure) std::rethrow_exception(s.failure);
  } else {
    try {
      s.arena.execute([&] { s.group.run(std::move(compress)); });
    } catch (...) {  // not queued: the file cannot be completed
      s.fail(std::current_exception());
      throw;
    }
  }
}

void VdbStreamWriter::close() {
  Impl& s = *impl_;
  if (s.closed) return;
  s.wait_for_grids();
  if (s.written != s.added)
    throw Error(ErrorCategory::Internal, "VDB writer: " + std::to_string(s.added - s.written) +
                                             " grid(s) not appended to " + s.file.string());
  if (s.added != s.announced)
    throw Error(ErrorCategory::Internal, "VDB writer: " + std::to_string(s.added) + " of " +
                                             std::to_string(s.announced) + " announced grids written to " +
                                             s.file.string());
  s.os.close();
  s.closed = true;
  if (s.os.fail()) throw_io("cannot write VDB file (disk full?)", s.where());
}

std::uint64_t VdbStreamWriter::bytes_written() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->closed ? std::filesystem::file_size(impl_->file) : static_cast<std::uint64_t>(impl_->os.tellp());
}

double VdbStreamWriter::compress_seconds() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->compress_seconds;
}

int VdbStreamWriter::grids_written() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->written;
}

double half_rounding_error(const std::array<std::vector<float>, 3>& rgb) {
  double err = 0, peak = 0;
  for (const auto& c : rgb)
    for (float v : c) {
      err = std::max(err, std::fabs(static_cast<double>(static_cast<float>(openvdb::math::half(v))) - v));
      peak = std::max(peak, std::fabs(static_cast<double>(v)));
    }
  return peak > 0 ? err / peak : 0.0;
}

void write_vdb(const std::filesystem::path& file, const DenseFrame& frame, const std::vector<DenseGridOut>& grids,
               const nlohmann::json& file_metadata) {
  VdbStreamWriter w(file, frame, static_cast<int>(grids.size()), file_metadata);
  for (const DenseGridOut& g : grids) w.add(g);
  w.close();
}

}  // namespace lblight
