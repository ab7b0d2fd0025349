#include "lblight/io/vdb_stream_writer.h"

#include <fstream>
#include <set>
#include <string>

#include <openvdb/io/GridDescriptor.h>
#include <openvdb/io/io.h>
#include <openvdb/tools/Dense.h>
#include <tbb/parallel_for.h>

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

  void add(std::ostream& os, const openvdb::GridBase::ConstPtr& grid) {
    openvdb::io::GridDescriptor gd(grid->getName(), grid->type(), grid->saveFloatAsHalf());
    writeGrid(gd, grid, os, /*seekable=*/true);
    // Mask compression is chosen per grid; the next grid starts from the file's settings.
    openvdb::io::setDataCompression(os, compression());
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
  int announced = 0, written = 0;
  std::set<std::string> names;
  bool closed = false;

  Location where() const { return {file.string(), {}, {}}; }
  void check_stream(const char* what) {
    if (!os) throw_io(std::string("cannot write VDB file (") + what + "; disk full?)", where());
  }
};

VdbStreamWriter::VdbStreamWriter(const std::filesystem::path& file, const DenseFrame& frame, int grid_count,
                                 const nlohmann::json& file_metadata)
    : impl_(std::make_unique<Impl>()) {
  ensure_initialized();
  Impl& s = *impl_;
  s.file = file;
  s.frame = frame;
  s.transform = to_vdb_transform(frame.index_to_world);
  s.announced = grid_count;
  s.os.open(file, std::ios::out | std::ios::binary | std::ios::trunc);
  if (!s.os) throw_io("cannot create VDB file", s.where());
  openvdb::MetaMap meta;
  set_metadata(meta, file_metadata);
  try {
    s.archive.begin(s.os, grid_count, meta);
  } catch (const openvdb::Exception& e) {
    throw_io(std::string("cannot write VDB file: ") + e.what(), s.where());
  }
  s.check_stream("header");
}

VdbStreamWriter::~VdbStreamWriter() = default;

void VdbStreamWriter::add(const DenseGridOut& spec) {
  Impl& s = *impl_;
  if (s.closed || s.written >= s.announced)
    throw Error(ErrorCategory::Internal, "VDB writer: more grids than announced for " + s.file.string());
  if (!s.names.insert(spec.name).second)
    throw Error(ErrorCategory::Internal, "VDB writer: grid name '" + spec.name + "' given twice");
  openvdb::GridBase::Ptr g = make_grid(s.frame, spec);
  g->setTransform(s.transform->copy());
  try {
    s.archive.add(s.os, g);
  } catch (const openvdb::Exception& e) {
    throw_io(std::string("cannot write VDB file: ") + e.what(), s.where());
  }
  s.check_stream(spec.name.c_str());
  ++s.written;
}

void VdbStreamWriter::close() {
  Impl& s = *impl_;
  if (s.closed) return;
  if (s.written != s.announced)
    throw Error(ErrorCategory::Internal, "VDB writer: " + std::to_string(s.written) + " of " +
                                             std::to_string(s.announced) + " announced grids written to " +
                                             s.file.string());
  s.os.close();
  s.closed = true;
  if (s.os.fail()) throw_io("cannot write VDB file (disk full?)", s.where());
}

std::uint64_t VdbStreamWriter::bytes_written() const {
  auto& os = impl_->os;
  return impl_->closed ? std::filesystem::file_size(impl_->file) : static_cast<std::uint64_t>(os.tellp());
}

int VdbStreamWriter::grids_written() const { return impl_->written; }

void write_vdb(const std::filesystem::path& file, const DenseFrame& frame, const std::vector<DenseGridOut>& grids,
               const nlohmann::json& file_metadata) {
  VdbStreamWriter w(file, frame, static_cast<int>(grids.size()), file_metadata);
  for (const DenseGridOut& g : grids) w.add(g);
  w.close();
}

}  // namespace lblight
