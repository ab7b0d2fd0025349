#include "lblight/compress/lbh_writer.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <thread>

#include "lblight/compress/haar.h"
#include "lblight/core/error.h"
#include "lblight/io/output_dir.h"

namespace lblight {
namespace {

// Per z-slab of sub-blocks: partial results added in slab order (deterministic for any thread count).
struct SlabStats {
  double sum_sq = 0, max_err = 0, max_err_block = 0, bound = 0;
  std::uint64_t fast = 0;
  float max_detail = 0;  // largest |kept detail coefficient| over channels (pass 1)
  bool finite = true;    // every coefficient finite (|values| near FLT_MAX overflow the filters)
};

// The Q8 step (docs/lbh-format.md sec. 3.4): half the threshold, or coarser when the largest kept
// detail needs it to fit -127..127; kept between the smallest positive float and the largest one
// whose 127 multiples stay finite (what readers check). A solution without kept details gets 1.
float q8_step(float threshold, float max_detail) {
  if (!(max_detail > 0)) return 1.0f;
  constexpr float kLargest = std::numeric_limits<float>::max() / 128.0f;  // 127 x step finite
  const double wanted = std::max(0.5 * threshold, static_cast<double>(max_detail) / lbh::kQ8Max);
  float step = static_cast<float>(std::min(wanted, static_cast<double>(kLargest)));
  step = std::max(step, std::numeric_limits<float>::denorm_min());
  while (step < kLargest && std::nearbyint(static_cast<double>(max_detail) / step) > lbh::kQ8Max)
    step = std::nextafter(step, std::numeric_limits<float>::infinity());
  return step;
}

std::int8_t quantise(float c, float step) {
  const double q = std::nearbyint(static_cast<double>(c) / step);
  return static_cast<std::int8_t>(std::clamp(q, -double{lbh::kQ8Max}, double{lbh::kQ8Max}));
}

// Runs fn(slab) for slab = 0..count-1 on up to `threads` threads.
template <typename Fn>
void parallel_slabs(int count, int threads, Fn fn) {
  int n = threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  n = std::max(1, std::min(n, count));
  std::atomic<int> next{0};
  auto work = [&] {
    for (int s = next++; s < count; s = next++) fn(s);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < n; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
}

// Nodes i of one axis whose value the reader takes from block b: [3b, 3b + 2], and for the last
// block every node up to n - 1.
void own_range(int b, int nb, int n, int& lo, int& hi) {
  lo = 3 * b;
  hi = b == nb - 1 ? n - 1 : 3 * b + 2;
}

void put32(std::string& s, std::size_t at, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) s[at + k] = static_cast<char>((v >> (8 * k)) & 0xFFu);
}
void put64(std::string& s, std::size_t at, std::uint64_t v) {
  for (int k = 0; k < 8; ++k) s[at + k] = static_cast<char>((v >> (8 * k)) & 0xFFu);
}
void puti32(std::string& s, std::size_t at, std::int32_t v) {
  std::uint32_t u;
  std::memcpy(&u, &v, 4);
  put32(s, at, u);
}
void putf32(std::string& s, std::size_t at, float v) {
  std::uint32_t u;
  std::memcpy(&u, &v, 4);
  put32(s, at, u);
}
void putf64(std::string& s, std::size_t at, double v) {
  std::uint64_t u;
  std::memcpy(&u, &v, 8);
  put64(s, at, u);
}
std::uint64_t align64(std::uint64_t v) { return (v + 63) / 64 * 64; }

}  // namespace

namespace {

// Largest |value| over nodes and channels (the scale of a relative threshold); rejects NaN and
// Inf with the node that holds it.
double checked_max_abs(const LbhSolutionIn& in, const Dims& d) {
  double max_abs = 0;
  for (int c = 0; c < 3; ++c) {
    const std::vector<float>& v = (*in.rgb)[c];
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (!std::isfinite(v[i])) {
        const std::size_t x = i % d.nx, y = (i / d.nx) % d.ny, z = i / (static_cast<std::size_t>(d.nx) * d.ny);
        throw_invalid("solution " + in.name + " holds a non-finite value; allowed: finite values",
                      {in.name, {}, "(" + std::to_string(x) + ", " + std::to_string(y) + ", " + std::to_string(z) + ")"});
      }
      max_abs = std::max(max_abs, static_cast<double>(std::fabs(v[i])));
    }
  }
  return max_abs;
}

// The sub-block grid of one solution and its values, as both passes walk it.
struct BlockGrid {
  Dims d;
  int nb[3];
  std::size_t slab;  // blocks per z-slab
  std::array<const float*, 3> rgb;
  std::uint64_t count() const { return static_cast<std::uint64_t>(nb[0]) * nb[1] * nb[2]; }
  std::size_t index(int bx, int by, int bz) const { return bz * slab + static_cast<std::size_t>(by) * nb[0] + bx; }
};

// Pass 1: transform and threshold every block, keep the masks (and the largest kept detail).
void select_coefficients(const BlockGrid& grid, int threads, LbhEncoded& out, std::vector<SlabStats>& stats) {
  parallel_slabs(grid.nb[2], threads, [&](int bz) {
    haar::Block blk;
    for (int by = 0; by < grid.nb[1]; ++by)
      for (int bx = 0; bx < grid.nb[0]; ++bx) {
        haar::gather_block(grid.rgb, grid.d, bx, by, bz, blk);
        haar::forward(blk);
        const std::uint64_t mask = haar::keep_mask(blk, out.threshold);
        out.masks[grid.index(bx, by, bz)] = mask;
        for (const auto& ch : blk)
          for (float c : ch) stats[static_cast<std::size_t>(bz)].finite &= std::isfinite(c);
        float& dmax = stats[static_cast<std::size_t>(bz)].max_detail;
        for (std::uint64_t m = mask & ~std::uint64_t{1}; m; m &= m - 1)
          for (int c = 0; c < 3; ++c) dmax = std::max(dmax, std::fabs(blk[c][lbh::lowest_bit(m)]));
      }
  });
}

// Offsets: prefix sums of the kept counts; returns the total kept.
std::uint64_t assign_offsets(LbhEncoded& out, const Location& where) {
  std::uint64_t total = 0;
  for (std::size_t b = 0; b < out.masks.size(); ++b) {
    if (total > 0xFFFFFFFFull) throw_invalid("more than 2^32 coefficients in one solution", where);
    out.offsets[b] = static_cast<std::uint32_t>(total);
    total += static_cast<std::uint64_t>(lbh::popcount64(out.masks[b]));
  }
  return total;
}

// Pass 2, one block: pack its kept coefficients, decode it the way readers do and measure the error.
void pack_block(const BlockGrid& grid, int bx, int by, int bz, bool q8, const lbh::SolutionView& view, LbhEncoded& out,
                SlabStats& st) {
  haar::Block blk, orig;
  lbh::Rgb dec[64];
  const std::size_t b = grid.index(bx, by, bz);
  haar::gather_block(grid.rgb, grid.d, bx, by, bz, orig);
  blk = orig;
  haar::forward(blk);
  const std::uint64_t mask = out.masks[b];
  // Error per coefficient (max over channels): |c| when dropped, |c - decoded c| when kept.
  float err[64];
  haar::dropped_errors(blk, mask, err);
  if (q8) {
    float* avg = out.coeffs.data() + 3 * b;
    std::int8_t* q = out.details.data() + 3ull * (out.offsets[b] - b);
    for (int c = 0; c < 3; ++c) avg[c] = blk[c][0];
    for (std::uint64_t m = mask & ~std::uint64_t{1}; m; m &= m - 1, q += 3) {
      const int l = lbh::lowest_bit(m);
      for (int c = 0; c < 3; ++c) {
        q[c] = quantise(blk[c][l], out.step);
        err[l] = std::max(err[l], std::fabs(blk[c][l] - out.step * static_cast<float>(q[c])));
      }
    }
  } else {
    float* dst = out.coeffs.data() + 3ull * out.offsets[b];
    for (std::uint64_t m = mask; m; m &= m - 1, dst += 3)
      for (int c = 0; c < 3; ++c) dst[c] = blk[c][lbh::lowest_bit(m)];
  }
  st.fast += mask == 1u;
  st.bound = std::max(st.bound, static_cast<double>(haar::path_error_bound(err)));
  lbh::decode_block(view, b, dec);
  for (int l = 0; l < 64; ++l) {
    const float got[3] = {dec[l].r, dec[l].g, dec[l].b};
    for (int c = 0; c < 3; ++c)
      st.max_err_block = std::max(st.max_err_block, static_cast<double>(std::fabs(got[c] - orig[c][l])));
  }
  int lo[3], hi[3];
  own_range(bx, grid.nb[0], grid.d.nx, lo[0], hi[0]);
  own_range(by, grid.nb[1], grid.d.ny, lo[1], hi[1]);
  own_range(bz, grid.nb[2], grid.d.nz, lo[2], hi[2]);
  for (int z = lo[2]; z <= hi[2]; ++z)
    for (int y = lo[1]; y <= hi[1]; ++y)
      for (int x = lo[0]; x <= hi[0]; ++x) {
        const int l = (x - lo[0]) + 4 * (y - lo[1]) + 16 * (z - lo[2]);
        const float got[3] = {dec[l].r, dec[l].g, dec[l].b};
        for (int c = 0; c < 3; ++c) {
          const double e = static_cast<double>(got[c]) - static_cast<double>(orig[c][l]);
          st.sum_sq += e * e;
          st.max_err = std::max(st.max_err, std::fabs(e));
        }
      }
}

// The statistics of a finished encoding: slab results added in slab order.
void finish_stats(const std::vector<SlabStats>& stats, const BlockGrid& grid, std::uint64_t total, bool q8,
                  double max_abs, LbhEncoded& out) {
  LbhStats& s = out.stats;
  double sum_sq = 0;
  for (const SlabStats& st : stats) {
    sum_sq += st.sum_sq;
    s.max_abs_error = std::max(s.max_abs_error, st.max_err);
    s.max_abs_error_block = std::max(s.max_abs_error_block, st.max_err_block);
    s.error_bound = std::max(s.error_bound, st.bound);
    s.fast_blocks += st.fast;
  }
  const std::uint64_t nblocks = grid.count();
  s.nodes = grid.d.count();
  s.blocks = nblocks;
  s.coefficients = total;
  s.float_rgb_bytes = s.nodes * 12u;
  s.stream_bytes = nblocks * 12u + (q8 ? nblocks * 12u + (total - nblocks) * 3u : total * 12u);
  s.ratio = static_cast<double>(s.float_rgb_bytes) / static_cast<double>(s.stream_bytes);
  s.max_abs_value = max_abs;
  s.threshold = out.threshold;
  s.rms_error = std::sqrt(sum_sq / (3.0 * static_cast<double>(s.nodes)));
}

}  // namespace

