// Streams for the Haar and reader tests: a light-like field, a lattice frame, an encoded and
// serialised stream of it, and the byte edits that keep a damaged file's checksums valid.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <catch2/catch.hpp>

#include "lblight/compress/lbh_writer.h"
#include "readers/lbh/lbh_reader.h"

namespace lblight::test {


// A light-like field: smooth falloff, a sharp shadow edge, a constant corner, small noise.
inline std::array<std::vector<float>, 3> make_field(const Dims& d, unsigned seed, float noise = 0.02f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::array<std::vector<float>, 3> rgb;
  for (auto& c : rgb) c.resize(d.count());
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x) {
        const std::size_t i = d.index(x, y, z);
        const bool corner = x <= d.nx / 2 && y <= d.ny / 2;
        const float smooth = 2.0f + std::sin(0.3f * x) * std::cos(0.2f * y) + 0.05f * z;
        const float shadow = x + y > d.nx ? 0.4f : 1.0f;
        for (int c = 0; c < 3; ++c)
          rgb[c][i] = corner ? 1.5f : (smooth * shadow * (1.0f + 0.1f * c) + noise * u(rng));
      }
  return rgb;
}

inline DenseFrame frame_of(const Dims& d) {
  DenseFrame f;
  f.dims = d;
  f.index_min = {-3, 5, 7};
  // scale 0.25, a rotation about z by 90 degrees, a translation
  f.index_to_world = {0, -0.25, 0, 1.0, 0.25, 0, 0, -2.0, 0, 0, 0.25, 0.5, 0, 0, 0, 1};
  return f;
}

struct Encoded {
  DenseFrame frame;
  std::vector<LbhEncoded> sols;
  std::array<std::vector<float>, 3> field;
  std::string bytes;
};

inline Encoded encode(const Dims& d, LbhSettings t, unsigned seed = 1, float noise = 0.02f, int threads = 2) {
  Encoded e;
  e.frame = frame_of(d);
  e.field = make_field(d, seed, noise);
  e.sols.push_back(encode_lbh_solution(e.frame, {"B00", 0, {0, 0, 0}, &e.field}, t, threads));
  e.bytes = serialize_lbh(e.frame, e.sols);
  return e;
}

inline lbh::Stream open_ok(const std::string& bytes) {
  lbh::Stream s;
  const lbh::Status st = s.open_memory(bytes.data(), bytes.size());
  INFO(s.error());
  REQUIRE(st == lbh::Status::Ok);
  return s;
}

// Reference trilinear sampling of a decoded lattice (interleaved RGB), clamped at both ends.
inline lbh::Rgb trilinear(const std::vector<float>& v, const Dims& d, double u, double w, double t) {
  const int n[3] = {d.nx, d.ny, d.nz};
  double p[3] = {u, w, t};
  int i0[3], i1[3];
  double a[3];
  for (int k = 0; k < 3; ++k) {
    p[k] = std::min(std::max(p[k], 0.0), static_cast<double>(n[k] - 1));
    i0[k] = std::min(static_cast<int>(std::floor(p[k])), std::max(n[k] - 2, 0));
    i1[k] = std::min(i0[k] + 1, n[k] - 1);
    a[k] = p[k] - i0[k];
  }
  double out[3] = {0, 0, 0};
  for (int c = 0; c < 8; ++c) {
    const int x = c & 1 ? i1[0] : i0[0], y = c & 2 ? i1[1] : i0[1], z = c & 4 ? i1[2] : i0[2];
    const double wt = (c & 1 ? a[0] : 1 - a[0]) * (c & 2 ? a[1] : 1 - a[1]) * (c & 4 ? a[2] : 1 - a[2]);
    for (int ch = 0; ch < 3; ++ch) out[ch] += wt * v[d.index(x, y, z) * 3 + ch];
  }
  return {static_cast<float>(out[0]), static_cast<float>(out[1]), static_cast<float>(out[2])};
}

inline void put32(std::string& s, std::size_t at, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) s[at + k] = static_cast<char>(v >> (8 * k));
}
inline void put64(std::string& s, std::size_t at, std::uint64_t v) {
  for (int k = 0; k < 8; ++k) s[at + k] = static_cast<char>(v >> (8 * k));
}
inline void fix_header_crc(std::string& s) { put32(s, 252, lbh::crc32(s.data(), 252)); }
inline void fix_table_crc(std::string& s, int solutions = 1) {
  put32(s, 216, lbh::crc32(s.data() + 256, 128u * solutions));
  fix_header_crc(s);
}


}  // namespace lblight::test
