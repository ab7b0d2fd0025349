// lbh_reader.h - header-only reader for lblight's Haar-compressed sub-block streams (.lbh, versions 1
// and 2).
//
// Standard C++17 library only; no OpenVDB, no lblight. Drop this one file into a renderer.
// The byte layout is specified in docs/lbh-format.md; in short (all little-endian):
//
//   offset 0    header, 256 bytes: magic 89 'L' 'B' 'H' 0D 0A 1A 0A, u32 version (1 or 2), u32 endian tag
//               0x01020304, sizes, lattice dims, index_min, sub-blocks per axis, f64[16] index-to-world,
//               table offset + CRC-32, header CRC-32 (over bytes 0..251)
//   offset 256  solution table: solution_count entries of 128 bytes (name, base-solution index and
//               direction, threshold, counts, section offsets, CRC-32 of each section)
//   then        per solution, each section starting at the next multiple of 64 (gaps zero):
//               u64 mask[block_count], u32 offset[block_count], f32 rgb[coeff_count][3]; or, for a
//               solution with 8-bit details (version 2, encoding 1): u64 mask[block_count],
//               u32 offset[block_count], f32 average[block_count][3], i8 detail[coeff_count - block_count][3]
//               (detail value = quant_step x stored integer)
//
// Geometry (docs/lbh-format.md sec. 3). Lattice nodes (i, j, k), 0 <= i < nx, sit at integer
// index coordinates index_min + (i, j, k) (voxel centres, as in the bake's .vdb). Sub-block
// (bx, by, bz), 0 <= bx < max(1, ceil((nx - 1) / 3)), holds the 4^3 node values at
// (3bx + x, 3by + y, 3bz + z), x, y, z in 0..3, each coordinate clamped to the last node, stored
// Haar-transformed (z, then y, then x; two levels per axis). A kept coefficient is marked in the
// block's 64-bit mask; offset[b] is the position of block b's first kept coefficient in the packed
// array (with 8-bit details: block b's averages at b, its k-th detail at offset[b] - b + k - 1).
// A trilinear sample reads exactly one sub-block.
//
// Usage (host):
//   lbh::Stream s;
//   if (s.open_file("tree.lbh") != lbh::Status::Ok) { std::cerr << s.error() << "\n"; return 1; }
//   lbh::Rgb v = s.sample_world(s.find(0), wx, wy, wz);           // ambient solution B00
//   lbh::Relighter r;  s.make_relighter(dx, dy, dz, 1.0f, 0.2f, r);  // sun travelling along d
//   lbh::Rgb lit = lbh::relight_index(s.lattice(), r, ix, iy, iz);
// Usage (CUDA/HIP): copy s.data()/s.size() to device memory (cudaMalloc is 256-byte aligned), take
// s.view(slot, device_ptr) or s.make_relighter(..., device_ptr), pass lattice + views by value to
// a kernel and call the LBH_HOSTDEV functions there. Device code never throws or allocates.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

#if !defined(LBH_DEVICE_ONLY)
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>
#endif

#if defined(__CUDACC__) || defined(__HIPCC__)
#define LBH_HOSTDEV __host__ __device__
#else
#define LBH_HOSTDEV
#endif

