// The header-only .lbh reader (readers/lbh/lbh_reader.h) on its own: sun decomposition and
// relighting as lblight does them, its checksum, and its refusal of damaged, crafted and random
// files.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "lblight/compress/lbh_writer.h"
#include "lblight/lattice/sun.h"
#include "readers/lbh/lbh_reader.h"
#include "tests/compress/lbh_test_streams.h"

using namespace lblight;
using namespace lblight::test;

TEST_CASE("Reader sun decomposition matches lblight's", "[reader]") {
  std::mt19937 rng(4);
  std::normal_distribution<double> g;
  for (int i = 0; i < 2000; ++i) {
    Vec3d d{g(rng), g(rng), g(rng)};
    if (i < 6) d = {i == 0 ? 1.0 : 0.0, i == 1 ? 1.0 : 0.0, i == 2 ? -1.0 : 0.3};
    const SunWeights a = decompose_direction(d);
    const lbh::SunWeights b = lbh::decompose_direction(d.x, d.y, d.z);
    // compare as 18-vectors (a face tie may list directions in another order)
    std::array<double, 19> wa{}, wb{};
    for (int k = 0; k < 3; ++k) {
      wa[a.direction[k]] += a.weight[k];
      wb[b.direction[k]] += b.weight[k];
    }
    for (int m = 0; m < 19; ++m) CHECK(wb[m] == Approx(wa[m]).margin(1e-6));
  }
  CHECK(lbh::decompose_direction(0, 0, 0).direction[0] == 0);
}

TEST_CASE("Relighting blends three directional solutions and the ambient one", "[reader]") {
  const Dims d{10, 8, 7};
  const DenseFrame f = frame_of(d);
  std::vector<std::array<std::vector<float>, 3>> fields;
  for (unsigned k = 0; k < 19; ++k) fields.push_back(make_field(d, 100 + k));
  std::vector<LbhEncoded> sols;
  for (int k = 0; k < 19; ++k) {
    char name[8];
    std::snprintf(name, sizeof name, "B%02d", k);
    sols.push_back(encode_lbh_solution(f, {name, k, {lbh::lattice_cx(k), lbh::lattice_cy(k), lbh::lattice_cz(k)}, &fields[k]},
                                       {0.01, true}, 1));
  }
  const std::string bytes = serialize_lbh(f, sols);
  lbh::Stream s = open_ok(bytes);
  const Vec3d travel{0.3, -0.5, -0.8};
  const SunWeights w = decompose_direction(travel);
  lbh::Relighter r;
  REQUIRE(s.make_relighter(travel.x, travel.y, travel.z, 2.0f, 0.25f, r) == lbh::Status::Ok);
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> u(0, 9);
  for (int i = 0; i < 200; ++i) {
    const float p[3] = {u(rng) - 3, u(rng) + 5, u(rng) + 7};
    const lbh::Rgb got = lbh::relight_index(s.lattice(), r, p[0], p[1], p[2]);
    double ref[3] = {0, 0, 0};
    for (int k = 0; k < 3; ++k) {
      const lbh::Rgb v = s.sample_index(static_cast<std::size_t>(s.find(w.direction[k])), p[0], p[1], p[2]);
      ref[0] += 2.0 * w.weight[k] * v.r;
      ref[1] += 2.0 * w.weight[k] * v.g;
      ref[2] += 2.0 * w.weight[k] * v.b;
    }
    const lbh::Rgb amb = s.sample_index(static_cast<std::size_t>(s.find(0)), p[0], p[1], p[2]);
    CHECK(got.r == Approx(ref[0] + 0.25 * amb.r).epsilon(1e-5));
    CHECK(got.g == Approx(ref[1] + 0.25 * amb.g).epsilon(1e-5));
    CHECK(got.b == Approx(ref[2] + 0.25 * amb.b).epsilon(1e-5));
  }
  // a stream without the needed directions says so
  lbh::Stream one = open_ok(serialize_lbh(f, {sols[0]}));
  CHECK(one.make_relighter(0, 0, -1, 1, 0, r) == lbh::Status::BadHeader);
  CHECK(one.error().find("base solution 6") != std::string::npos);
}

TEST_CASE("CRC-32 is zlib's", "[reader]") {
  CHECK(lbh::crc32("123456789", 9) == 0xCBF43926u);
  CHECK(lbh::crc32("", 0) == 0u);
}