LbhEncoded encode_lbh_solution(const DenseFrame& frame, const LbhSolutionIn& in, const LbhSettings& threshold,
                               int threads) {
  const auto t0 = std::chrono::steady_clock::now();
  const Dims& d = frame.dims;
  const Location where{in.name, {}, {}};
  if (d.nx < 1 || d.ny < 1 || d.nz < 1 || d.nx > lbh::kMaxDim || d.ny > lbh::kMaxDim || d.nz > lbh::kMaxDim)
    throw_invalid("lattice dims must be 1.." + std::to_string(lbh::kMaxDim) + " per axis", where);
  if (!in.rgb) throw Error(ErrorCategory::Internal, "encode_lbh_solution: no values", where);
  for (const auto& ch : *in.rgb)
    if (ch.size() != d.count()) throw Error(ErrorCategory::Internal, "encode_lbh_solution: size mismatch", where);
  if (!(threshold.value >= 0) || !std::isfinite(threshold.value))
    throw_invalid("threshold " + std::to_string(threshold.value) + " is not allowed; allowed: a finite number >= 0",
                  where);

  LbhEncoded out;
  out.name = in.name;
  out.index = in.index;
  out.direction = in.direction;
  out.requested = threshold;
  const double max_abs = checked_max_abs(in, d);
  out.max_abs_value = static_cast<float>(max_abs);
  const double t_abs = threshold.relative ? threshold.value * max_abs : threshold.value;
  out.threshold = static_cast<float>(t_abs);
  if (!std::isfinite(out.threshold)) throw_invalid("threshold overflows a float", where);
  const bool q8 = threshold.coefficients == LbhCoefficients::Q8 ||
                  (threshold.coefficients == LbhCoefficients::Auto && out.threshold > 0);
  out.encoding = q8 ? lbh::Encoding::Q8 : lbh::Encoding::F32;

  BlockGrid grid{d, {haar::blocks_along(d.nx), haar::blocks_along(d.ny), haar::blocks_along(d.nz)}, 0,
                 {(*in.rgb)[0].data(), (*in.rgb)[1].data(), (*in.rgb)[2].data()}};
  grid.slab = static_cast<std::size_t>(grid.nb[0]) * grid.nb[1];
  const std::uint64_t nblocks = grid.count();
  out.masks.assign(nblocks, 0u);
  out.offsets.assign(nblocks, 0u);

  std::vector<SlabStats> stats(static_cast<std::size_t>(grid.nb[2]));
  select_coefficients(grid, threads, out, stats);
  for (const SlabStats& st : stats)
    if (!st.finite)
      throw_invalid("solution " + in.name + " holds values too large for the Haar filters (sums of two values "
                    "overflow a float); allowed: |value| <= 1.7e38",
                    where);
  if (q8) {
    float dmax = 0;
    for (const SlabStats& st : stats) dmax = std::max(dmax, st.max_detail);
    out.step = q8_step(out.threshold, dmax);
  }

  const std::uint64_t total = assign_offsets(out, where);
  out.coeffs.assign((q8 ? nblocks : total) * 3, 0.0f);
  if (q8) out.details.assign((total - nblocks) * 3, 0);

  const lbh::SolutionView view{out.masks.data(), out.offsets.data(), out.coeffs.data(),
                               q8 ? out.details.data() : nullptr, out.step};
  parallel_slabs(grid.nb[2], threads, [&](int bz) {
    for (int by = 0; by < grid.nb[1]; ++by)
      for (int bx = 0; bx < grid.nb[0]; ++bx) pack_block(grid, bx, by, bz, q8, view, out, stats[static_cast<std::size_t>(bz)]);
  });
  finish_stats(stats, grid, total, q8, max_abs, out);
  out.stats.encode_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

std::string serialize_lbh(const DenseFrame& frame, const std::vector<LbhEncoded>& sols) {
  if (sols.empty() || sols.size() > lbh::kMaxSolutions)
    throw Error(ErrorCategory::Internal, "an .lbh file holds 1.." + std::to_string(lbh::kMaxSolutions) + " solutions");
  const std::uint64_t table_end = lbh::kHeaderBytes + sols.size() * lbh::kEntryBytes;
  // Canonical layout: per solution masks, offsets, coefficients (F32) or averages and details
  // (Q8), each at the next multiple of 64.
  std::vector<std::array<std::uint64_t, 4>> sections(sols.size());
  std::uint64_t pos = table_end;
  bool any_q8 = false;
  for (std::size_t i = 0; i < sols.size(); ++i) {
    sections[i][0] = align64(pos);
    pos = sections[i][0] + sols[i].masks.size() * 8;
    sections[i][1] = align64(pos);
    pos = sections[i][1] + sols[i].offsets.size() * 4;
    sections[i][2] = align64(pos);
    pos = sections[i][2] + sols[i].coeffs.size() * 4;
    if (sols[i].encoding == lbh::Encoding::Q8) {
      any_q8 = true;
      sections[i][3] = align64(pos);
      pos = sections[i][3] + sols[i].details.size();
    }
  }
  std::string s(pos, '\0');

  namespace E = lbh::entry_field;
  for (std::size_t i = 0; i < sols.size(); ++i) {
    const LbhEncoded& e = sols[i];
    if (const char* why = lbh::name_problem(e.name.data(), e.name.size()))
      throw Error(ErrorCategory::Internal, "solution name '" + e.name + "' " + why);
    for (std::size_t k = 0; k < i; ++k)
      if (sols[k].name == e.name) throw Error(ErrorCategory::Internal, "two solutions are named '" + e.name + "'");
    const std::size_t t = lbh::kHeaderBytes + i * lbh::kEntryBytes;
    const auto at = [t](const lbh::Field& f) { return t + f.offset; };
    std::memcpy(&s[at(E::kName)], e.name.data(), e.name.size());
    puti32(s, at(E::kIndex), e.index);
    for (int a = 0; a < 3; ++a) puti32(s, at(E::kDirection) + 4 * a, e.direction[a]);
    put32(s, at(E::kThresholdMode), e.requested.relative ? 1u : 0u);
    putf32(s, at(E::kThresholdParam), static_cast<float>(e.requested.value));
    putf32(s, at(E::kThreshold), e.threshold);
    putf32(s, at(E::kMaxAbsValue), e.max_abs_value);
    put64(s, at(E::kBlockCount), e.masks.size());
    const bool q8 = e.encoding == lbh::Encoding::Q8;
    put64(s, at(E::kCoeffCount), q8 ? e.masks.size() + e.details.size() / 3 : e.coeffs.size() / 3);
    put64(s, at(E::kMasksOffset), sections[i][0]);
    put64(s, at(E::kOffsetsOffset), sections[i][1]);
    put64(s, at(E::kCoeffsOffset), sections[i][2]);
    if (!e.masks.empty()) std::memcpy(&s[sections[i][0]], e.masks.data(), e.masks.size() * 8);  // little-endian host
    if (!e.offsets.empty()) std::memcpy(&s[sections[i][1]], e.offsets.data(), e.offsets.size() * 4);
    if (!e.coeffs.empty()) std::memcpy(&s[sections[i][2]], e.coeffs.data(), e.coeffs.size() * 4);
    put32(s, at(E::kMasksCrc), lbh::crc32(&s[sections[i][0]], e.masks.size() * 8));
    put32(s, at(E::kOffsetsCrc), lbh::crc32(&s[sections[i][1]], e.offsets.size() * 4));
    put32(s, at(E::kCoeffsCrc), lbh::crc32(&s[sections[i][2]], e.coeffs.size() * 4));
    if (q8) {
      if (!e.details.empty()) std::memcpy(&s[sections[i][3]], e.details.data(), e.details.size());
      put32(s, at(E::kEncoding), static_cast<std::uint32_t>(lbh::Encoding::Q8));
      putf32(s, at(E::kQuantStep), e.step);
      put32(s, at(E::kDetailsCrc), lbh::crc32(&s[sections[i][3]], e.details.size()));
    }
    put64(s, at(E::kFastBlocks), e.stats.fast_blocks);
    putf32(s, at(E::kMaxAbsError), static_cast<float>(e.stats.max_abs_error));
    putf32(s, at(E::kRmsError), static_cast<float>(e.stats.rms_error));
  }

  namespace H = lbh::header_field;
  static const unsigned char magic[8] = {0x89, 'L', 'B', 'H', 0x0D, 0x0A, 0x1A, 0x0A};
  std::memcpy(&s[H::kMagic.offset], magic, H::kMagic.bytes);
  put32(s, H::kVersion.offset, any_q8 ? 2u : 1u);  // version 1 when every solution is F32: readable by version-1 readers
  put32(s, H::kEndianTag.offset, lbh::kEndianTag);
  put32(s, H::kHeaderBytes.offset, lbh::kHeaderBytes);
  put32(s, H::kEntryBytes.offset, lbh::kEntryBytes);
  put64(s, H::kFileBytes.offset, pos);
  put32(s, H::kSolutionCount.offset, static_cast<std::uint32_t>(sols.size()));
  put32(s, H::kFlags.offset, 0);
  const int dims[3] = {frame.dims.nx, frame.dims.ny, frame.dims.nz};
  for (int a = 0; a < 3; ++a) {
    puti32(s, H::kDims.offset + 4 * a, dims[a]);
    puti32(s, H::kIndexMin.offset + 4 * a, frame.index_min[a]);
    put32(s, H::kBlocks.offset + 4 * a, lbh::detail::blocks_for(dims[a]));
  }
  for (int e = 0; e < 16; ++e) putf64(s, H::kIndexToWorld.offset + 8 * e, frame.index_to_world[e]);
  put64(s, H::kTableOffset.offset, lbh::kHeaderBytes);
  put32(s, H::kTableCrc.offset, lbh::crc32(&s[lbh::kHeaderBytes], table_end - lbh::kHeaderBytes));
  put32(s, H::kHeaderCrc.offset, lbh::crc32(s.data(), H::kHeaderCrc.offset));
  return s;
}

void write_lbh(const std::filesystem::path& file, const DenseFrame& frame, const std::vector<LbhEncoded>& solutions) {
  write_file_atomically(file, serialize_lbh(frame, solutions));
}

nlohmann::json lbh_stats_json(const LbhEncoded& e, const std::string& file_name) {
  const LbhStats& s = e.stats;
  nlohmann::json j;
  j["file"] = file_name;
  j["threshold"] = s.threshold;
  j["threshold_requested"] = {{"value", e.requested.value}, {"relative", e.requested.relative}};
  j["max_abs_value"] = s.max_abs_value;
  j["float_rgb_bytes"] = s.float_rgb_bytes;
  j["compressed_bytes"] = s.stream_bytes;
  j["ratio"] = s.ratio;
  j["rms_error"] = s.rms_error;
  j["max_abs_error"] = s.max_abs_error;
  j["max_abs_error_stored_values"] = s.max_abs_error_block;
  j["error_bound"] = s.error_bound;
  j["blocks"] = s.blocks;
  j["fast_path_blocks"] = s.fast_blocks;
  j["coefficients"] = s.coefficients;
  j["coefficient_encoding"] = e.encoding == lbh::Encoding::Q8 ? "q8" : "f32";
  if (e.encoding == lbh::Encoding::Q8) j["quant_step"] = e.step;
  j["encode_seconds"] = s.encode_seconds;
  return j;
}

}  // namespace lblight