namespace lbh {

// ------------------------------------------------------------------------------------------------
// Format constants (docs/lbh-format.md sec. 2)
constexpr std::uint32_t kVersion = 2;          // newest version read and written
constexpr std::uint32_t kOldestVersion = 1;    // version 1: f32 coefficients only (every encoding field 0)
constexpr std::uint32_t kEndianTag = 0x01020304u;
constexpr std::uint32_t kHeaderBytes = 256;
constexpr std::uint32_t kEntryBytes = 128;
constexpr std::uint32_t kSectionAlign = 64;
constexpr std::int32_t kMaxDim = 1 << 20;         // nodes per axis
constexpr std::uint32_t kMaxSolutions = 4096;
constexpr int kBlockStride = 3;                    // nodes per sub-block and axis (own nodes)
constexpr int kBlockEdge = 4;                      // values per sub-block and axis (with the forward border)

// ------------------------------------------------------------------------------------------------
// Byte layout of the header and of a solution-table entry (docs/lbh-format.md secs. 2.1, 2.2),
// defined once: the reader here and lblight's writer (lblight/compress/lbh_writer.cpp) address
// every field through these names. The static_asserts check that the fields tile each record.
struct Field {
  std::uint32_t offset, bytes;
  constexpr std::uint32_t end() const { return offset + bytes; }
};
namespace header_field {
constexpr Field kMagic{0, 8};            // 89 'L' 'B' 'H' 0D 0A 1A 0A
constexpr Field kVersion{8, 4};          // u32: 1 or 2
constexpr Field kEndianTag{12, 4};       // u32: 0x01020304
constexpr Field kHeaderBytes{16, 4};     // u32: 256
constexpr Field kEntryBytes{20, 4};      // u32: 128
constexpr Field kFileBytes{24, 8};       // u64: the whole file
constexpr Field kSolutionCount{32, 4};   // u32
constexpr Field kFlags{36, 4};           // u32: 0
constexpr Field kDims{40, 12};           // i32[3]
constexpr Field kIndexMin{52, 12};       // i32[3]
constexpr Field kBlocks{64, 12};         // u32[3]: sub-blocks per axis
constexpr Field kReserved1{76, 4};       // u32: 0
constexpr Field kIndexToWorld{80, 128};  // f64[16], row-major
constexpr Field kTableOffset{208, 8};    // u64: 256
constexpr Field kTableCrc{216, 4};       // u32: CRC-32 of the solution table
constexpr Field kReserved2{220, 32};     // 0
constexpr Field kHeaderCrc{252, 4};      // u32: CRC-32 of bytes 0..251
constexpr Field kAll[] = {kMagic,     kVersion,  kEndianTag,    kHeaderBytes, kEntryBytes, kFileBytes,
                          kSolutionCount, kFlags, kDims,         kIndexMin,    kBlocks,     kReserved1,
                          kIndexToWorld, kTableOffset, kTableCrc, kReserved2,   kHeaderCrc};
}  // namespace header_field
namespace entry_field {
constexpr Field kName{0, 16};             // printable ASCII, NUL-padded
constexpr Field kIndex{16, 4};            // i32: base solution 0..18, -1 otherwise
constexpr Field kDirection{20, 12};       // i32[3], each -1..1
constexpr Field kThresholdMode{32, 4};    // u32: 0 absolute, 1 relative
constexpr Field kThresholdParam{36, 4};   // f32: as requested
constexpr Field kThreshold{40, 4};        // f32: absolute, as applied
constexpr Field kMaxAbsValue{44, 4};      // f32
constexpr Field kBlockCount{48, 8};       // u64
constexpr Field kCoeffCount{56, 8};       // u64
constexpr Field kMasksOffset{64, 8};      // u64
constexpr Field kOffsetsOffset{72, 8};    // u64
constexpr Field kCoeffsOffset{80, 8};     // u64 (Q8: the averages)
constexpr Field kMasksCrc{88, 4};         // u32
constexpr Field kOffsetsCrc{92, 4};       // u32
constexpr Field kCoeffsCrc{96, 4};        // u32
constexpr Field kEncoding{100, 4};        // u32: 0 f32, 1 8-bit details (version 2)
constexpr Field kFastBlocks{104, 8};      // u64
constexpr Field kMaxAbsError{112, 4};     // f32 (informational)
constexpr Field kRmsError{116, 4};        // f32 (informational)
constexpr Field kQuantStep{120, 4};       // f32: Q8 step; 0 for f32
constexpr Field kDetailsCrc{124, 4};      // u32: Q8 details; 0 for f32
constexpr Field kAll[] = {kName,         kIndex,        kDirection,    kThresholdMode, kThresholdParam, kThreshold,
                          kMaxAbsValue,  kBlockCount,   kCoeffCount,   kMasksOffset,   kOffsetsOffset,  kCoeffsOffset,
                          kMasksCrc,     kOffsetsCrc,   kCoeffsCrc,    kEncoding,      kFastBlocks,     kMaxAbsError,
                          kRmsError,     kQuantStep,    kDetailsCrc};
}  // namespace entry_field
// Why `name` cannot name a solution (nullptr when it can): 1..15 printable ASCII characters, and
// no two solutions of a file share one. The writer (lblight/compress) applies the same rule.
inline const char* name_problem(const char* name, std::size_t len) {
  if (len == 0) return "is empty";
  if (len > 15) return "is longer than 15 characters";
  for (std::size_t c = 0; c < len; ++c)
    if (static_cast<unsigned char>(name[c]) < 0x20 || static_cast<unsigned char>(name[c]) > 0x7E)
      return "is not printable ASCII";
  return nullptr;
}

namespace detail {
template <std::size_t N>
constexpr bool tiles(const Field (&fields)[N], std::uint32_t total) {
  std::uint32_t at = 0;
  for (const Field& f : fields) {
    if (f.offset != at) return false;
    at = f.end();
  }
  return at == total;
}
}  // namespace detail
static_assert(detail::tiles(header_field::kAll, kHeaderBytes), "header fields must tile its 256 bytes in order");
static_assert(detail::tiles(entry_field::kAll, kEntryBytes), "entry fields must tile its 128 bytes in order");
static_assert(header_field::kHeaderCrc.end() == kHeaderBytes, "the header CRC covers everything before it");

struct Rgb {
  float r, g, b;
};

// How a solution stores its kept coefficients (table entry offset 100; version 2).
enum class Encoding : std::uint32_t {
  F32 = 0,  // every kept coefficient as 3 f32 (the only encoding of version 1)
  Q8 = 1,   // the block average as 3 f32, each kept detail as 3 i8 in units of quant_step
};
constexpr std::int8_t kQ8Max = 127;  // stored integers lie in -127..127

// ------------------------------------------------------------------------------------------------
// Bit helpers
LBH_HOSTDEV inline int popcount64(std::uint64_t m) {
#if defined(__CUDA_ARCH__) || defined(__HIP_DEVICE_COMPILE__)
  return __popcll(m);
#elif defined(__GNUC__) || defined(__clang__)
  return __builtin_popcountll(m);
#else
  int n = 0;
  for (; m; m &= m - 1) ++n;
  return n;
#endif
}

LBH_HOSTDEV inline int lowest_bit(std::uint64_t m) {  // m != 0
#if defined(__CUDA_ARCH__) || defined(__HIP_DEVICE_COMPILE__)
  return __ffsll(static_cast<long long>(m)) - 1;
#elif defined(__GNUC__) || defined(__clang__)
  return __builtin_ctzll(m);
#else
  int n = 0;
  while (!(m & 1u)) { m >>= 1; ++n; }
  return n;
#endif
}

// ------------------------------------------------------------------------------------------------
// Haar transform ([Steele2009] sec. 2.3): unnormalised filters (x0 + x1) / 2 and (x0 - x1) / 2, two levels.
// 1D on 4 values: [x0 x1 x2 x3] -> [A D d0 d1] with s0 = (x0+x1)/2, s1 = (x2+x3)/2,
// d0 = (x0-x1)/2, d1 = (x2-x3)/2, A = (s0+s1)/2, D = (s0-s1)/2. Example: [4 19 44 0] ->
// [16.75 -5.25 -7.5 22]. Inverse: s0 = A+D, s1 = A-D, x = [s0+d0, s0-d0, s1+d1, s1-d1].
// In a block, value (x, y, z) sits at x + 4y + 16z and coefficient (fx, fy, fz) at fx + 4fy + 16fz.

LBH_HOSTDEV inline void haar_forward_1d(float* v, int stride) {
  const float x0 = v[0], x1 = v[stride], x2 = v[2 * stride], x3 = v[3 * stride];
  const float s0 = (x0 + x1) * 0.5f, s1 = (x2 + x3) * 0.5f;
  const float d0 = (x0 - x1) * 0.5f, d1 = (x2 - x3) * 0.5f;
  v[0] = (s0 + s1) * 0.5f;
  v[stride] = (s0 - s1) * 0.5f;
  v[2 * stride] = d0;
  v[3 * stride] = d1;
}

LBH_HOSTDEV inline void haar_inverse_1d(float* v, int stride) {
  const float a = v[0], d = v[stride], d0 = v[2 * stride], d1 = v[3 * stride];
  const float s0 = a + d, s1 = a - d;
  v[0] = s0 + d0;
  v[stride] = s0 - d0;
  v[2 * stride] = s1 + d1;
  v[3 * stride] = s1 - d1;
}

// One channel of a 4^3 block in place: forward along z, then y, then x.
LBH_HOSTDEV inline void haar_forward_block(float* v) {
  for (int i = 0; i < 16; ++i) haar_forward_1d(v + i, 16);                        // z (stride 16)
  for (int z = 0; z < 4; ++z)
    for (int x = 0; x < 4; ++x) haar_forward_1d(v + 16 * z + x, 4);              // y (stride 4)
  for (int i = 0; i < 16; ++i) haar_forward_1d(v + 4 * i, 1);                     // x (stride 1)
}

// The inverse: along x, then y, then z.
LBH_HOSTDEV inline void haar_inverse_block(float* v) {
  for (int i = 0; i < 16; ++i) haar_inverse_1d(v + 4 * i, 1);
  for (int z = 0; z < 4; ++z)
    for (int x = 0; x < 4; ++x) haar_inverse_1d(v + 16 * z + x, 4);
  for (int i = 0; i < 16; ++i) haar_inverse_1d(v + i, 16);
}

// ------------------------------------------------------------------------------------------------
// Views: plain structs (pointers into a validated stream, host or device memory), passed by value.

struct Lattice {
  std::int32_t n[3];             // nodes per axis
  std::int32_t nb[3];            // sub-blocks per axis: max(1, ceil((n - 1) / 3))
  std::int32_t index_min[3];     // index coordinate of node (0, 0, 0)
  float world_to_index[12];      // row-major 3x4 affine (inverse of the file's index_to_world)
};

struct SolutionView {
  const std::uint64_t* masks = nullptr;    // block_count
  const std::uint32_t* offsets = nullptr;  // block_count, in coefficients (averages included)
  const float* coeffs = nullptr;           // F32: coeff_count x 3 (RGB); Q8: the averages, block_count x 3
  const std::int8_t* details = nullptr;    // Q8 only: (coeff_count - block_count) x 3; null for F32
  float step = 0.0f;                       // Q8 only: a detail is step x its stored integer
};

LBH_HOSTDEV inline std::uint64_t block_index(const Lattice& L, int bx, int by, int bz) {
  return (static_cast<std::uint64_t>(bz) * static_cast<std::uint64_t>(L.nb[1]) + static_cast<std::uint64_t>(by)) *
             static_cast<std::uint64_t>(L.nb[0]) +
         static_cast<std::uint64_t>(bx);
}

// Where block b's average lies in s.coeffs.
LBH_HOSTDEV inline const float* block_average(const SolutionView& s, std::uint64_t b) {
  return s.coeffs + 3ull * (s.details ? b : static_cast<std::uint64_t>(s.offsets[b]));
}

// Q8: where block b's first kept detail lies in s.details (offsets count the averages too).
LBH_HOSTDEV inline const std::int8_t* block_details(const SolutionView& s, std::uint64_t b) {
  return s.details + 3ull * (static_cast<std::uint64_t>(s.offsets[b]) - b);
}

// Decodes sub-block b into its 64 RGB values (value (x, y, z) at x + 4y + 16z).
LBH_HOSTDEV inline void decode_block(const SolutionView& s, std::uint64_t b, Rgb* out) {
  const std::uint64_t mask = s.masks[b];
  const float* avg = block_average(s, b);
  if (mask == 1u) {  // fast path: only the average kept, the block is constant
    for (int i = 0; i < 64; ++i) out[i] = Rgb{avg[0], avg[1], avg[2]};
    return;
  }
  float ch[3][64];
  for (int k = 0; k < 3; ++k)
    for (int i = 0; i < 64; ++i) ch[k][i] = 0.0f;
  if (s.details) {
    for (int k = 0; k < 3; ++k) ch[k][0] = avg[k];
    const std::int8_t* q = block_details(s, b);
    for (std::uint64_t m = mask & ~std::uint64_t{1}; m; m &= m - 1, q += 3) {
      const int l = lowest_bit(m);
      for (int k = 0; k < 3; ++k) ch[k][l] = s.step * static_cast<float>(q[k]);
    }
  } else {
    const float* c = avg;
    for (std::uint64_t m = mask; m; m &= m - 1, c += 3) {
      const int l = lowest_bit(m);
      for (int k = 0; k < 3; ++k) ch[k][l] = c[k];
    }
  }
  for (int k = 0; k < 3; ++k) haar_inverse_block(ch[k]);
  for (int i = 0; i < 64; ++i) out[i] = Rgb{ch[0][i], ch[1][i], ch[2][i]};
}

// ------------------------------------------------------------------------------------------------
// Trilinear sampling ([Steele2009] eqs. 4.4-4.5; docs/lbh-format.md sec. 4). A lattice-relative position u
// (node i at u = i) is clamped to [0, n - 1] per axis (NaN -> 0); the cell is i = min(floor(u), n - 2)
// (0 when n = 1) with fraction a = u - i, blended from nodes i and i + 1. [Steele2009]'s texel convention
// (texel i centred at i + 0.5, x_B = max(0, p - 0.5)) is the same with p = u + 0.5; the far edge is
// clamped here as well. The cell lies in sub-block i / 3 at local offset i - 3 (i / 3) in 0..2.

struct Cell {
  std::uint64_t block;  // sub-block index
  float w[3][4];        // per axis: weight of coefficient frequency f = 0..3 at this position
};

// Axis weights: sum over the two corners of (trilinear weight) x (Haar basis value at the corner).
// Basis values per frequency f and position p: f0 = 1; f1 = +1 (p < 2), -1 (p >= 2);
// f2 = +1 (p = 0), -1 (p = 1), 0 otherwise; f3 = +1 (p = 2), -1 (p = 3), 0 otherwise.
LBH_HOSTDEV inline void axis_weights(int local, float a, float* w) {
  const float w0 = 1.0f - a, w1 = a;
  w[0] = w0 + w1;
  if (local == 0) {
    w[1] = w0 + w1;
    w[2] = w0 - w1;
    w[3] = 0.0f;
  } else if (local == 1) {
    w[1] = w0 - w1;
    w[2] = -w0;
    w[3] = w1;
  } else {
    w[1] = -(w0 + w1);
    w[2] = 0.0f;
    w[3] = w0 - w1;
  }
}

LBH_HOSTDEV inline void locate_axis(std::int32_t n, float u, int& block, int& local, float& a) {
  const float hi = static_cast<float>(n - 1);
  if (!(u > 0.0f)) u = 0.0f;  // also NaN
  if (u > hi) u = hi;
  int i = static_cast<int>(u);
  if (i > n - 2) i = n - 2 > 0 ? n - 2 : 0;
  a = u - static_cast<float>(i);
  block = i / kBlockStride;
  local = i - kBlockStride * block;
}

// u, v, w: lattice-relative coordinates (node (0, 0, 0) at 0).
LBH_HOSTDEV inline Cell locate_lattice(const Lattice& L, float u, float v, float w) {
  Cell c;
  int b[3], l[3];
  float a[3];
  locate_axis(L.n[0], u, b[0], l[0], a[0]);
  locate_axis(L.n[1], v, b[1], l[1], a[1]);
  locate_axis(L.n[2], w, b[2], l[2], a[2]);
  for (int k = 0; k < 3; ++k) axis_weights(l[k], a[k], c.w[k]);
  c.block = block_index(L, b[0], b[1], b[2]);
  return c;
}

// x, y, z: index-space coordinates of the bake's .vdb grid (node (i, j, k) at index_min + (i, j, k)).
LBH_HOSTDEV inline Cell locate_index(const Lattice& L, float x, float y, float z) {
  return locate_lattice(L, x - static_cast<float>(L.index_min[0]), y - static_cast<float>(L.index_min[1]),
                        z - static_cast<float>(L.index_min[2]));
}

LBH_HOSTDEV inline Cell locate_world(const Lattice& L, float x, float y, float z) {
  const float* m = L.world_to_index;
  return locate_index(L, m[0] * x + m[1] * y + m[2] * z + m[3], m[4] * x + m[5] * y + m[6] * z + m[7],
                      m[8] * x + m[9] * y + m[10] * z + m[11]);
}

// The trilinear sample of one solution: the sum over the block's kept coefficients of
// coefficient x w_x[fx] w_y[fy] w_z[fz] (equal, up to float rounding, to decoding the block and
// blending its 8 nodes). Reads one mask, one offset and the block's coefficients.
LBH_HOSTDEV inline Rgb sample_cell(const SolutionView& s, const Cell& cell) {
  const std::uint64_t mask = s.masks[cell.block];
  const float* c = block_average(s, cell.block);
  if (mask == 1u) return Rgb{c[0], c[1], c[2]};  // fast path: constant block
  if (s.details) {  // Q8: the average (weight w_x[0] w_y[0] w_z[0] = 1) plus the scaled details
    float r = 0.0f, g = 0.0f, bl = 0.0f;
    const std::int8_t* q = block_details(s, cell.block);
    for (std::uint64_t m = mask & ~std::uint64_t{1}; m; m &= m - 1, q += 3) {
      const int l = lowest_bit(m);
      const float wt = cell.w[0][l & 3] * cell.w[1][(l >> 2) & 3] * cell.w[2][l >> 4];
      r += wt * static_cast<float>(q[0]);
      g += wt * static_cast<float>(q[1]);
      bl += wt * static_cast<float>(q[2]);
    }
    return Rgb{c[0] + s.step * r, c[1] + s.step * g, c[2] + s.step * bl};
  }
  Rgb out{0.0f, 0.0f, 0.0f};
  for (std::uint64_t m = mask; m; m &= m - 1, c += 3) {
    const int l = lowest_bit(m);
    const float wt = cell.w[0][l & 3] * cell.w[1][(l >> 2) & 3] * cell.w[2][l >> 4];
    out.r += wt * c[0];
    out.g += wt * c[1];
    out.b += wt * c[2];
  }
  return out;
}

LBH_HOSTDEV inline Rgb sample_index(const Lattice& L, const SolutionView& s, float x, float y, float z) {
  return sample_cell(s, locate_index(L, x, y, z));
}

LBH_HOSTDEV inline Rgb sample_world(const Lattice& L, const SolutionView& s, float x, float y, float z) {
  return sample_cell(s, locate_world(L, x, y, z));
}

// ------------------------------------------------------------------------------------------------
// Relighting (docs/model.md sec. 4, [Steele2009] sec. 4.2): for sunlight travelling along d, the ray from the origin
// along d hits one of the 32 faces of the polyhedron of the 18 unit lattice directions; with its
// barycentric weights (w_a, w_b, w_c) the light is s (w_a B_a + w_b B_b + w_c B_c) + a B_0.

// D3Q19 directions in the order of docs/model.md sec. 1 (packed as c + 1, two bits per direction).
LBH_HOSTDEV inline int lattice_cx(int m) { return static_cast<int>((0x1548889549ull >> (2 * m)) & 3ull) - 1; }
LBH_HOSTDEV inline int lattice_cy(int m) { return static_cast<int>((0x895609495ull >> (2 * m)) & 3ull) - 1; }
LBH_HOSTDEV inline int lattice_cz(int m) { return static_cast<int>((0x20a0954955ull >> (2 * m)) & 3ull) - 1; }

// The 32 faces as direction triples (a | b << 5 | c << 10), outward oriented.
LBH_HOSTDEV inline int polyhedron_face(int f) {
  switch (f) {
    case 0: return 1 | 7 << 5 | 11 << 10;    case 1: return 1 | 13 << 5 | 7 << 10;
    case 2: return 1 | 11 << 5 | 9 << 10;    case 3: return 1 | 9 << 5 | 13 << 10;
    case 4: return 2 | 12 << 5 | 8 << 10;    case 5: return 2 | 8 << 5 | 14 << 10;
    case 6: return 2 | 10 << 5 | 12 << 10;   case 7: return 2 | 14 << 5 | 10 << 10;
    case 8: return 3 | 15 << 5 | 7 << 10;    case 9: return 3 | 7 << 5 | 17 << 10;
    case 10: return 3 | 10 << 5 | 15 << 10;  case 11: return 3 | 17 << 5 | 10 << 10;
    case 12: return 4 | 8 << 5 | 16 << 10;   case 13: return 4 | 18 << 5 | 8 << 10;
    case 14: return 4 | 16 << 5 | 9 << 10;   case 15: return 4 | 9 << 5 | 18 << 10;
    case 16: return 5 | 11 << 5 | 15 << 10;  case 17: return 5 | 18 << 5 | 11 << 10;
    case 18: return 5 | 15 << 5 | 14 << 10;  case 19: return 5 | 14 << 5 | 18 << 10;
    case 20: return 6 | 16 << 5 | 12 << 10;  case 21: return 6 | 12 << 5 | 17 << 10;
    case 22: return 6 | 13 << 5 | 16 << 10;  case 23: return 6 | 17 << 5 | 13 << 10;
    case 24: return 7 | 15 << 5 | 11 << 10;  case 25: return 7 | 13 << 5 | 17 << 10;
    case 26: return 8 | 12 << 5 | 16 << 10;  case 27: return 8 | 18 << 5 | 14 << 10;
    case 28: return 9 | 11 << 5 | 18 << 10;  case 29: return 9 | 16 << 5 | 13 << 10;
    case 30: return 10 | 17 << 5 | 12 << 10; default: return 10 | 14 << 5 | 15 << 10;
  }
}

struct SunWeights {
  int direction[3];  // lattice directions 1..18 (0 when the input was not a finite non-zero vector)
  float weight[3];   // barycentric weights >= 0, summing to 1
};

LBH_HOSTDEV inline double det3(const double* a, const double* b, const double* c) {
  return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

// Light travelling along (dx, dy, dz); a zero or non-finite vector gives weights 0.
LBH_HOSTDEV inline SunWeights decompose_direction(double dx, double dy, double dz) {
  SunWeights out{{0, 0, 0}, {0.0f, 0.0f, 0.0f}};
  if (!(dx * dx + dy * dy + dz * dz > 0.0) || !(dx * dx + dy * dy + dz * dz < 1e300)) return out;
  double best_min = -1e300, best[3] = {0, 0, 0};
  for (int f = 0; f < 32; ++f) {
    const int packed = polyhedron_face(f);
    const int id[3] = {packed & 31, (packed >> 5) & 31, (packed >> 10) & 31};
    double n[3][3];
    for (int k = 0; k < 3; ++k) {
      const int m = id[k];
      const double len = (lattice_cx(m) != 0) + (lattice_cy(m) != 0) + (lattice_cz(m) != 0) == 1 ? 1.0
                                                                                                 : 0.70710678118654752440;
      n[k][0] = lattice_cx(m) * len;
      n[k][1] = lattice_cy(m) * len;
      n[k][2] = lattice_cz(m) * len;
    }
    // Cramer's rule for d = alpha n_a + beta n_b + gamma n_c.
    const double d[3] = {dx, dy, dz};
    const double det = det3(n[0], n[1], n[2]);
    const double alpha = det3(d, n[1], n[2]) / det, beta = det3(n[0], d, n[2]) / det,
                 gamma = det3(n[0], n[1], d) / det;
    double lo = alpha < beta ? alpha : beta;
    lo = lo < gamma ? lo : gamma;
    if (lo > best_min + 1e-15) {  // the face with the largest smallest coefficient is the one hit
      best_min = lo;
      const double sum = alpha + beta + gamma;
      best[0] = alpha / sum > 0 ? alpha / sum : 0.0;
      best[1] = beta / sum > 0 ? beta / sum : 0.0;
      best[2] = gamma / sum > 0 ? gamma / sum : 0.0;
      for (int k = 0; k < 3; ++k) out.direction[k] = id[k];
    }
  }
  // rounding residue (a sun along a lattice direction or face edge) is 0: it needs no solution
  // (1e-9: kNegligibleSunWeight in lblight/lattice/sun.h; this header includes nothing of lblight)
  for (int k = 0; k < 3; ++k)
    if (best[k] < 1e-9) best[k] = 0.0;
  const double s = best[0] + best[1] + best[2];
  for (int k = 0; k < 3; ++k) out.weight[k] = static_cast<float>(best[k] / s);
  return out;
}

// Up to four weighted solutions blended per sample (three directional + ambient).
struct Relighter {
  SolutionView view[4];
  float weight[4];
  int count = 0;
};

LBH_HOSTDEV inline Rgb relight_cell(const Relighter& r, const Cell& cell) {
  Rgb out{0.0f, 0.0f, 0.0f};
  for (int k = 0; k < r.count; ++k) {
    const Rgb v = sample_cell(r.view[k], cell);
    out.r += r.weight[k] * v.r;
    out.g += r.weight[k] * v.g;
    out.b += r.weight[k] * v.b;
  }
  return out;
}

LBH_HOSTDEV inline Rgb relight_index(const Lattice& L, const Relighter& r, float x, float y, float z) {
  return relight_cell(r, locate_index(L, x, y, z));
}

LBH_HOSTDEV inline Rgb relight_world(const Lattice& L, const Relighter& r, float x, float y, float z) {
  return relight_cell(r, locate_world(L, x, y, z));
}

#if !defined(LBH_DEVICE_ONLY)
// ================================================================================================
// Host side: CRC-32, opening and validating a stream. No exceptions: every call returns a Status
// and error() says what is wrong in one line.

// Fuzzing builds may skip the CRC-32 comparisons to reach the checks behind them; never ship that.
#if defined(LBH_FUZZ_IGNORE_CHECKSUMS)
constexpr bool kVerifyChecksums = false;
#else
constexpr bool kVerifyChecksums = true;
#endif

// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320, init and final xor 0xFFFFFFFF): the CRC of
// zlib.crc32 / binascii.crc32. crc32("123456789") = 0xCBF43926.
inline std::uint32_t crc32(const void* data, std::size_t size, std::uint32_t crc = 0) {
  struct Table {
    std::uint32_t t[256];
    Table() {
      for (std::uint32_t i = 0; i < 256; ++i) {
        std::uint32_t c = i;
        for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
        t[i] = c;
      }
    }
  };
  static const Table table;
  const unsigned char* p = static_cast<const unsigned char*>(data);
  crc = ~crc;
  for (std::size_t i = 0; i < size; ++i) crc = table.t[(crc ^ p[i]) & 0xFFu] ^ (crc >> 8);
  return ~crc;
}

enum class Status {
  Ok = 0,
  IoError,              // the file could not be read
  Truncated,            // fewer bytes than the header declares
  BadMagic,             // not an .lbh file
  UnsupportedVersion,   // a format version this reader does not know
  UnsupportedEndianness,  // big-endian file, or a big-endian host
  BadHeader,            // a header or table field outside its allowed values
  CountOutOfRange,      // a count or offset that cannot fit the file or the lattice
  ChecksumMismatch,     // a CRC-32 does not match: corrupted
  Inconsistent,         // masks, offsets and counts disagree, or a coefficient is not finite
};

inline const char* status_name(Status s) {
  switch (s) {
    case Status::Ok: return "ok";
    case Status::IoError: return "I/O error";
    case Status::Truncated: return "truncated";
    case Status::BadMagic: return "not an .lbh file";
    case Status::UnsupportedVersion: return "unsupported version";
    case Status::UnsupportedEndianness: return "unsupported endianness";
    case Status::BadHeader: return "bad header";
    case Status::CountOutOfRange: return "count out of range";
    case Status::ChecksumMismatch: return "checksum mismatch";
    case Status::Inconsistent: return "inconsistent";
  }
  return "?";
}

struct Header {
  std::uint32_t version = 0;
  std::uint64_t file_bytes = 0;
  std::uint32_t solution_count = 0;
  std::int32_t dims[3] = {0, 0, 0};
  std::int32_t index_min[3] = {0, 0, 0};
  std::uint32_t blocks[3] = {0, 0, 0};
  double index_to_world[16] = {};  // row-major, acts on column vectors (i, j, k, 1)
  double world_to_index[16] = {};  // its inverse (computed by the reader)
};

struct SolutionInfo {
  std::string name;                 // grid name, e.g. "B05" or "light"
  std::int32_t index = -1;          // base solution 0..18, -1 when not a base solution
  std::int32_t direction[3] = {0, 0, 0};
  std::uint32_t threshold_mode = 0;  // 0 absolute, 1 relative to max_abs_value
  float threshold_param = 0;        // as requested (absolute value or fraction)
  float threshold = 0;              // absolute threshold applied to the coefficients
  float max_abs_value = 0;          // max |value| over nodes and channels of the original
  std::uint64_t block_count = 0, coeff_count = 0, fast_blocks = 0;
  std::uint64_t masks_offset = 0, offsets_offset = 0, coeffs_offset = 0;
  std::uint32_t masks_crc = 0, offsets_crc = 0, coeffs_crc = 0;
  float max_abs_error = 0, rms_error = 0;  // recorded by the encoder (informational)
  Encoding encoding = Encoding::F32;
  float quant_step = 0;                    // Q8: value of one stored integer step; F32: 0
  std::uint64_t details_offset = 0;        // Q8: the details section (canonical, after the averages)
  std::uint32_t details_crc = 0;
  std::uint64_t detail_count() const { return coeff_count - block_count; }
  // Bytes of coefficients as stored: F32 12 per kept coefficient; Q8 12 per average + 3 per detail.
  std::uint64_t coefficient_bytes() const {
    return encoding == Encoding::Q8 ? block_count * 12u + detail_count() * 3u : coeff_count * 12u;
  }
  // Bytes of masks + offsets + coefficients (the stream without header, table and padding).
  std::uint64_t stream_bytes() const { return block_count * 12u + coefficient_bytes(); }
};

namespace detail {
inline std::uint32_t rd32(const unsigned char* p) {
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}
inline std::uint64_t rd64(const unsigned char* p) {
  return static_cast<std::uint64_t>(rd32(p)) | static_cast<std::uint64_t>(rd32(p + 4)) << 32;
}
inline std::int32_t rdi32(const unsigned char* p) {
  const std::uint32_t u = rd32(p);
  std::int32_t v;
  std::memcpy(&v, &u, 4);
  return v;
}
inline float rdf32(const unsigned char* p) {
  const std::uint32_t u = rd32(p);
  float v;
  std::memcpy(&v, &u, 4);
  return v;
}
inline double rdf64(const unsigned char* p) {
  const std::uint64_t u = rd64(p);
  double v;
  std::memcpy(&v, &u, 8);
  return v;
}
inline std::uint64_t align_up(std::uint64_t v) { return (v + (kSectionAlign - 1)) / kSectionAlign * kSectionAlign; }
inline bool all_zero(const unsigned char* p, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i)
    if (p[i]) return false;
  return true;
}
inline std::uint32_t blocks_for(std::int32_t n) {
  return n <= 1 ? 1u : static_cast<std::uint32_t>((n - 1 + kBlockStride - 1) / kBlockStride);
}
}  // namespace detail

class Stream {
 public:
  // Reads and validates a whole file.
  Status open_file(const std::string& path) {
    reset();
    // A pipe or device would block or never end: only regular files (symlinks followed).
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
      return fail(Status::IoError, "'" + path + "' " +
                                       (std::filesystem::exists(path, ec) ? "is not a regular file" : "does not exist"));
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) return fail(Status::IoError, "cannot open '" + path + "'");
    const std::streamoff size = in.tellg();
    if (size < 0) return fail(Status::IoError, "cannot determine the size of '" + path + "'");
    std::vector<unsigned char> tmp;
    try {
      tmp.resize(static_cast<std::size_t>(size));
    } catch (...) {
      return fail(Status::IoError, "'" + path + "' is too large to load");
    }
    in.seekg(0);
    if (size > 0 && !in.read(reinterpret_cast<char*>(tmp.data()), size))
      return fail(Status::IoError, "cannot read '" + path + "'");
    const Status s = open_memory(tmp.data(), tmp.size());
    if (s != Status::Ok) error_ = path + ": " + error_;
    return s;
  }

