// Haar sub-block streams: the transform ([Steele2009] sec. 2.3), the encoder's error bound and
// determinism, and sampling what it wrote (the reader's own checks: tests/reader).
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "lblight/compress/haar.h"
#include "lblight/compress/lbh_writer.h"
#include "lblight/core/error.h"
#include "lblight/core/relative_gap.h"
#include "lblight/lattice/sun.h"
#include "readers/lbh/lbh_reader.h"
#include "tests/compress/lbh_test_streams.h"
#include "tests/support/expect_error.h"

using namespace lblight;
using namespace lblight::test;
using lblight::test::expect_invalid_input;

TEST_CASE("Steele2009's Haar example [4 19 44 0] gives [16.75 -5.25 -7.5 22]", "[haar]") {
  float v[4] = {4, 19, 44, 0};
  lbh::haar_forward_1d(v, 1);
  CHECK(v[0] == 16.75f);
  CHECK(v[1] == -5.25f);
  CHECK(v[2] == -7.5f);
  CHECK(v[3] == 22.0f);
  lbh::haar_inverse_1d(v, 1);
  CHECK(v[0] == 4.0f);
  CHECK(v[1] == 19.0f);
  CHECK(v[2] == 44.0f);
  CHECK(v[3] == 0.0f);
  // the same sequence along z inside a block (stride 16): transform order z, y, x
  float b[64] = {};
  for (int z = 0; z < 4; ++z) b[16 * z] = std::array<float, 4>{4, 19, 44, 0}[z];
  lbh::haar_forward_1d(b, 16);
  CHECK(b[0] == 16.75f);
  CHECK(b[16] == -5.25f);
  CHECK(b[32] == -7.5f);
  CHECK(b[48] == 22.0f);
}

TEST_CASE("3D Haar block: layout, separability and inverse", "[haar]") {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-5, 5);
  float v[64], c[64];
  for (float& x : v) x = u(rng);
  std::memcpy(c, v, sizeof v);
  lbh::haar_forward_block(c);
  float r[64];
  std::memcpy(r, c, sizeof c);
  lbh::haar_inverse_block(r);
  for (int i = 0; i < 64; ++i) CHECK(r[i] == Approx(v[i]).margin(1e-5));
  // coefficient 0 is the block average
  double mean = 0;
  for (float x : v) mean += x / 64.0;
  CHECK(c[0] == Approx(mean).margin(1e-5));
  // a field varying along x only has coefficients only at fy = fz = 0 (indices 0..3)
  float xs[64];
  for (int i = 0; i < 64; ++i) xs[i] = std::array<float, 4>{4, 19, 44, 0}[i & 3];
  lbh::haar_forward_block(xs);
  CHECK(xs[0] == 16.75f);
  CHECK(xs[1] == -5.25f);
  CHECK(xs[2] == -7.5f);
  CHECK(xs[3] == 22.0f);
  for (int i = 4; i < 64; ++i) CHECK(xs[i] == 0.0f);
  // a constant block keeps only its average, even at threshold 0 (the fast path)
  haar::Block k;
  for (auto& ch : k) ch.fill(0.7f);
  haar::forward(k);
  CHECK(haar::keep_mask(k, 0.0f) == 1u);
}

TEST_CASE("Threshold 0 round-trips every node to float rounding", "[haar]") {
  for (const Dims d : {Dims{11, 7, 5}, Dims{1, 1, 1}, Dims{2, 3, 4}, Dims{4, 4, 4}, Dims{13, 1, 10}}) {
    const Encoded e = encode(d, {0.0, false});
    const lbh::Stream s = open_ok(e.bytes);
    const std::vector<float> dec = s.decode_all(0);
    double worst = 0, scale = 0;
    for (std::size_t i = 0; i < d.count(); ++i)
      for (int c = 0; c < 3; ++c) {
        const double err = std::fabs(static_cast<double>(dec[3 * i + c]) - e.field[c][i]);
        if (!(err <= worst)) worst = err;  // NaN wins
        keep_worst(scale, std::fabs(static_cast<double>(e.field[c][i])));
      }
    INFO(d.nx << "x" << d.ny << "x" << d.nz);
    CHECK(worst <= 1e-6 * scale);
    CHECK(e.sols[0].stats.max_abs_error <= 1e-6 * scale);
    CHECK(e.sols[0].stats.error_bound == 0.0);
    // constant corner region: those blocks take the fast path
    if (d.nx >= 11) CHECK(e.sols[0].stats.fast_blocks > 0);
  }
}