TEST_CASE("Reader rejects truncated, corrupted, wrong-version and oversized files", "[reader]") {
  const LbhCoefficients coeffs = GENERATE(LbhCoefficients::F32, LbhCoefficients::Q8);
  const bool q8 = coeffs == LbhCoefficients::Q8;
  INFO((q8 ? "q8" : "f32"));
  const Encoded e = encode({5, 4, 3}, {0.05, true, coeffs});
  const std::string good = e.bytes;
  open_ok(good);
  auto status_of = [](const std::string& b, std::string* msg = nullptr) {
    lbh::Stream s;
    const lbh::Status st = s.open_memory(b.data(), b.size());
    if (msg) *msg = s.error();
    if (st != lbh::Status::Ok) {
      CHECK_FALSE(s.ok());
      CHECK(s.error().rfind("lbh: ", 0) == 0);
    }
    return st;
  };
  std::string msg;

  SECTION("every truncation") {
    for (std::size_t n = 0; n < good.size(); ++n) {
      const lbh::Status st = status_of(good.substr(0, n));
      INFO("length " << n);
      CHECK(st != lbh::Status::Ok);
      if (n >= 16) CHECK(st == lbh::Status::Truncated);
    }
    CHECK(status_of(good.substr(0, 100), &msg) == lbh::Status::Truncated);
    CHECK(msg.find("256") != std::string::npos);
    CHECK(status_of(good + std::string(8, '\0')) == lbh::Status::BadHeader);  // trailing bytes
  }
  SECTION("every single-byte corruption") {
    for (std::size_t i = 0; i < good.size(); ++i) {
      std::string b = good;
      b[i] = static_cast<char>(b[i] ^ 0x5A);
      INFO("byte " << i);
      CHECK(status_of(b) != lbh::Status::Ok);
    }
  }
  SECTION("checksums") {
    std::string b = good;
    const std::uint64_t coeffs = lbh::detail::rd64(reinterpret_cast<const unsigned char*>(b.data()) + 256 + 80);
    b[coeffs + 5] ^= 1;
    CHECK(status_of(b, &msg) == lbh::Status::ChecksumMismatch);
    CHECK(msg.find(q8 ? "averages CRC-32" : "coefficients CRC-32") != std::string::npos);
    if (q8) {
      b = good;
      b[b.size() - 1] ^= 1;  // the last detail
      CHECK(status_of(b, &msg) == lbh::Status::ChecksumMismatch);
      CHECK(msg.find("details CRC-32") != std::string::npos);
    }
    b = good;
    b[300] ^= 1;  // inside the table entry (threshold fields)
    CHECK(status_of(b, &msg) == lbh::Status::ChecksumMismatch);
    b = good;
    b[130] ^= 1;  // index_to_world
    CHECK(status_of(b, &msg) == lbh::Status::ChecksumMismatch);
    CHECK(msg.find("header CRC-32") != std::string::npos);
  }
  SECTION("wrong version, magic, endianness") {
    std::string b = good;
    put32(b, 8, 3);
    fix_header_crc(b);
    CHECK(status_of(b, &msg) == lbh::Status::UnsupportedVersion);
    CHECK(msg.find("version 3") != std::string::npos);
    b = good;  // f32 files are written as version 1 and are valid version 2 files; q8 needs version 2
    put32(b, 8, q8 ? 1 : 2);
    fix_header_crc(b);
    CHECK(status_of(b, &msg) == (q8 ? lbh::Status::BadHeader : lbh::Status::Ok));
    if (q8) CHECK(msg.find("version 1 allows only 0") != std::string::npos);
    b = good;
    put32(b, 8, 0);
    CHECK(status_of(b) == lbh::Status::UnsupportedVersion);
    b = good;
    b[1] = 'X';
    CHECK(status_of(b) == lbh::Status::BadMagic);
    b = good;
    for (int k = 0; k < 4; ++k) b[12 + k] = static_cast<char>(1 + k);  // 0x01020304 stored big-endian
    CHECK(status_of(b) == lbh::Status::UnsupportedEndianness);
  }
  SECTION("oversized counts, even with valid checksums") {
    std::string b = good;
    put64(b, 256 + 56, 0xFFFFFFFFFFFFull);  // coefficient count
    fix_table_crc(b);
    CHECK(status_of(b, &msg) == lbh::Status::CountOutOfRange);
    CHECK(msg.find("coefficient count") != std::string::npos);
    b = good;
    put64(b, 256 + 48, 1ull << 62);  // block count
    fix_table_crc(b);
    CHECK(status_of(b) == lbh::Status::CountOutOfRange);
    b = good;
    put32(b, 32, 0xFFFFFFFFu);  // solution count
    fix_header_crc(b);
    CHECK(status_of(b) == lbh::Status::CountOutOfRange);
    b = good;
    put32(b, 32, 3);  // more solutions than the table holds
    fix_header_crc(b);
    CHECK(status_of(b) != lbh::Status::Ok);
    b = good;
    put32(b, 40, 0x7FFFFFFFu);  // a huge dimension
    fix_header_crc(b);
    CHECK(status_of(b, &msg) == lbh::Status::CountOutOfRange);
    b = good;  // huge dims with matching sub-block counts: the block count cannot fit the file
    const std::uint32_t big = 1u << 20;
    for (int a = 0; a < 3; ++a) {
      put32(b, 40 + 4 * a, big);
      put32(b, 64 + 4 * a, lbh::detail::blocks_for(static_cast<std::int32_t>(big)));
    }
    fix_header_crc(b);
    CHECK(status_of(b) == lbh::Status::CountOutOfRange);
    b = good;
    put64(b, 24, 1ull << 40);  // declared file size larger than the file
    fix_header_crc(b);
    CHECK(status_of(b) == lbh::Status::Truncated);
  }
  SECTION("a direction that is not its index's, behind valid checksums") {
    std::string b = good;
    auto* p = reinterpret_cast<const unsigned char*>(b.data());
    const int index = lbh::detail::rdi32(p + 256 + 16);
    const int m = index < 0 ? 5 : (index % 18) + 1;  // another lattice direction than the entry's
    put32(b, 256 + 20, static_cast<std::uint32_t>(lbh::lattice_cx(m)));
    put32(b, 256 + 24, static_cast<std::uint32_t>(lbh::lattice_cy(m)));
    put32(b, 256 + 28, static_cast<std::uint32_t>(lbh::lattice_cz(m)));
    fix_table_crc(b);
    CHECK(status_of(b, &msg) == lbh::Status::BadHeader);
    CHECK(msg.find("is not that of its index") != std::string::npos);
  }
  SECTION("inconsistent masks and offsets behind valid checksums") {
    std::string b = good;
    auto* p = reinterpret_cast<const unsigned char*>(b.data());
    const std::uint64_t masks = lbh::detail::rd64(p + 256 + 64), offsets = lbh::detail::rd64(p + 256 + 72);
    put64(b, masks, lbh::detail::rd64(p + masks) & ~1ull);  // drop the average bit of block 0
    put32(b, 256 + 88, lbh::crc32(b.data() + masks, lbh::detail::rd64(p + 256 + 48) * 8));
    fix_table_crc(b);
    CHECK(status_of(b) == lbh::Status::Inconsistent);
    b = good;
    put32(b, offsets + 4, 1000);  // block 1 pointing past its place
    put32(b, 256 + 92, lbh::crc32(b.data() + offsets, lbh::detail::rd64(p + 256 + 48) * 4));
    fix_table_crc(b);
    CHECK(status_of(b) == lbh::Status::Inconsistent);
    if (q8) {
      const std::uint64_t blocks = lbh::detail::rd64(p + 256 + 48), kept = lbh::detail::rd64(p + 256 + 56);
      REQUIRE(kept > blocks);
      const std::size_t details = b.size() - 3 * (kept - blocks);  // the last section
      b = good;
      b[details] = static_cast<char>(0x80);  // -128: outside -127..127
      put32(b, 256 + 124, lbh::crc32(b.data() + details, 3 * (kept - blocks)));
      fix_table_crc(b);
      CHECK(status_of(b, &msg) == lbh::Status::Inconsistent);
      CHECK(msg.find("-128") != std::string::npos);
      for (const float step : {0.0f, -1.0f, std::numeric_limits<float>::infinity(), 1e38f}) {
        b = good;
        std::uint32_t u;
        std::memcpy(&u, &step, 4);
        put32(b, 256 + 120, u);
        fix_table_crc(b);
        CHECK(status_of(b, &msg) == lbh::Status::BadHeader);
        CHECK(msg.find("quantisation step") != std::string::npos);
      }
      b = good;
      put32(b, 256 + 100, 2);  // an unknown encoding
      fix_table_crc(b);
      CHECK(status_of(b, &msg) == lbh::Status::BadHeader);
    }
  }
  SECTION("files") {
    lbh::Stream s;
    CHECK(s.open_file("/nonexistent/dir/x.lbh") == lbh::Status::IoError);
    CHECK(s.error().find("x.lbh") != std::string::npos);
  }
}

TEST_CASE("Random garbage never opens and never crashes the reader", "[reader]") {
  const Encoded e = encode({7, 6, 4}, {0.01, true});
  std::mt19937 rng(12);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int trial = 0; trial < 300; ++trial) {
    std::string b = e.bytes;
    const int flips = 1 + trial % 8;
    for (int k = 0; k < flips; ++k) b[rng() % b.size()] = static_cast<char>(byte(rng));
    if (trial % 3 == 0) b.resize(rng() % (b.size() + 1));
    lbh::Stream s;
    if (b == e.bytes) continue;
    CHECK(s.open_memory(b.data(), b.size()) != lbh::Status::Ok);
  }
}