  // Copies `size` bytes into an 8-byte aligned buffer and validates them: after Ok, every
  // count, offset, mask and coefficient has been checked, so decoding cannot read out of bounds.
  Status open_memory(const void* data, std::size_t size) {
    reset();
    {
      const std::uint32_t one = 1;
      unsigned char first;
      std::memcpy(&first, &one, 1);
      if (first != 1) return fail(Status::UnsupportedEndianness, "this reader needs a little-endian host");
    }
    try {
      storage_.assign((size + 7) / 8, 0u);
    } catch (...) {
      return fail(Status::IoError, "out of memory loading " + std::to_string(size) + " bytes");
    }
    if (size) std::memcpy(storage_.data(), data, size);
    size_ = size;
    const Status s = validate();
    if (s != Status::Ok) {
      storage_.clear();
      size_ = 0;
      infos_.clear();
    }
    return s;
  }

  bool ok() const { return ok_; }
  Status status() const { return status_; }
  const std::string& error() const { return error_; }

  const unsigned char* data() const { return reinterpret_cast<const unsigned char*>(storage_.data()); }
  std::size_t size() const { return size_; }
  const Header& header() const { return header_; }
  std::size_t solution_count() const { return infos_.size(); }
  const SolutionInfo& info(std::size_t slot) const { return infos_.at(slot); }