TEST_CASE("The max error never exceeds the bound the threshold implies", "[haar]") {
  const Dims d{20, 17, 14};
  const LbhCoefficients coeffs = GENERATE(LbhCoefficients::F32, LbhCoefficients::Q8);
  for (double rel : {0.001, 0.01, 0.03, 0.1, 0.5}) {
    const Encoded e = encode(d, {rel, true, coeffs}, 7, 0.05f);
    const LbhStats& st = e.sols[0].stats;
    const double t = e.sols[0].threshold;
    const bool q8 = coeffs == LbhCoefficients::Q8;
    INFO((q8 ? "q8" : "f32") << ", relative threshold " << rel << ", t = " << t << ", step " << e.sols[0].step);
    CHECK(t == Approx(rel * st.max_abs_value));
    CHECK((e.sols[0].encoding == lbh::Encoding::Q8) == q8);  // (make_field is non-negative)
    const double eps = 2e-6 * st.max_abs_value;  // float rounding of the filters
    // Per coefficient on a value's path: a dropped one is off by < t, a quantised one by <= step / 2
    // (0 for f32); the step is t / 2 unless the largest kept detail needs 127 coarser steps.
    double per_coeff = t;
    if (q8 && e.sols[0].details.empty()) {
      CHECK(e.sols[0].step == 1.0f);  // nothing to quantise
    } else if (q8) {
      CHECK(e.sols[0].step >= 0.5 * t * (1 - 1e-6));
      // make_field is non-negative, so details are <= M / 2 <= 63.5 t from 1/127 relative on
      if (rel >= 1.0 / 127) CHECK(e.sols[0].step <= 0.5 * t * (1 + 1e-6));
      per_coeff = std::max(t, 0.5 * e.sols[0].step * (1 + 1e-6));
    }
    // measured over every stored value (forward borders included) <= sum of coefficient errors on
    // the value's path <= 26 per_coeff
    CHECK(st.max_abs_error <= st.max_abs_error_block);
    CHECK(st.max_abs_error_block <= st.error_bound + eps);
    CHECK(st.error_bound < haar::kMaxDetailsPerValue * per_coeff);
    // recompute independently from the decoded lattice
    const lbh::Stream s = open_ok(e.bytes);
    const std::vector<float> dec = s.decode_all(0);
    double worst = 0, sq = 0;
    for (std::size_t i = 0; i < d.count(); ++i)
      for (int c = 0; c < 3; ++c) {
        const double err = static_cast<double>(dec[3 * i + c]) - e.field[c][i];
        keep_worst(worst, std::fabs(err));
        sq += err * err;
      }
    CHECK(worst == Approx(st.max_abs_error).margin(1e-7));
    CHECK(std::sqrt(sq / (3.0 * d.count())) == Approx(st.rms_error).epsilon(1e-6).margin(1e-9));
    CHECK(worst <= haar::kMaxDetailsPerValue * per_coeff + eps);
    const double coeff_bytes = q8 ? st.blocks * 12.0 + (st.coefficients - st.blocks) * 3.0 : st.coefficients * 12.0;
    CHECK(st.ratio == Approx(d.count() * 12.0 / (st.blocks * 12.0 + coeff_bytes)));
    CHECK(st.stream_bytes == lbh::Stream(open_ok(e.bytes)).info(0).stream_bytes());
  }
}

