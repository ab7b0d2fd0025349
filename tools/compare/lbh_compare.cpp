// Compares .lbh (Haar sub-block streams) with OpenVDB's own savings (half floats, zip, Blosc) and
// NanoVDB's grids (Vec3f, and per channel Fp4/Fp8/Fp16/FpN) on the Vec3f grids of a bake's .vdb:
// bytes, max and RMS error over the lattice nodes, and single-threaded trilinear sampling rates.
// Not part of the default build (needs libnanovdb-dev): cmake -DLBLIGHT_COMPARE_TOOLS=ON.
//   lbh_compare tree.vdb [--threshold 0.01] [--samples 2000000] [--json out.json]
#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>
#include <openvdb/tools/Interpolation.h>

#include <nanovdb/NanoVDB.h>
#include <nanovdb/util/OpenToNanoVDB.h>
#include <nanovdb/util/SampleFromVoxels.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include "lblight/compress/lbh_writer.h"
#include "lblight/io/vdb_io.h"
#include "readers/lbh/lbh_reader.h"

namespace fs = std::filesystem;
using namespace lblight;

namespace {

struct Solution {
  std::string name;
  DenseGridIn grid;
};

struct ErrStats {
  double max = 0, sum_sq = 0;
  std::size_t n = 0;
  void add(double e) {
    max = std::max(max, std::fabs(e));
    sum_sq += e * e;
    ++n;
  }
  double rms() const { return n ? std::sqrt(sum_sq / static_cast<double>(n)) : 0; }
};

openvdb::FloatGrid::Ptr channel_grid(const DenseGridIn& g, int c) {
  const auto& f = g.frame;
  const openvdb::CoordBBox box(openvdb::Coord(f.index_min[0], f.index_min[1], f.index_min[2]),
                               openvdb::Coord(f.index_min[0] + f.dims.nx - 1, f.index_min[1] + f.dims.ny - 1,
                                              f.index_min[2] + f.dims.nz - 1));
  auto grid = openvdb::FloatGrid::create(0.0f);
  openvdb::tools::Dense<const float, openvdb::tools::LayoutXYZ> dense(box, g.values[c].data());
  openvdb::tools::copyFromDense(dense, *grid, 0.0f);
  return grid;
}

// Bytes of a NanoVDB grid from its first leaf on: the leaves (plus any blind data), without the
// grid, tree, root and internal nodes in front of them (a fixed cost of ~0.3-0.5 MB per grid here).
std::size_t g_leaf_bytes = 0;
template <typename NanoBuildT>
std::size_t leaf_bytes(const nanovdb::GridHandle<nanovdb::HostBuffer>& h) {
  const auto* grid = h.template grid<NanoBuildT>();
  const auto* first = grid->tree().template getFirstNode<0>();
  return h.size() - static_cast<std::size_t>(reinterpret_cast<const char*>(first) - reinterpret_cast<const char*>(grid));
}

template <typename NanoBuildT>
nanovdb::GridHandle<nanovdb::HostBuffer> to_nano(const openvdb::FloatGrid& g, float tolerance = -1) {
  nanovdb::OpenToNanoVDB<float, NanoBuildT, nanovdb::AbsDiff> conv;
  if (tolerance >= 0) conv.oracle() = nanovdb::AbsDiff(tolerance);
  return conv(g, nanovdb::StatsMode::Disable, nanovdb::ChecksumMode::Disable, 0);
}

// Per-channel NanoVDB grids of one solution: bytes and errors over the lattice nodes.
template <typename NanoBuildT>
void nano_channels(const Solution& s, float tol, std::size_t& bytes, ErrStats& err,
                   std::vector<nanovdb::GridHandle<nanovdb::HostBuffer>>* keep = nullptr) {
  const auto& f = s.grid.frame;
  for (int c = 0; c < 3; ++c) {
    auto h = to_nano<NanoBuildT>(*channel_grid(s.grid, c), tol);
    bytes += h.size();
    g_leaf_bytes += leaf_bytes<NanoBuildT>(h);
    auto* grid = h.template grid<NanoBuildT>();
    auto acc = grid->getAccessor();
    for (int z = 0; z < f.dims.nz; ++z)
      for (int y = 0; y < f.dims.ny; ++y)
        for (int x = 0; x < f.dims.nx; ++x) {
          const float v = acc.getValue(nanovdb::Coord(x + f.index_min[0], y + f.index_min[1], z + f.index_min[2]));
          err.add(static_cast<double>(v) - s.grid.values[c][f.dims.index(x, y, z)]);
        }
    if (keep) keep->push_back(std::move(h));
  }
}

LbhEncoded haar(const Solution& s, double t_abs, LbhCoefficients coefficients = LbhCoefficients::Auto) {
  LbhSolutionIn in{s.name, -1, {0, 0, 0}, &s.grid.values};
  return encode_lbh_solution(s.grid.frame, in, {t_abs, false, coefficients}, 0);
}

// The smallest stream whose max node error stays <= target: per coefficient encoding, the largest
// absolute threshold that meets it (bisection on a log scale); 8-bit details cannot go below
// their quantisation error, so tight targets end with f32.
LbhEncoded haar_at_max_error(const Solution& s, double target) {
  LbhEncoded best = haar(s, 0.0, LbhCoefficients::F32);
  for (const LbhCoefficients c : {LbhCoefficients::F32, LbhCoefficients::Q8}) {
    double lo = 0, hi = 4 * target;
    for (int it = 0; it < 14; ++it) {
      const double mid = lo == 0 ? hi / 2 : std::sqrt(lo * hi);
      LbhEncoded e = haar(s, mid, c);
      if (e.stats.max_abs_error <= target) {
        lo = mid;
        if (e.stats.stream_bytes <= best.stats.stream_bytes) best = std::move(e);
      } else {
        hi = mid;
      }
    }
  }
  return best;
}

template <typename Fn>
double rate(const std::vector<openvdb::Vec3f>& pos, Fn fn) {
  double best = 0;
  volatile float sink = 0;
  for (int rep = 0; rep < 5; ++rep) {
    const auto t0 = std::chrono::steady_clock::now();
    float acc = 0;
    for (const auto& p : pos) acc += fn(p);
    sink = sink + acc;
    best = std::max(best, pos.size() / std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s FILE.vdb [--threshold REL] [--samples N] [--json OUT]\n", argv[0]);
    return 2;
  }
  double rel = 0.01;
  std::size_t nsamples = 2000000;
  std::string json_out;
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--threshold") rel = std::stod(argv[i + 1]);
    else if (a == "--samples") nsamples = std::stoull(argv[i + 1]);
    else if (a == "--json") json_out = argv[i + 1];
  }
  openvdb::initialize();
  const fs::path in = argv[1];
  std::vector<Solution> sols;
  const nlohmann::json info = inspect_vdb(in);
  for (const auto& g : info["grids"])
    if (g["type"] == "vec3s") sols.push_back({g["name"], read_vdb_grid_dense(in, g["name"])});
  std::sort(sols.begin(), sols.end(), [](const Solution& a, const Solution& b) { return a.name < b.name; });
  // A bake's lattice starts at index -1 (the margin): straddling the origin costs OpenVDB and
  // NanoVDB eight top-level nodes. Shift every copy to start at index 0, their best case.
  for (auto& s : sols) s.grid.frame.index_min = {0, 0, 0};
  if (sols.empty()) {
    std::fprintf(stderr, "no Vec3f grids in %s\n", argv[1]);
    return 1;
  }
  const Dims dims = sols[0].grid.frame.dims;
  const double raw = static_cast<double>(dims.count()) * 12.0 * sols.size();
  nlohmann::json report;
  report["file"] = in.string();
  report["dims"] = {dims.nx, dims.ny, dims.nz};
  report["solutions"] = sols.size();
  report["float_rgb_bytes"] = raw;
  report["rows"] = nlohmann::json::array();
  std::printf("%s: %zu Vec3f grids, %dx%dx%d, float RGB %.2f MB\n", argv[1], sols.size(), dims.nx, dims.ny, dims.nz,
              raw / 1e6);
  std::printf("%-44s %12s %9s %12s %12s\n", "format", "bytes", "ratio", "max error", "rms error");
  auto row = [&](const std::string& name, double bytes, double max_err, double rms, double max_rel) {
    std::printf("%-44s %12.0f %8.2f:1 %12.3g %12.3g\n", name.c_str(), bytes, raw / bytes, max_err, rms);
    report["rows"].push_back({{"format", name}, {"bytes", bytes}, {"ratio", raw / bytes}, {"max_abs_error", max_err},
                              {"rms_error", rms}, {"max_error_relative_to_max", max_rel}});
  };
  double max_value = 0;
  for (const auto& s : sols)
    for (int c = 0; c < 3; ++c)
      for (float v : s.grid.values[c]) max_value = std::max(max_value, static_cast<double>(std::fabs(v)));

  // --- OpenVDB files: the Vec3f grids alone, with each compression option ---
  {
    openvdb::GridPtrVec grids;
    ErrStats half_err;
    for (const auto& s : sols) {
      auto vg = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
      const auto& f = s.grid.frame;
      std::vector<openvdb::Vec3s> inter(dims.count());
      for (std::size_t i = 0; i < inter.size(); ++i) {
        inter[i] = openvdb::Vec3s(s.grid.values[0][i], s.grid.values[1][i], s.grid.values[2][i]);
        for (int c = 0; c < 3; ++c)
          half_err.add(static_cast<double>(static_cast<float>(openvdb::math::half(s.grid.values[c][i]))) -
                       s.grid.values[c][i]);
      }
      const openvdb::CoordBBox box(openvdb::Coord(f.index_min[0], f.index_min[1], f.index_min[2]),
                                   openvdb::Coord(f.index_min[0] + dims.nx - 1, f.index_min[1] + dims.ny - 1,
                                                  f.index_min[2] + dims.nz - 1));
      openvdb::tools::Dense<const openvdb::Vec3s, openvdb::tools::LayoutXYZ> dense(box, inter.data());
      openvdb::tools::copyFromDense(dense, *vg, openvdb::Vec3s(0.0f));
      vg->setName(s.name);
      if (grids.empty())
        std::printf("(OpenVDB copy of %s: %llu active voxels, %llu leaves, bbox %s)\n", s.name.c_str(),
                    static_cast<unsigned long long>(vg->activeVoxelCount()),
                    static_cast<unsigned long long>(vg->tree().leafCount()), (std::ostringstream() << vg->evalActiveVoxelBoundingBox()).str().c_str());
      grids.push_back(vg);
    }
    const fs::path tmp = fs::temp_directory_path() / ("lbh_compare_" + std::to_string(::getpid()) + ".vdb");
    struct Opt {
      const char* name;
      uint32_t flags;
      bool half;
    };
    std::vector<Opt> opts = {{"OpenVDB float, uncompressed", openvdb::io::COMPRESS_NONE, false},
                             {"OpenVDB float, zip", openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK, false},
                             {"OpenVDB half float, uncompressed", openvdb::io::COMPRESS_NONE, true},
                             {"OpenVDB half float, zip", openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK, true}};
    if (openvdb::io::Archive::hasBloscCompression()) {
      opts.push_back({"OpenVDB float, Blosc", openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK, false});
      opts.push_back({"OpenVDB half float, Blosc", openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK, true});
    } else {
      std::printf("(this OpenVDB has no Blosc)\n");
    }
    for (const Opt& o : opts) {
      for (auto& g : grids) g->setSaveFloatAsHalf(o.half);
      openvdb::io::File file(tmp.string());
      file.setCompression(o.flags);
      file.write(grids);
      file.close();
      const double bytes = static_cast<double>(fs::file_size(tmp));
      row(o.name, bytes, o.half ? half_err.max : 0.0, o.half ? half_err.rms() : 0.0,
          o.half ? half_err.max / max_value : 0.0);
    }
    fs::remove(tmp);
  }

  // --- NanoVDB ---
  std::vector<nanovdb::GridHandle<nanovdb::HostBuffer>> nano_vec3, nano_fp8, nano_fpn;
  {
    std::size_t bytes = 0;
    g_leaf_bytes = 0;
    for (const auto& s : sols) {
      auto vg = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
      auto fg0 = channel_grid(s.grid, 0);
      // Vec3f NanoVDB grid (lossless float)
      std::vector<openvdb::Vec3s> inter(dims.count());
      for (std::size_t i = 0; i < inter.size(); ++i)
        inter[i] = openvdb::Vec3s(s.grid.values[0][i], s.grid.values[1][i], s.grid.values[2][i]);
      const auto& f = s.grid.frame;
      const openvdb::CoordBBox box(openvdb::Coord(f.index_min[0], f.index_min[1], f.index_min[2]),
                                   openvdb::Coord(f.index_min[0] + dims.nx - 1, f.index_min[1] + dims.ny - 1,
                                                  f.index_min[2] + dims.nz - 1));
      openvdb::tools::Dense<const openvdb::Vec3s, openvdb::tools::LayoutXYZ> dense(box, inter.data());
      openvdb::tools::copyFromDense(dense, *vg, openvdb::Vec3s(0.0f));
      auto h = nanovdb::openToNanoVDB<nanovdb::HostBuffer, openvdb::Vec3STree>(*vg, nanovdb::StatsMode::Disable,
                                                                             nanovdb::ChecksumMode::Disable, 0);
      bytes += h.size();
      g_leaf_bytes += leaf_bytes<nanovdb::Vec3f>(h);
      nano_vec3.push_back(std::move(h));
    }
    row("NanoVDB Vec3f", static_cast<double>(bytes), 0, 0, 0);
    row("  (leaves only)", static_cast<double>(g_leaf_bytes), 0, 0, 0);
  }
  auto nano_row = [&](const char* name, auto tag, float tol, std::vector<nanovdb::GridHandle<nanovdb::HostBuffer>>* keep,
                      std::vector<double>* per_solution_max) {
    using T = decltype(tag);
    std::size_t bytes = 0;
    g_leaf_bytes = 0;
    ErrStats all;
    for (const auto& s : sols) {
      ErrStats e;
      nano_channels<T>(s, tol, bytes, e, keep);
      if (per_solution_max) per_solution_max->push_back(e.max);
      all.max = std::max(all.max, e.max);
      all.sum_sq += e.sum_sq;
      all.n += e.n;
    }
    row(name, static_cast<double>(bytes), all.max, all.rms(), all.max / max_value);
    row("  (leaves only)", static_cast<double>(g_leaf_bytes), all.max, all.rms(), all.max / max_value);
    return bytes;
  };
  std::vector<double> fp4_max, fp8_max, fp16_max;
  nano_row("NanoVDB Fp4 (3 float grids)", nanovdb::Fp4{}, -1, nullptr, &fp4_max);
  nano_row("NanoVDB Fp8 (3 float grids)", nanovdb::Fp8{}, -1, &nano_fp8, &fp8_max);
  nano_row("NanoVDB Fp16 (3 float grids)", nanovdb::Fp16{}, -1, nullptr, &fp16_max);

  // --- Haar at the requested relative threshold, then FpN at the same per-solution max error ---
  std::vector<LbhEncoded> enc;
  {
    double bytes = 0, enc_s = 0;
    ErrStats all;
    std::vector<double> per_max;
    for (const auto& s : sols) {
      double mx = 0;
      for (int c = 0; c < 3; ++c)
        for (float v : s.grid.values[c]) mx = std::max(mx, static_cast<double>(std::fabs(v)));
      enc.push_back(haar(s, rel * mx));
      const LbhStats& st = enc.back().stats;
      bytes += static_cast<double>(st.stream_bytes);
      enc_s += st.encode_seconds;
      all.max = std::max(all.max, st.max_abs_error);
      all.sum_sq += st.rms_error * st.rms_error * 3.0 * static_cast<double>(st.nodes);
      all.n += 3 * st.nodes;
      per_max.push_back(st.max_abs_error);
    }
    char name[96];
    std::snprintf(name, sizeof name, "lbh Haar, %g relative threshold", rel);
    row(name, bytes, all.max, all.rms(), all.max / max_value);
    report["encode_seconds_total"] = enc_s;
    // FpN with each solution's Haar max error as its tolerance
    std::size_t fbytes = 0;
    g_leaf_bytes = 0;
    ErrStats fall;
    for (std::size_t i = 0; i < sols.size(); ++i) {
      ErrStats e;
      nano_channels<nanovdb::FpN>(sols[i], static_cast<float>(per_max[i]), fbytes, e,
                                  i < 4 ? &nano_fpn : nullptr);
      fall.max = std::max(fall.max, e.max);
      fall.sum_sq += e.sum_sq;
      fall.n += e.n;
    }
    row("NanoVDB FpN, tolerance = lbh max error", static_cast<double>(fbytes), fall.max, fall.rms(),
        fall.max / max_value);
    row("  (leaves only)", static_cast<double>(g_leaf_bytes), fall.max, fall.rms(), fall.max / max_value);
    // FpN at each solution's Haar RMS error instead (bisection on the tolerance)
    std::size_t rbytes = 0, rleaf = 0;
    ErrStats rall;
    for (std::size_t i = 0; i < sols.size(); ++i) {
      const double target = enc[i].stats.rms_error;
      double lo = 0, hi = 8 * per_max[i];
      std::size_t best_bytes = 0, best_leaf = 0;
      ErrStats best;
      for (int it = 0; it < 12; ++it) {
        const double mid = 0.5 * (lo + hi);
        std::size_t b = 0;
        ErrStats e;
        g_leaf_bytes = 0;
        nano_channels<nanovdb::FpN>(sols[i], static_cast<float>(mid), b, e);
        if (e.rms() <= target || best_bytes == 0) {
          if (e.rms() <= target) lo = mid;
          else hi = mid;
          best_bytes = b;
          best_leaf = g_leaf_bytes;
          best = e;
        } else {
          hi = mid;
        }
      }
      rbytes += best_bytes;
      rleaf += best_leaf;
      rall.max = std::max(rall.max, best.max);
      rall.sum_sq += best.sum_sq;
      rall.n += best.n;
    }
    row("NanoVDB FpN, RMS error = lbh RMS error", static_cast<double>(rbytes), rall.max, rall.rms(), rall.max / max_value);
    row("  (leaves only)", static_cast<double>(rleaf), rall.max, rall.rms(), rall.max / max_value);
  }
  // Haar at the max error of Fp8 / Fp16 / Fp4, per solution
  auto haar_at = [&](const char* name, const std::vector<double>& target) {
    double bytes = 0;
    ErrStats all;
    std::size_t q8 = 0;
    for (std::size_t i = 0; i < sols.size(); ++i) {
      const LbhEncoded e = haar_at_max_error(sols[i], target[i]);
      q8 += e.encoding == lbh::Encoding::Q8;
      bytes += static_cast<double>(e.stats.stream_bytes);
      all.max = std::max(all.max, e.stats.max_abs_error);
      all.sum_sq += e.stats.rms_error * e.stats.rms_error * 3.0 * static_cast<double>(e.stats.nodes);
      all.n += 3 * e.stats.nodes;
    }
    const std::string label = std::string(name) + " (" + std::to_string(q8) + "/" + std::to_string(sols.size()) + " q8)";
    row(label.c_str(), bytes, all.max, all.rms(), all.max / max_value);
  };
  haar_at("lbh Haar at Fp4's max error", fp4_max);
  haar_at("lbh Haar at Fp8's max error", fp8_max);
  haar_at("lbh Haar at Fp16's max error", fp16_max);

  // --- Sampling throughput (one thread, random positions inside the lattice, solution 0) ---
  std::mt19937 rng(7);
  const auto& f = sols[0].grid.frame;
  std::uniform_real_distribution<float> ux(f.index_min[0], f.index_min[0] + dims.nx - 1),
      uy(f.index_min[1], f.index_min[1] + dims.ny - 1), uz(f.index_min[2], f.index_min[2] + dims.nz - 1);
  std::vector<openvdb::Vec3f> pos(nsamples);
  for (auto& p : pos) p = openvdb::Vec3f(ux(rng), uy(rng), uz(rng));
  const std::string lbh_bytes = serialize_lbh({dims, f.index_min, f.index_to_world}, {enc[0]});
  lbh::Stream stream;
  stream.open_memory(lbh_bytes.data(), lbh_bytes.size());
  const lbh::Lattice L = stream.lattice();
  const lbh::SolutionView view = stream.view(0);
  const std::vector<float>& R = sols[0].grid.values[0];
  const std::vector<float>& G = sols[0].grid.values[1];
  const std::vector<float>& B = sols[0].grid.values[2];
  std::vector<float> inter(dims.count() * 3);
  for (std::size_t i = 0; i < dims.count(); ++i) {
    inter[3 * i] = R[i];
    inter[3 * i + 1] = G[i];
    inter[3 * i + 2] = B[i];
  }
  auto dense = [&](const openvdb::Vec3f& p) {
    float q[3] = {p[0] - f.index_min[0], p[1] - f.index_min[1], p[2] - f.index_min[2]};
    int i[3];
    float a[3];
    const int n[3] = {dims.nx, dims.ny, dims.nz};
    for (int k = 0; k < 3; ++k) {
      q[k] = std::min(std::max(q[k], 0.0f), static_cast<float>(n[k] - 1));
      i[k] = std::min(static_cast<int>(q[k]), std::max(n[k] - 2, 0));
      a[k] = q[k] - i[k];
    }
    const std::size_t sx = 3, sy = 3 * static_cast<std::size_t>(dims.nx), sz = sy * dims.ny;
    const float* b = &inter[3 * dims.index(i[0], i[1], i[2])];
    float out = 0;
    for (int c = 0; c < 8; ++c) {
      const float w = (c & 1 ? a[0] : 1 - a[0]) * (c & 2 ? a[1] : 1 - a[1]) * (c & 4 ? a[2] : 1 - a[2]);
      const float* v = b + (c & 1 ? sx : 0) + (c & 2 ? sy : 0) + (c & 4 ? sz : 0);
      out += w * (v[0] + v[1] + v[2]);
    }
    return out;
  };
  nlohmann::json rates;
  const double r_dense = rate(pos, dense);
  const double r_lbh = rate(pos, [&](const openvdb::Vec3f& p) {
    const lbh::Rgb v = lbh::sample_index(L, view, p[0], p[1], p[2]);
    return v.r + v.g + v.b;
  });
  auto* nv = nano_vec3[0].grid<nanovdb::Vec3f>();
  auto nacc = nv->getAccessor();
  auto nsampler = nanovdb::createSampler<1>(nacc);
  const double r_nano = rate(pos, [&](const openvdb::Vec3f& p) {
    const nanovdb::Vec3f v = nsampler(nanovdb::Vec3f(p[0], p[1], p[2]));
    return v[0] + v[1] + v[2];
  });
  auto fp8_rate = [&](std::vector<nanovdb::GridHandle<nanovdb::HostBuffer>>& hs, auto tag) {
    using T = decltype(tag);
    auto a0 = hs[0].template grid<T>()->getAccessor();
    auto a1 = hs[1].template grid<T>()->getAccessor();
    auto a2 = hs[2].template grid<T>()->getAccessor();
    auto s0 = nanovdb::createSampler<1>(a0);
    auto s1 = nanovdb::createSampler<1>(a1);
    auto s2 = nanovdb::createSampler<1>(a2);
    return rate(pos, [&](const openvdb::Vec3f& p) {
      const nanovdb::Vec3f q(p[0], p[1], p[2]);
      return s0(q) + s1(q) + s2(q);
    });
  };
  const double r_fp8 = fp8_rate(nano_fp8, nanovdb::Fp8{});
  const double r_fpn = fp8_rate(nano_fpn, nanovdb::FpN{});
  auto vdb_grid = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
  {
    const openvdb::CoordBBox box(openvdb::Coord(f.index_min[0], f.index_min[1], f.index_min[2]),
                                 openvdb::Coord(f.index_min[0] + dims.nx - 1, f.index_min[1] + dims.ny - 1,
                                                f.index_min[2] + dims.nz - 1));
    std::vector<openvdb::Vec3s> iv(dims.count());
    for (std::size_t i = 0; i < iv.size(); ++i) iv[i] = openvdb::Vec3s(R[i], G[i], B[i]);
    openvdb::tools::Dense<const openvdb::Vec3s, openvdb::tools::LayoutXYZ> d(box, iv.data());
    openvdb::tools::copyFromDense(d, *vdb_grid, openvdb::Vec3s(0.0f));
  }
  auto vacc = vdb_grid->getConstAccessor();
  const double r_vdb = rate(pos, [&](const openvdb::Vec3f& p) {
    openvdb::Vec3s v;
    openvdb::tools::BoxSampler::sample(vacc, openvdb::Vec3R(p[0], p[1], p[2]), v);
    return v[0] + v[1] + v[2];
  });
  std::printf("\nsampling %s (trilinear, 1 thread, %zu random positions), million samples/s:\n", sols[0].name.c_str(),
              nsamples);
  const std::pair<const char*, double> rr[] = {{"dense float RGB array", r_dense},
                                               {"lbh stream (lbh::sample_index)", r_lbh},
                                               {"NanoVDB Vec3f (SampleFromVoxels<1>)", r_nano},
                                               {"NanoVDB Fp8 x 3 channels", r_fp8},
                                               {"NanoVDB FpN x 3 channels", r_fpn},
                                               {"OpenVDB Vec3f (BoxSampler, accessor)", r_vdb}};
  for (const auto& [name, r] : rr) {
    std::printf("  %-40s %8.2f   (%.2fx the dense time)\n", name, r / 1e6, r_dense / r);
    rates[name] = r;
  }
  report["samples_per_second"] = rates;
  if (!json_out.empty()) std::ofstream(json_out) << report.dump(2) << "\n";
  return 0;
}