  // Slot of base solution `index` (0..18), or -1.
  int find(int index) const {
    for (std::size_t i = 0; i < infos_.size(); ++i)
      if (infos_[i].index == index) return static_cast<int>(i);
    return -1;
  }
  int find_name(const std::string& name) const {
    for (std::size_t i = 0; i < infos_.size(); ++i)
      if (infos_[i].name == name) return static_cast<int>(i);
    return -1;
  }

  const Lattice& lattice() const { return lattice_; }

  // Pointers into this stream's bytes, or into a copy of data()[0, size()) at `base` (device memory).
  SolutionView view(std::size_t slot, const void* base = nullptr) const {
    const SolutionInfo& i = infos_.at(slot);
    const unsigned char* b = base ? static_cast<const unsigned char*>(base) : data();
    SolutionView v;
    v.masks = reinterpret_cast<const std::uint64_t*>(b + i.masks_offset);
    v.offsets = reinterpret_cast<const std::uint32_t*>(b + i.offsets_offset);
    v.coeffs = reinterpret_cast<const float*>(b + i.coeffs_offset);
    if (i.encoding == Encoding::Q8) {
      v.details = reinterpret_cast<const std::int8_t*>(b + i.details_offset);
      v.step = i.quant_step;
    }
    return v;
  }