TEST_CASE("8-bit details: same mask as f32, error within half a step, about 2.5x smaller", "[haar]") {
  const Dims d{20, 17, 14};
  const Encoded f = encode(d, {0.01, true, LbhCoefficients::F32}, 7, 0.05f);
  const Encoded q = encode(d, {0.01, true}, 7, 0.05f);  // auto: q8 because the threshold is > 0
  const LbhEncoded &ef = f.sols[0], &eq = q.sols[0];
  REQUIRE(eq.encoding == lbh::Encoding::Q8);
  CHECK(ef.masks == eq.masks);  // the same coefficients are kept
  CHECK(ef.offsets == eq.offsets);
  CHECK(eq.step == Approx(0.5 * eq.threshold));
  // the averages are stored exactly; every detail within step / 2 of the f32 one
  for (std::size_t b = 0; b < ef.masks.size(); ++b) {
    const float* cf = ef.coeffs.data() + 3 * ef.offsets[b];
    for (int c = 0; c < 3; ++c) CHECK(eq.coeffs[3 * b + c] == cf[c]);
    const std::int8_t* dq = eq.details.data() + 3 * (eq.offsets[b] - b);
    for (int k = 1; k < lbh::popcount64(ef.masks[b]); ++k)
      for (int c = 0; c < 3; ++c) CHECK(std::fabs(cf[3 * k + c] - eq.step * dq[3 * (k - 1) + c]) <= 0.5f * eq.step * 1.0001f);
  }
  CHECK(eq.stats.ratio > 2.0 * ef.stats.ratio);
  CHECK(eq.stats.rms_error < 1.2 * ef.stats.rms_error);
  CHECK(lbh::detail::rd32(reinterpret_cast<const unsigned char*>(q.bytes.data()) + 8) == 2u);  // version 2
  CHECK(lbh::detail::rd32(reinterpret_cast<const unsigned char*>(f.bytes.data()) + 8) == 1u);  // f32 only: 1
  // threshold 0: auto stays lossless f32; asking for q8 anyway is lossy, within its bound
  CHECK(encode(d, {0.0, false}).sols[0].encoding == lbh::Encoding::F32);
  const Encoded z = encode(d, {0.0, false, LbhCoefficients::Q8}, 7, 0.05f);
  CHECK(z.sols[0].stats.max_abs_error > 0.0);
  CHECK(z.sols[0].stats.max_abs_error <= z.sols[0].stats.error_bound * (1 + 1e-6) + 1e-6);
  CHECK(z.sols[0].stats.error_bound <= haar::kMaxDetailsPerValue * 0.5 * z.sols[0].step * (1 + 1e-6));
  open_ok(z.bytes);
}

TEST_CASE("Error bound of one block is attained by a worst-case pattern", "[haar]") {
  // All 26 details on the path of value (0,0,0) just below t, with signs that add up there.
  const float t = 1.0f;
  haar::Block c;
  for (auto& ch : c) ch.fill(0.0f);
  for (int l = 1; l < 64; ++l) {
    const int f[3] = {l & 3, (l >> 2) & 3, l >> 4};
    bool on_path = true;
    for (int a : f) on_path = on_path && a <= 2;  // frequencies 0, 1, 2 are on the path of position 0
    if (on_path)
      for (auto& ch : c) ch[l] = 0.999f;  // all basis values are +1 at position 0
  }
  for (auto& ch : c) ch[0] = 5.0f;
  const std::uint64_t mask = haar::keep_mask(c, t);
  CHECK(mask == 1u);
  const float bound = haar::dropped_path_bound(c, mask);
  CHECK(bound == Approx(26 * 0.999f));
  haar::Block v = c;
  for (auto& ch : v) lbh::haar_inverse_block(ch.data());
  // full value at (0,0,0) minus the fast-path reconstruction (5.0) is exactly the bound
  CHECK(v[0][0] - 5.0f == Approx(bound));
}

TEST_CASE("Encoding does not depend on the thread count", "[haar]") {
  const Dims d{16, 9, 12};
  const auto field = make_field(d, 5);
  const DenseFrame f = frame_of(d);
  std::string bytes[3];
  int k = 0;
  for (int threads : {1, 2, 7}) {
    LbhEncoded e = encode_lbh_solution(f, {"B03", 3, {0, 1, 0}, &field}, {0.02, true}, threads);
    bytes[k++] = serialize_lbh(f, {e});
  }
  CHECK(bytes[0] == bytes[1]);
  CHECK(bytes[0] == bytes[2]);
}

