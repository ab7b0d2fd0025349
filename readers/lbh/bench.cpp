// Sampling throughput of an .lbh stream against the same solution stored uncompressed (a dense
// float RGB array, x fastest, decoded from the stream), single-threaded on the CPU.
//   lbh_bench FILE.lbh [--samples N] [--solution INDEX]
// Reports samples per second for: the dense grid (trilinear, 8 nodes), the stream's sampler
// (lbh::sample_index: one mask, one offset, the block's kept coefficients), [Steele2009]'s method (decode
// the whole 4^3 sub-block, then blend 8 values), and relighting (3 directional solutions +
// ambient) from the stream vs from dense grids. Positions: uniformly random in the lattice
// ("incoherent", like scattered secondary rays) and along random rays in steps of half a node
// ("coherent", like a ray march).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "lbh_reader.h"

namespace {

struct Dense {
  int n[3];
  int index_min[3];
  std::vector<float> rgb;  // interleaved, x fastest
};

inline lbh::Rgb dense_sample(const Dense& d, float x, float y, float z) {
  float p[3] = {x - d.index_min[0], y - d.index_min[1], z - d.index_min[2]};
  int i[3];
  float a[3];
  for (int k = 0; k < 3; ++k) {
    const float hi = static_cast<float>(d.n[k] - 1);
    if (!(p[k] > 0.0f)) p[k] = 0.0f;
    if (p[k] > hi) p[k] = hi;
    i[k] = static_cast<int>(p[k]);
    if (i[k] > d.n[k] - 2) i[k] = d.n[k] - 2 > 0 ? d.n[k] - 2 : 0;
    a[k] = p[k] - static_cast<float>(i[k]);
  }
  const std::size_t sx = d.n[0] > 1 ? 3 : 0, sy = d.n[1] > 1 ? 3 * static_cast<std::size_t>(d.n[0]) : 0,
                    sz = d.n[2] > 1 ? 3 * static_cast<std::size_t>(d.n[0]) * d.n[1] : 0;
  const float* b = &d.rgb[3 * ((static_cast<std::size_t>(i[2]) * d.n[1] + i[1]) * d.n[0] + i[0])];
  lbh::Rgb out{0, 0, 0};
  for (int c = 0; c < 8; ++c) {
    const float w = (c & 1 ? a[0] : 1 - a[0]) * (c & 2 ? a[1] : 1 - a[1]) * (c & 4 ? a[2] : 1 - a[2]);
    const float* q = b + (c & 1 ? sx : 0) + (c & 2 ? sy : 0) + (c & 4 ? sz : 0);
    out.r += w * q[0];
    out.g += w * q[1];
    out.b += w * q[2];
  }
  return out;
}

// [Steele2009] sec. 5.3: decode the whole sub-block, then blend the cell's 8 values.
inline lbh::Rgb block_sample(const lbh::Lattice& L, const lbh::SolutionView& v, float x, float y, float z) {
  float p[3] = {x - L.index_min[0], y - L.index_min[1], z - L.index_min[2]};
  int b[3], l[3];
  float a[3];
  for (int k = 0; k < 3; ++k) lbh::locate_axis(L.n[k], p[k], b[k], l[k], a[k]);
  lbh::Rgb blk[64];
  lbh::decode_block(v, lbh::block_index(L, b[0], b[1], b[2]), blk);
  lbh::Rgb out{0, 0, 0};
  for (int c = 0; c < 8; ++c) {
    const float w = (c & 1 ? a[0] : 1 - a[0]) * (c & 2 ? a[1] : 1 - a[1]) * (c & 4 ? a[2] : 1 - a[2]);
    const lbh::Rgb& q = blk[(l[0] + (c & 1)) + 4 * (l[1] + (c >> 1 & 1)) + 16 * (l[2] + (c >> 2 & 1))];
    out.r += w * q.r;
    out.g += w * q.g;
    out.b += w * q.b;
  }
  return out;
}

template <typename Fn>
double best_rate(const std::vector<float>& pos, Fn fn, float& sink) {
  double best = 0;
  for (int rep = 0; rep < 5; ++rep) {
    const auto t0 = std::chrono::steady_clock::now();
    float acc = 0;
    for (std::size_t i = 0; i + 2 < pos.size(); i += 3) {
      const lbh::Rgb v = fn(pos[i], pos[i + 1], pos[i + 2]);
      acc += v.r + v.g + v.b;
    }
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    sink += acc;
    best = std::max(best, static_cast<double>(pos.size() / 3) / s);
  }
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s FILE.lbh [--samples N] [--solution INDEX]\n", argv[0]);
    return 2;
  }
  std::size_t samples = 4000000;
  int solution = -2;
  for (int i = 2; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--samples")) samples = std::strtoull(argv[i + 1], nullptr, 10);
    else if (!std::strcmp(argv[i], "--solution")) solution = std::atoi(argv[i + 1]);
  }
  lbh::Stream s;
  if (s.open_file(argv[1]) != lbh::Status::Ok) {
    std::fprintf(stderr, "%s\n", s.error().c_str());
    return 1;
  }
  const lbh::Lattice& L = s.lattice();
  int slot = solution == -2 ? 0 : s.find(solution);
  if (slot < 0) {
    std::fprintf(stderr, "no solution %d in %s\n", solution, argv[1]);
    return 1;
  }
  auto dense_of = [&](int sl) {
    Dense d;
    for (int k = 0; k < 3; ++k) {
      d.n[k] = L.n[k];
      d.index_min[k] = L.index_min[k];
    }
    d.rgb = s.decode_all(static_cast<std::size_t>(sl));
    return d;
  };
  const Dense dense = dense_of(slot);
  const lbh::SolutionView view = s.view(static_cast<std::size_t>(slot));
  const lbh::SolutionInfo& info = s.info(static_cast<std::size_t>(slot));
  const double nodes = static_cast<double>(L.n[0]) * L.n[1] * L.n[2];