  // Host conveniences.
  Rgb sample_index(std::size_t slot, float x, float y, float z) const {
    return lbh::sample_index(lattice_, view(slot), x, y, z);
  }
  Rgb sample_world(std::size_t slot, float x, float y, float z) const {
    return lbh::sample_world(lattice_, view(slot), x, y, z);
  }
  void decode_block(std::size_t slot, std::uint64_t block, Rgb* out64) const {
    lbh::decode_block(view(slot), block, out64);
  }
  // Every node of one solution, RGB interleaved, x fastest: ((k * ny + j) * nx + i) * 3 + channel.
  // Node (i, j, k) is taken from the sub-block that the sampler uses for it.
  std::vector<float> decode_all(std::size_t slot) const {
    const SolutionView v = view(slot);
    const std::int32_t* n = lattice_.n;
    std::vector<float> out(static_cast<std::size_t>(n[0]) * n[1] * n[2] * 3);
    std::vector<Rgb> block(64);
    for (int bz = 0; bz < lattice_.nb[2]; ++bz)
      for (int by = 0; by < lattice_.nb[1]; ++by)
        for (int bx = 0; bx < lattice_.nb[0]; ++bx) {
          lbh::decode_block(v, block_index(lattice_, bx, by, bz), block.data());
          const int b[3] = {bx, by, bz};
          int lo[3], hi[3];
          for (int a = 0; a < 3; ++a) {  // nodes whose cell lies in this block
            lo[a] = 3 * b[a];
            hi[a] = b[a] == lattice_.nb[a] - 1 ? n[a] - 1 : 3 * b[a] + 2;
          }
          for (int k = lo[2]; k <= hi[2]; ++k)
            for (int j = lo[1]; j <= hi[1]; ++j)
              for (int i = lo[0]; i <= hi[0]; ++i) {
                const Rgb& c = block[(i - lo[0]) + 4 * (j - lo[1]) + 16 * (k - lo[2])];
                float* o = &out[((static_cast<std::size_t>(k) * n[1] + j) * n[0] + i) * 3];
                o[0] = c.r;
                o[1] = c.g;
                o[2] = c.b;
              }
        }
    return out;
  }