// Reference: trilinear blend of the 8 nodes of the cell around lattice position p, taken from the
// decoded 4^3 values of the one sub-block holding that cell (cell i = min(floor(u), n - 2) in block i / 3).
lbh::Rgb trilinear_in_block(const lbh::Stream& s, double u, double v, double w) {
  const lbh::Lattice& L = s.lattice();
  double p[3] = {u, v, w};
  int cell[3];
  double a[3];
  for (int k = 0; k < 3; ++k) {
    p[k] = std::min(std::max(p[k], 0.0), static_cast<double>(L.n[k] - 1));
    cell[k] = std::min(static_cast<int>(std::floor(p[k])), std::max(L.n[k] - 2, 0));
    a[k] = p[k] - cell[k];
  }
  lbh::Rgb blk[64];
  s.decode_block(0, lbh::block_index(L, cell[0] / 3, cell[1] / 3, cell[2] / 3), blk);
  double out[3] = {0, 0, 0};
  for (int c = 0; c < 8; ++c) {
    const int x = cell[0] % 3 + (c & 1), y = cell[1] % 3 + (c >> 1 & 1), z = cell[2] % 3 + (c >> 2 & 1);
    const double wt = (c & 1 ? a[0] : 1 - a[0]) * (c & 2 ? a[1] : 1 - a[1]) * (c & 4 ? a[2] : 1 - a[2]);
    const lbh::Rgb& q = blk[x + 4 * y + 16 * z];
    out[0] += wt * q.r;
    out[1] += wt * q.g;
    out[2] += wt * q.b;
  }
  return {static_cast<float>(out[0]), static_cast<float>(out[1]), static_cast<float>(out[2])};
}

TEST_CASE("Sampling the stream equals trilinear sampling of the decompressed data", "[haar][reader]") {
  // Threshold 0: equal to trilinear sampling of the decompressed grid (float rounding). Lossy:
  // equal to trilinear sampling of the decompressed sub-block that holds the cell; at nodes equal
  // to the decompressed grid; between nodes next to a block's far face the forward border (decoded
  // in this block) and the next block's own node (decoded there) may differ by the two errors.
  for (const double rel : {0.0, 0.02}) {
    for (const Dims d : {Dims{14, 11, 9}, Dims{2, 5, 1}, Dims{4, 7, 10}}) {
      const Encoded e = encode(d, {rel, true}, 11, 0.1f);
      const lbh::Stream s = open_ok(e.bytes);
      const std::vector<float> dec = s.decode_all(0);
      const lbh::Lattice& L = s.lattice();
      const double scale = e.sols[0].max_abs_value, tol = 2e-6 * scale;
      const double seam = 2 * e.sols[0].stats.max_abs_error_block + tol;
      std::mt19937 rng(9);
      std::uniform_real_distribution<double> ux(-2, d.nx + 1), uy(-2, d.ny + 1), uz(-2, d.nz + 1);
      for (int i = 0; i < 3000; ++i) {
        double p[3] = {ux(rng), uy(rng), uz(rng)};
        if (i % 5 == 0) p[i % 3] = std::round(p[i % 3]);  // node and block faces
        const lbh::Rgb got = lbh::sample_index(L, s.view(0), static_cast<float>(p[0] + L.index_min[0]),
                                               static_cast<float>(p[1] + L.index_min[1]),
                                               static_cast<float>(p[2] + L.index_min[2]));
        const lbh::Rgb blk = trilinear_in_block(s, p[0], p[1], p[2]);
        const lbh::Rgb grid = trilinear(dec, d, p[0], p[1], p[2]);
        INFO("threshold " << rel << " at " << p[0] << ", " << p[1] << ", " << p[2]);
        CHECK(got.r == Approx(blk.r).margin(tol));
        CHECK(got.g == Approx(blk.g).margin(tol));
        CHECK(got.b == Approx(blk.b).margin(tol));
        CHECK(got.g == Approx(grid.g).margin(rel == 0.0 ? tol : seam));
      }
      // nodes sample to their decoded values; world positions through the transform
      const auto& m = e.frame.index_to_world;
      for (int z = 0; z < d.nz; ++z)
        for (int y = 0; y < d.ny; ++y)
          for (int x = 0; x < d.nx; ++x) {
            const double ix = x + L.index_min[0], iy = y + L.index_min[1], iz = z + L.index_min[2];
            const double w[3] = {m[0] * ix + m[1] * iy + m[2] * iz + m[3], m[4] * ix + m[5] * iy + m[6] * iz + m[7],
                                 m[8] * ix + m[9] * iy + m[10] * iz + m[11]};
            const lbh::Rgb a = s.sample_world(0, static_cast<float>(w[0]), static_cast<float>(w[1]),
                                              static_cast<float>(w[2]));
            const float* ref = &dec[d.index(x, y, z) * 3];
            CHECK(a.r == Approx(ref[0]).margin(1e-5 * scale));
            CHECK(a.b == Approx(ref[2]).margin(1e-5 * scale));
          }
    }
  }
}

