// Minimal use of lbh_reader.h: open and validate a stream, list its solutions, decode one
// sub-block, sample at the lattice centre (index and world space) and relight for a sun direction.
//   c++ -std=c++17 -O2 -I readers/lbh readers/lbh/example.cpp -o lbh_example
//   ./lbh_example out/default/tree.lbh
#include <cmath>
#include <cstdio>

#include "lbh_reader.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s FILE.lbh\n", argv[0]);
    return 2;
  }
  lbh::Stream s;
  if (s.open_file(argv[1]) != lbh::Status::Ok) {  // validates every count, offset and checksum
    std::fprintf(stderr, "%s\n", s.error().c_str());
    return 1;
  }
  const lbh::Header& h = s.header();
  const lbh::Lattice& L = s.lattice();
  std::printf("%s: %d x %d x %d nodes, %d x %d x %d sub-blocks, %zu solution(s), %llu bytes\n", argv[1], h.dims[0],
              h.dims[1], h.dims[2], L.nb[0], L.nb[1], L.nb[2], s.solution_count(),
              static_cast<unsigned long long>(h.file_bytes));
  const double nodes = static_cast<double>(h.dims[0]) * h.dims[1] * h.dims[2];
  for (std::size_t i = 0; i < s.solution_count(); ++i) {
    const lbh::SolutionInfo& in = s.info(i);
    std::printf("  %-6s index %3d  direction (%+d,%+d,%+d)  threshold %.3g  coefficients %llu  fast-path blocks "
                "%llu/%llu  ratio %.2f:1\n",
                in.name.c_str(), in.index, in.direction[0], in.direction[1], in.direction[2], in.threshold,
                static_cast<unsigned long long>(in.coeff_count), static_cast<unsigned long long>(in.fast_blocks),
                static_cast<unsigned long long>(in.block_count), nodes * 12.0 / static_cast<double>(in.stream_bytes()));
  }

  // One sub-block of the first solution: its 4^3 values (the 3^3 own nodes plus the forward border).
  lbh::Rgb block[64];
  s.decode_block(0, lbh::block_index(L, 0, 0, 0), block);
  std::printf("block (0,0,0) of %s: first value (%g, %g, %g), last (%g, %g, %g)\n", s.info(0).name.c_str(), block[0].r,
              block[0].g, block[0].b, block[63].r, block[63].g, block[63].b);

  // Trilinear samples at the lattice centre: index space of the bake's .vdb, then world space.
  const float c[3] = {L.index_min[0] + 0.5f * (L.n[0] - 1), L.index_min[1] + 0.5f * (L.n[1] - 1),
                      L.index_min[2] + 0.5f * (L.n[2] - 1)};
  const lbh::Rgb vi = s.sample_index(0, c[0], c[1], c[2]);
  const double* m = h.index_to_world;
  const float w[3] = {static_cast<float>(m[0] * c[0] + m[1] * c[1] + m[2] * c[2] + m[3]),
                      static_cast<float>(m[4] * c[0] + m[5] * c[1] + m[6] * c[2] + m[7]),
                      static_cast<float>(m[8] * c[0] + m[9] * c[1] + m[10] * c[2] + m[11])};
  const lbh::Rgb vw = s.sample_world(0, w[0], w[1], w[2]);
  std::printf("sample of %s at index (%g, %g, %g): (%g, %g, %g); at world (%g, %g, %g): (%g, %g, %g)\n",
              s.info(0).name.c_str(), c[0], c[1], c[2], vi.r, vi.g, vi.b, w[0], w[1], w[2], vw.r, vw.g, vw.b);

  // Relighting: sun at elevation 50 degrees, azimuth 30 degrees; light travels away from the sun.
  const double el = 50 * 3.14159265358979 / 180, az = 30 * 3.14159265358979 / 180;
  const double d[3] = {-std::cos(el) * std::cos(az), -std::cos(el) * std::sin(az), -std::sin(el)};
  lbh::Relighter r;
  if (s.make_relighter(d[0], d[1], d[2], 1.0f, 0.2f, r) == lbh::Status::Ok) {
    const lbh::SunWeights sw = lbh::decompose_direction(d[0], d[1], d[2]);
    const lbh::Rgb v = lbh::relight_index(L, r, c[0], c[1], c[2]);
    std::printf("relit (B%02d x %.3f + B%02d x %.3f + B%02d x %.3f + 0.2 B00) at the centre: (%g, %g, %g)\n",
                sw.direction[0], sw.weight[0], sw.direction[1], sw.weight[1], sw.direction[2], sw.weight[2], v.r, v.g,
                v.b);
  } else {
    std::printf("not relit: %s\n", s.error().c_str());
  }
  return 0;
}