  // Blend for sunlight travelling along (dx, dy, dz) with intensity s and ambient level a:
  // s (w_a B_a + w_b B_b + w_c B_c) + a B_0. Fails (BadHeader) when a needed solution is missing.
  // `base` as in view(): pointers into a device copy of the stream.
  Status make_relighter(double dx, double dy, double dz, float intensity, float ambient, Relighter& out,
                        const void* base = nullptr) {
    out = Relighter{};
    const SunWeights w = decompose_direction(dx, dy, dz);
    if (w.direction[0] == 0) return fail_keep(Status::BadHeader, "sun direction must be a finite, non-zero vector");
    for (int k = 0; k < 3; ++k) {
      if (w.weight[k] == 0.0f) continue;
      const int slot = find(w.direction[k]);
      if (slot < 0)
        return fail_keep(Status::BadHeader, "relighting needs base solution " + std::to_string(w.direction[k]) +
                                                ", which this stream does not hold");
      out.view[out.count] = view(static_cast<std::size_t>(slot), base);
      out.weight[out.count++] = intensity * w.weight[k];
    }
    if (ambient != 0.0f) {
      const int slot = find(0);
      if (slot < 0) return fail_keep(Status::BadHeader, "relighting with ambient light needs base solution 0");
      out.view[out.count] = view(static_cast<std::size_t>(slot), base);
      out.weight[out.count++] = ambient;
    }
    return Status::Ok;
  }

 private:
  std::vector<std::uint64_t> storage_;
  std::size_t size_ = 0;
  Header header_;
  Lattice lattice_{};
  std::vector<SolutionInfo> infos_;
  bool ok_ = false;
  Status status_ = Status::IoError;
  std::string error_ = "no stream opened";

  void reset() {
    storage_.clear();
    size_ = 0;
    header_ = Header{};
    lattice_ = Lattice{};
    infos_.clear();
    ok_ = false;
    status_ = Status::IoError;
    error_ = "no stream opened";
  }
  Status fail(Status s, const std::string& msg) {
    ok_ = false;
    status_ = s;
    error_ = std::string("lbh: ") + status_name(s) + ": " + msg;
    return s;
  }
  Status fail_keep(Status s, const std::string& msg) {  // an error that leaves the stream usable
    error_ = std::string("lbh: ") + msg;
    return s;
  }