TEST_CASE("Decoding one sub-block gives its 4^3 nodes with the forward border", "[haar][reader]") {
  const Dims d{8, 6, 5};  // 3 x 2 x 2 blocks; the last ones clamp
  const Encoded e = encode(d, {0.0, false});
  const lbh::Stream s = open_ok(e.bytes);
  CHECK(s.lattice().nb[0] == 3);
  CHECK(s.lattice().nb[1] == 2);
  CHECK(s.lattice().nb[2] == 2);
  lbh::Rgb blk[64];
  const int bx = 2, by = 1, bz = 1;
  s.decode_block(0, lbh::block_index(s.lattice(), bx, by, bz), blk);
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 4; ++x) {
        const std::size_t n = d.index(std::min(3 * bx + x, d.nx - 1), std::min(3 * by + y, d.ny - 1),
                                      std::min(3 * bz + z, d.nz - 1));
        CHECK(blk[x + 4 * y + 16 * z].g == Approx(e.field[1][n]).margin(1e-5));
      }
}

TEST_CASE("8-bit details: step edge cases give files the reader accepts", "[haar]") {
  const Dims d{7, 5, 6};
  const DenseFrame f = frame_of(d);
  auto encode_field = [&](const std::array<std::vector<float>, 3>& field, LbhSettings settings) {
    LbhEncoded e = encode_lbh_solution(f, {"B01", 1, {1, 0, 0}, &field}, settings, 2);
    lbh::Stream s = open_ok(serialize_lbh(f, {e}));
    CHECK(s.info(0).encoding == e.encoding);
    return e;
  };
  auto constant = [&](float v) {
    std::array<std::vector<float>, 3> field;
    for (auto& c : field) c.assign(d.count(), v);
    return field;
  };
  // no kept details (constant and all-zero fields): step 1, every block on the fast path
  for (const float v : {0.0f, 0.75f}) {
    const LbhEncoded e = encode_field(constant(v), {0.01, true, LbhCoefficients::Q8});
    CHECK(e.step == 1.0f);
    CHECK(e.details.empty());
    CHECK(e.stats.fast_blocks == e.stats.blocks);
    CHECK(e.stats.max_abs_error == 0.0);
  }
  // an absolute threshold so large that half of it times 127 would overflow a float
  const LbhEncoded big = encode_field(constant(3.0f), {1e37, false});
  CHECK(std::isfinite(127.0f * big.step));
  // a threshold below the smallest float's half, on denormal details: returns, step > 0
  std::array<std::vector<float>, 3> tiny = constant(0.0f);
  for (std::size_t i = 0; i < d.count(); i += 3) tiny[1][i] = 1e-40f;
  const LbhEncoded t = encode_field(tiny, {1e-45, false, LbhCoefficients::Q8});
  CHECK(t.step > 0.0f);
  CHECK(t.stats.max_abs_error <= t.stats.error_bound * (1 + 1e-6) + 1e-45);
  // signed data: the largest detail sets a step above t / 2; the bound still holds
  std::array<std::vector<float>, 3> sign = constant(0.0f);
  for (std::size_t i = 0; i < d.count(); ++i)
    for (auto& c : sign) c[i] = (i % 2) ? 1.0f : -1.0f;
  const LbhEncoded sg = encode_field(sign, {0.01, true});
  CHECK(sg.step > 0.5f * sg.threshold);
  CHECK(sg.stats.max_abs_error <= sg.stats.error_bound * (1 + 1e-6) + 1e-6);
  CHECK(sg.stats.error_bound < haar::kMaxDetailsPerValue * std::max<double>(sg.threshold, 0.5 * sg.step * (1 + 1e-6)));
  // values whose pair sums overflow the filters: a clear input error, not a file readers reject
  encode_lbh_solution(f, {"B01", 1, {1, 0, 0}, &sign}, {0.01, true}, 2);
  const auto huge = constant(3e38f);
  expect_invalid_input([&] { encode_lbh_solution(f, {"B01", 1, {1, 0, 0}, &huge}, {0.01, true}, 2); }, "too large");
}
