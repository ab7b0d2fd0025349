// libFuzzer target for readers/lbh/lbh_reader.h: any byte string must either be rejected with a
// message or open as a stream that decodes and samples without reading out of bounds.
// Built with -DLBH_FUZZ_IGNORE_CHECKSUMS so mutated inputs get past the CRC-32 checks and reach the
// structural checks behind them (the checksums are tested by tests/reader/test_lbh_reader.cpp).
//   clang++ -std=c++17 -g -O1 -fsanitize=fuzzer,address,undefined -DLBH_FUZZ_IGNORE_CHECKSUMS -I. \
//       tests/fuzz_lbh_reader.cpp -o fuzz_lbh_reader && ./fuzz_lbh_reader -max_total_time=60 tests/fuzz/corpus
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "readers/lbh/lbh_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lbh::Stream s;
  if (s.open_memory(data, size) != lbh::Status::Ok) {
    if (s.error().empty() || s.ok()) __builtin_trap();  // a rejection must say why
    return 0;
  }
  const lbh::Lattice& L = s.lattice();
  const std::uint64_t blocks = static_cast<std::uint64_t>(L.nb[0]) * L.nb[1] * L.nb[2];
  lbh::Rgb out[64];
  volatile float sink = 0;
  for (std::size_t slot = 0; slot < s.solution_count() && slot < 8; ++slot) {
    const lbh::SolutionView v = s.view(slot);
    for (std::uint64_t b = 0; b < blocks && b < 4096; ++b) {
      lbh::decode_block(v, b, out);
      sink = sink + out[63].r;
    }
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    const float probes[] = {-1e30f, -1.0f, 0.0f, 0.5f, 1.0f, 2.999f, 3.0f, 7.25f, 1e9f, nan, inf, -inf};
    for (float x : probes)
      for (float y : probes) {
        sink = sink + s.sample_index(slot, x + L.index_min[0], y + L.index_min[1], x).g;
        sink = sink + s.sample_world(slot, x, y, y).b;
      }
  }
  lbh::Relighter r;
  if (s.make_relighter(0.2, -0.3, -1.0, 1.0f, 0.5f, r) == lbh::Status::Ok)
    sink = sink + lbh::relight_index(L, r, 1.0f, 2.0f, 3.0f).r;
  if (s.solution_count() > 0) sink = sink + s.decode_all(0).back();
  return 0;
}