  // Checks the whole file before anything is read from it: header, solution table, section
  // layout, checksums, then what masks and offsets mean.
  Status validate() {
    std::uint64_t table_end = 0;
    if (const Status st = validate_header(table_end); st != Status::Ok) return st;
    std::uint64_t pos = table_end;
    infos_.resize(header_.solution_count);
    for (std::uint32_t s = 0; s < header_.solution_count; ++s)
      if (const Status st = read_entry(s, pos); st != Status::Ok) return st;
    if (pos != header_.file_bytes)
      return fail(Status::BadHeader, "the last section ends at " + std::to_string(pos) + " but the file at " +
                                         std::to_string(header_.file_bytes));
    for (std::uint32_t s = 0; s < header_.solution_count; ++s)
      if (const Status st = check_sections(s); st != Status::Ok) return st;
    for (int a = 0; a < 3; ++a) {
      lattice_.n[a] = header_.dims[a];
      lattice_.nb[a] = static_cast<std::int32_t>(header_.blocks[a]);
      lattice_.index_min[a] = header_.index_min[a];
    }
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c)
        lattice_.world_to_index[4 * r + c] = static_cast<float>(header_.world_to_index[4 * r + c]);
    ok_ = true;
    status_ = Status::Ok;
    error_.clear();
    return Status::Ok;
  }

  // The 256-byte header and the table's checksum; table_end: where the table ends.
  Status validate_header(std::uint64_t& table_end) {
    using namespace detail;
    namespace H = header_field;
    const unsigned char* p = data();
    static const unsigned char magic[8] = {0x89, 'L', 'B', 'H', 0x0D, 0x0A, 0x1A, 0x0A};
    if (size_ < H::kMagic.end())
      return fail(Status::Truncated, "file has " + std::to_string(size_) + " bytes, less than the magic");
    if (std::memcmp(p, magic, 8) != 0) return fail(Status::BadMagic, "the first 8 bytes are not 89 4C 42 48 0D 0A 1A 0A");
    if (size_ < H::kEndianTag.end())
      return fail(Status::Truncated, "file has " + std::to_string(size_) + " bytes; the header has 256");
    const std::uint32_t tag = rd32(p + H::kEndianTag.offset);
    if (tag == 0x04030201u) return fail(Status::UnsupportedEndianness, "the file is big-endian; .lbh is little-endian");
    if (tag != kEndianTag) return fail(Status::BadHeader, "endianness tag is not 0x01020304");
    const std::uint32_t version = rd32(p + H::kVersion.offset);
    if (version < kOldestVersion || version > kVersion)
      return fail(Status::UnsupportedVersion, "format version " + std::to_string(version) + "; this reader reads versions " +
                                                  std::to_string(kOldestVersion) + ".." + std::to_string(kVersion));
    if (size_ < kHeaderBytes)
      return fail(Status::Truncated, "file has " + std::to_string(size_) + " bytes; the header alone has 256");
    const std::uint32_t header_bytes = rd32(p + H::kHeaderBytes.offset), entry_bytes = rd32(p + H::kEntryBytes.offset);
    if (header_bytes != kHeaderBytes || entry_bytes != kEntryBytes)
      return fail(Status::BadHeader, "header size " + std::to_string(header_bytes) + " / entry size " +
                                         std::to_string(entry_bytes) + "; versions 1 and 2 have 256 / 128");
    Header& h = header_;
    h.version = version;
    h.file_bytes = rd64(p + H::kFileBytes.offset);
    if (h.file_bytes > size_)
      return fail(Status::Truncated, "file has " + std::to_string(size_) + " bytes but its header declares " +
                                         std::to_string(h.file_bytes));
    if (h.file_bytes < size_)
      return fail(Status::BadHeader, "file has " + std::to_string(size_ - h.file_bytes) +
                                         " bytes after the end its header declares (" + std::to_string(h.file_bytes) + ")");
    h.solution_count = rd32(p + H::kSolutionCount.offset);
    const std::uint32_t flags = rd32(p + H::kFlags.offset);
    if (flags != 0) return fail(Status::BadHeader, "flags are " + std::to_string(flags) + "; must be 0");
    for (int a = 0; a < 3; ++a) {
      h.dims[a] = rdi32(p + H::kDims.offset + 4 * a);
      h.index_min[a] = rdi32(p + H::kIndexMin.offset + 4 * a);
      h.blocks[a] = rd32(p + H::kBlocks.offset + 4 * a);
    }
    for (int a = 0; a < 3; ++a) {
      if (h.dims[a] < 1 || h.dims[a] > kMaxDim)
        return fail(Status::CountOutOfRange, "lattice dimension " + std::to_string(h.dims[a]) + " outside 1.." +
                                                 std::to_string(kMaxDim));
      if (h.blocks[a] != blocks_for(h.dims[a]))
        return fail(Status::BadHeader, "sub-blocks per axis " + std::to_string(h.blocks[a]) + " for " +
                                           std::to_string(h.dims[a]) + " nodes; expected " +
                                           std::to_string(blocks_for(h.dims[a])));
      const std::int64_t hi = static_cast<std::int64_t>(h.index_min[a]) + h.dims[a] - 1;
      if (hi > INT32_MAX) return fail(Status::CountOutOfRange, "lattice box exceeds 32-bit index coordinates");
    }
    if (rd32(p + H::kReserved1.offset) != 0) return fail(Status::BadHeader, "reserved field at offset 76 is not 0");
    for (int e = 0; e < 16; ++e) h.index_to_world[e] = rdf64(p + H::kIndexToWorld.offset + 8 * e);
    if (!invert_transform()) return fail(Status::BadHeader, "index_to_world is not a finite, invertible affine map");
    if (h.solution_count < 1 || h.solution_count > kMaxSolutions)
      return fail(Status::CountOutOfRange, "solution count " + std::to_string(h.solution_count) + " outside 1.." +
                                               std::to_string(kMaxSolutions));
    const std::uint64_t table_offset = rd64(p + H::kTableOffset.offset);
    if (table_offset != kHeaderBytes)
      return fail(Status::BadHeader, "table offset " + std::to_string(table_offset) + "; the format puts it at 256");
    table_end = table_offset + static_cast<std::uint64_t>(h.solution_count) * kEntryBytes;
    if (table_end > h.file_bytes)
      return fail(Status::CountOutOfRange, "solution table of " + std::to_string(h.solution_count) +
                                               " entries ends at " + std::to_string(table_end) + ", past the file end " +
                                               std::to_string(h.file_bytes));
    if (!all_zero(p + H::kReserved2.offset, H::kReserved2.bytes))
      return fail(Status::BadHeader, "reserved header bytes 220..251 are not 0");
    if (kVerifyChecksums && crc32(p, H::kHeaderCrc.offset) != rd32(p + H::kHeaderCrc.offset))
      return fail(Status::ChecksumMismatch, "header CRC-32 does not match");
    if (kVerifyChecksums && crc32(p + table_offset, table_end - table_offset) != rd32(p + H::kTableCrc.offset))
      return fail(Status::ChecksumMismatch, "solution table CRC-32 does not match");
    return Status::Ok;
  }

  // Table entry s, checked against the canonical layout (sections in order, 64-aligned, starting
  // at pos; pos ends after its last section).
  Status read_entry(std::uint32_t s, std::uint64_t& pos) {
    using namespace detail;
    namespace E = entry_field;
    const Header& h = header_;
    const unsigned char* p = data();
    const unsigned char* e = p + kHeaderBytes + static_cast<std::uint64_t>(s) * kEntryBytes;
    SolutionInfo& i = infos_[s];
    const std::string who = "solution " + std::to_string(s);
    const void* nul = std::memchr(e + E::kName.offset, 0, E::kName.bytes);
    if (!nul) return fail(Status::BadHeader, who + ": name is not NUL-terminated within 16 bytes");
    const std::size_t len = static_cast<std::size_t>(static_cast<const unsigned char*>(nul) - e);
    if (!all_zero(e + len, E::kName.bytes - len)) return fail(Status::BadHeader, who + ": name padding is not 0");
    if (const char* why = name_problem(reinterpret_cast<const char*>(e), len))
      return fail(Status::BadHeader, who + ": name " + why);
    i.name.assign(reinterpret_cast<const char*>(e), len);
    for (std::uint32_t k = 0; k < s; ++k)
      if (infos_[k].name == i.name) return fail(Status::BadHeader, who + ": name '" + i.name + "' is also solution " + std::to_string(k) + "'s");
    i.index = rdi32(e + E::kIndex.offset);
    if (i.index < -1 || i.index > 18)
      return fail(Status::BadHeader, who + ": base solution index " + std::to_string(i.index) + " outside -1..18");
    for (int a = 0; a < 3; ++a) {
      i.direction[a] = rdi32(e + E::kDirection.offset + 4 * a);
      if (i.direction[a] < -1 || i.direction[a] > 1)
        return fail(Status::BadHeader, who + ": direction component outside -1..1");
    }
    // The direction must be the one its index names (docs/lbh-format.md sec. 2.2): a file whose
    // entry says B06 but points along B05 would relight from the wrong side without a word.
    {
      const int m = i.index < 0 ? 0 : i.index;
      const int want[3] = {lattice_cx(m), lattice_cy(m), lattice_cz(m)};
      if (i.direction[0] != want[0] || i.direction[1] != want[1] || i.direction[2] != want[2])
        return fail(Status::BadHeader, who + ": direction (" + std::to_string(i.direction[0]) + ", " +
                                           std::to_string(i.direction[1]) + ", " + std::to_string(i.direction[2]) +
                                           ") is not that of its index " + std::to_string(i.index) + " (allowed: (" +
                                           std::to_string(want[0]) + ", " + std::to_string(want[1]) + ", " +
                                           std::to_string(want[2]) + "))");
    }
    i.threshold_mode = rd32(e + E::kThresholdMode.offset);
    i.threshold_param = rdf32(e + E::kThresholdParam.offset);
    i.threshold = rdf32(e + E::kThreshold.offset);
    i.max_abs_value = rdf32(e + E::kMaxAbsValue.offset);
    if (i.threshold_mode > 1) return fail(Status::BadHeader, who + ": threshold mode must be 0 or 1");
    if (!(i.threshold_param >= 0 && i.threshold >= 0 && i.max_abs_value >= 0) || !std::isfinite(i.threshold_param) ||
        !std::isfinite(i.threshold) || !std::isfinite(i.max_abs_value))
      return fail(Status::BadHeader, who + ": threshold and max value must be finite and >= 0");
    i.block_count = rd64(e + E::kBlockCount.offset);
    i.coeff_count = rd64(e + E::kCoeffCount.offset);
    i.masks_offset = rd64(e + E::kMasksOffset.offset);
    i.offsets_offset = rd64(e + E::kOffsetsOffset.offset);
    i.coeffs_offset = rd64(e + E::kCoeffsOffset.offset);
    i.masks_crc = rd32(e + E::kMasksCrc.offset);
    i.offsets_crc = rd32(e + E::kOffsetsCrc.offset);
    i.coeffs_crc = rd32(e + E::kCoeffsCrc.offset);
    const std::uint32_t encoding = rd32(e + E::kEncoding.offset);
    if (encoding > 1 || (encoding != 0 && h.version < 2))
      return fail(Status::BadHeader, who + ": coefficient encoding " + std::to_string(encoding) + " at entry offset 100; " +
                                         (h.version < 2 ? "version 1 allows only 0" : "allowed: 0 (f32) or 1 (8-bit details)"));
    i.encoding = static_cast<Encoding>(encoding);
    i.fast_blocks = rd64(e + E::kFastBlocks.offset);
    i.max_abs_error = rdf32(e + E::kMaxAbsError.offset);
    i.rms_error = rdf32(e + E::kRmsError.offset);
    if (i.encoding == Encoding::F32) {
      if (!all_zero(e + E::kQuantStep.offset, E::kQuantStep.bytes + E::kDetailsCrc.bytes))
        return fail(Status::BadHeader, who + ": entry bytes 120..127 are not 0 (f32 encoding)");
    } else {
      i.quant_step = rdf32(e + E::kQuantStep.offset);
      i.details_crc = rd32(e + E::kDetailsCrc.offset);
      if (!(i.quant_step > 0) || !std::isfinite(i.quant_step * static_cast<float>(kQ8Max)))
        return fail(Status::BadHeader, who + ": quantisation step must be finite and > 0 (and 127 steps finite)");
    }
    const std::uint64_t block_count =
        static_cast<std::uint64_t>(h.blocks[0]) * h.blocks[1] * static_cast<std::uint64_t>(h.blocks[2]);
    if (i.block_count != block_count)
      return fail(Status::CountOutOfRange, who + ": block count " + std::to_string(i.block_count) +
                                               "; the lattice has " + std::to_string(block_count) + " sub-blocks");
    if (i.coeff_count < i.block_count || i.coeff_count / 64 > i.block_count ||
        (i.coeff_count / 64 == i.block_count && i.coeff_count % 64 != 0))
      return fail(Status::CountOutOfRange, who + ": coefficient count " + std::to_string(i.coeff_count) +
                                               " outside [blocks, 64 x blocks] = [" + std::to_string(i.block_count) +
                                               ", 64 x " + std::to_string(i.block_count) + "]");
    if (i.fast_blocks > i.block_count)
      return fail(Status::CountOutOfRange, who + ": fast-path block count exceeds the block count");
    // Sections: sizes checked against the remaining file before any multiplication can overflow.
    // Q8 has a fourth section, the details, whose offset is not stored: it is canonical.
    const bool q8 = i.encoding == Encoding::Q8;
    const int sections = q8 ? 4 : 3;
    const std::uint64_t sizes[4] = {8, 4, 12, 3};
    const std::uint64_t counts[4] = {i.block_count, i.block_count, q8 ? i.block_count : i.coeff_count,
                                     i.coeff_count - i.block_count};
    std::uint64_t offsets[4] = {i.masks_offset, i.offsets_offset, i.coeffs_offset, 0};
    const char* names[4] = {"masks", "offsets", q8 ? "averages" : "coefficients", "details"};
    for (int k = 0; k < sections; ++k) {
      const std::uint64_t start = align_up(pos);
      if (k == 3) offsets[3] = i.details_offset = start;
      if (offsets[k] != start)
        return fail(Status::BadHeader, who + ": " + names[k] + " section at " + std::to_string(offsets[k]) +
                                           "; the canonical layout puts it at " + std::to_string(start));
      if (start > h.file_bytes || counts[k] > (h.file_bytes - start) / sizes[k])
        return fail(Status::CountOutOfRange, who + ": " + names[k] + " section of " + std::to_string(counts[k]) +
                                                 " entries does not fit the file (" + std::to_string(h.file_bytes) +
                                                 " bytes)");
      if (!all_zero(p + pos, start - pos)) return fail(Status::BadHeader, who + ": padding before " + names[k] + " is not 0");
      pos = start + counts[k] * sizes[k];
    }
    return Status::Ok;
  }

  // Solution s's section checksums, then the meaning of its masks and offsets.
  Status check_sections(std::uint32_t s) {
    using namespace detail;
    const unsigned char* p = data();
    const SolutionInfo& i = infos_[s];
    const std::string who = "solution " + std::to_string(s) + " (" + i.name + ")";
    if (kVerifyChecksums && crc32(p + i.masks_offset, i.block_count * 8) != i.masks_crc)
      return fail(Status::ChecksumMismatch, who + ": masks CRC-32 does not match");
    if (kVerifyChecksums && crc32(p + i.offsets_offset, i.block_count * 4) != i.offsets_crc)
      return fail(Status::ChecksumMismatch, who + ": offsets CRC-32 does not match");
    const bool q8 = i.encoding == Encoding::Q8;
    const std::uint64_t stored_f32 = q8 ? i.block_count : i.coeff_count;  // RGB triples of f32
    if (kVerifyChecksums && crc32(p + i.coeffs_offset, stored_f32 * 12) != i.coeffs_crc)
      return fail(Status::ChecksumMismatch, who + (q8 ? ": averages" : ": coefficients") + " CRC-32 does not match");
    if (q8 && kVerifyChecksums && crc32(p + i.details_offset, i.detail_count() * 3) != i.details_crc)
      return fail(Status::ChecksumMismatch, who + ": details CRC-32 does not match");
    std::uint64_t running = 0, fast = 0;
    for (std::uint64_t b = 0; b < i.block_count; ++b) {
      const std::uint64_t mask = rd64(p + i.masks_offset + 8 * b);
      const std::uint32_t off = rd32(p + i.offsets_offset + 4 * b);
      if (!(mask & 1u))
        return fail(Status::Inconsistent, who + ": block " + std::to_string(b) + " does not keep its average");
      if (off != running)
        return fail(Status::Inconsistent, who + ": block " + std::to_string(b) + " offset " + std::to_string(off) +
                                              "; the masks before it keep " + std::to_string(running));
      running += static_cast<std::uint64_t>(popcount64(mask));
      fast += mask == 1u;
      if (running > 0xFFFFFFFFull && b + 1 < i.block_count)
        return fail(Status::CountOutOfRange, who + ": more than 2^32 coefficients before a block");
    }
    if (running != i.coeff_count)
      return fail(Status::Inconsistent, who + ": masks keep " + std::to_string(running) + " coefficients; count says " +
                                            std::to_string(i.coeff_count));
    if (fast != i.fast_blocks)
      return fail(Status::Inconsistent, who + ": " + std::to_string(fast) + " fast-path blocks; entry says " +
                                            std::to_string(i.fast_blocks));
    for (std::uint64_t c = 0; c < stored_f32 * 3; ++c)
      if (!std::isfinite(rdf32(p + i.coeffs_offset + 4 * c)))
        return fail(Status::Inconsistent, who + (q8 ? ": average " : ": coefficient ") + std::to_string(c / 3) +
                                              " is not finite");
    if (q8)
      for (std::uint64_t c = 0; c < i.detail_count() * 3; ++c)
        if (p[i.details_offset + c] == 0x80u)
          return fail(Status::Inconsistent, who + ": detail " + std::to_string(c / 3) + " holds -128; allowed -127..127");
    return Status::Ok;
  }

  bool invert_transform() {
    const double* m = header_.index_to_world;
    for (int e = 0; e < 16; ++e)
      if (!std::isfinite(m[e])) return false;
    if (m[12] != 0 || m[13] != 0 || m[14] != 0 || m[15] != 1) return false;
    const double a = m[0], b = m[1], c = m[2], d = m[4], e = m[5], f = m[6], g = m[8], hh = m[9], k = m[10];
    const double A = e * k - f * hh, B = -(d * k - f * g), C = d * hh - e * g;
    const double det = a * A + b * B + c * C;
    double scale = 0;
    for (double v : {a, b, c, d, e, f, g, hh, k}) scale = std::fmax(scale, std::fabs(v));
    if (!(std::fabs(det) > 1e-12 * scale * scale * scale) || !std::isfinite(1.0 / det)) return false;
    const double inv[9] = {A / det, -(b * k - c * hh) / det, (b * f - c * e) / det,
                           B / det, (a * k - c * g) / det,   -(a * f - c * d) / det,
                           C / det, -(a * hh - b * g) / det, (a * e - b * d) / det};
    double* w = header_.world_to_index;
    for (int r = 0; r < 3; ++r) {
      for (int cc = 0; cc < 3; ++cc) w[4 * r + cc] = inv[3 * r + cc];
      w[4 * r + 3] = -(inv[3 * r] * m[3] + inv[3 * r + 1] * m[7] + inv[3 * r + 2] * m[11]);
    }
    w[12] = w[13] = w[14] = 0;
    w[15] = 1;
    for (int i = 0; i < 16; ++i)
      if (!std::isfinite(w[i])) return false;
    return true;
  }
};
#endif  // !LBH_DEVICE_ONLY

}  // namespace lbh