  std::mt19937 rng(42);
  std::vector<float> incoherent(samples * 3), coherent(samples * 3);
  std::uniform_real_distribution<float> ux(L.index_min[0], L.index_min[0] + L.n[0] - 1),
      uy(L.index_min[1], L.index_min[1] + L.n[1] - 1), uz(L.index_min[2], L.index_min[2] + L.n[2] - 1);
  for (std::size_t i = 0; i < samples; ++i) {
    incoherent[3 * i] = ux(rng);
    incoherent[3 * i + 1] = uy(rng);
    incoherent[3 * i + 2] = uz(rng);
  }
  std::normal_distribution<float> g;
  for (std::size_t i = 0; i < samples;) {  // rays through the lattice, half-node steps
    float o[3] = {ux(rng), uy(rng), uz(rng)}, d[3] = {g(rng), g(rng), g(rng)};
    const float len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) + 1e-6f;
    for (int step = 0; step < 64 && i < samples; ++step, ++i)
      for (int k = 0; k < 3; ++k) coherent[3 * i + k] = o[k] + 0.5f * step * d[k] / len;
  }

  std::printf("%s, solution %s: %d x %d x %d nodes, ratio %.2f:1, %.1f%% fast-path blocks, %llu samples, 1 thread\n",
              argv[1], info.name.c_str(), L.n[0], L.n[1], L.n[2], nodes * 12 / static_cast<double>(info.stream_bytes()),
              100.0 * static_cast<double>(info.fast_blocks) / static_cast<double>(info.block_count),
              static_cast<unsigned long long>(samples));
  float sink = 0;
  std::printf("%-34s %16s %16s\n", "method", "incoherent (M/s)", "coherent (M/s)");
  const char* names[3] = {"dense float RGB grid (uncompressed)", "lbh::sample_index (compressed)",
                          "decode 4^3 block + blend ([Steele2009])"};
  double rates[3][2];
  for (int k = 0; k < 2; ++k) {
    const std::vector<float>& pos = k == 0 ? incoherent : coherent;
    rates[0][k] = best_rate(pos, [&](float x, float y, float z) { return dense_sample(dense, x, y, z); }, sink);
    rates[1][k] = best_rate(pos, [&](float x, float y, float z) { return lbh::sample_index(L, view, x, y, z); }, sink);
    rates[2][k] = best_rate(pos, [&](float x, float y, float z) { return block_sample(L, view, x, y, z); }, sink);
  }
  for (int m = 0; m < 3; ++m)
    std::printf("%-34s %16.2f %16.2f   (%.2fx / %.2fx slower than dense)\n", names[m], rates[m][0] / 1e6,
                rates[m][1] / 1e6, rates[0][0] / rates[m][0], rates[0][1] / rates[m][1]);

  // Relighting: sun at elevation 50, azimuth 30 degrees, ambient 0.2.
  const double el = 50 * 3.14159265358979 / 180, az = 30 * 3.14159265358979 / 180;
  const double d[3] = {-std::cos(el) * std::cos(az), -std::cos(el) * std::sin(az), -std::sin(el)};
  lbh::Relighter r;
  if (s.make_relighter(d[0], d[1], d[2], 1.0f, 0.2f, r) == lbh::Status::Ok) {
    const lbh::SunWeights sw = lbh::decompose_direction(d[0], d[1], d[2]);
    std::vector<Dense> dense4;
    std::vector<float> w4;
    for (int k = 0; k < 3; ++k)
      if (sw.weight[k] > 0) {
        dense4.push_back(dense_of(s.find(sw.direction[k])));
        w4.push_back(sw.weight[k]);
      }
    dense4.push_back(dense_of(s.find(0)));
    w4.push_back(0.2f);
    double rr[2][2];
    for (int k = 0; k < 2; ++k) {
      const std::vector<float>& pos = k == 0 ? incoherent : coherent;
      rr[0][k] = best_rate(pos, [&](float x, float y, float z) {
        lbh::Rgb o{0, 0, 0};
        for (std::size_t j = 0; j < dense4.size(); ++j) {
          const lbh::Rgb v = dense_sample(dense4[j], x, y, z);
          o.r += w4[j] * v.r;
          o.g += w4[j] * v.g;
          o.b += w4[j] * v.b;
        }
        return o;
      }, sink);
      rr[1][k] = best_rate(pos, [&](float x, float y, float z) { return lbh::relight_index(L, r, x, y, z); }, sink);
    }
    std::printf("%-34s %16.2f %16.2f\n", "relight, dense grids", rr[0][0] / 1e6, rr[0][1] / 1e6);
    std::printf("%-34s %16.2f %16.2f   (%.2fx / %.2fx slower than dense)\n", "relight, lbh::relight_index",
                rr[1][0] / 1e6, rr[1][1] / 1e6, rr[0][0] / rr[1][0], rr[0][1] / rr[1][1]);
  }
  std::printf("(checksum %g)\n", static_cast<double>(sink));
  return 0;
}
