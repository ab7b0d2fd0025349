// How the CPU sweep cuts the lattice (backends/openmp): rows into chunks of one cache line, when
// a lattice is sparse enough to stream by position, and the four ways a sweep addresses the state.
#pragma once

#include <cstddef>
#include <utility>
#include <algorithm>

#include "lblight/backend/backend.h"
#include "lblight/lattice/lattice.h"

namespace lblight::openmp {

// The nodes [lo, hi] of chunk c of a row of nx nodes, as the sweeps cut rows into chunks of `line`
// nodes: whole lines from x = 1, the tail a whole line shifted back to end at nx - 2 (the
// in-place tail is a part of that), a row shorter than a line one chunk.
inline std::pair<int, int> chunk_nodes(int c, int nx, int line) {
  int lo = 1 + c * line;
  const int hi = std::min(lo + line - 1, nx - 2);
  if (hi - lo + 1 < line && nx - 2 >= line) lo = nx - 1 - line;
  return {lo, hi};
}

// Streaming by position pays below about 3/4 of the chunks busy (measured: forest and cloud
// bakes at 0.53-0.71 gain 16-26%, a lattice full of medium loses 8%; docs/performance.md).
inline bool mostly_idle(std::size_t busy_chunks, std::size_t chunks) { return 4 * busy_chunks < 3 * chunks; }

// Whether a solver with chunks of `line` nodes would stream g by position (classify_rows).
inline bool position_streaming_pays(const LatticeGeometry& g, int line) {
  const Dims& d = g.dims;
  const int chunks_per_row = (d.nx - 2 + line - 1) / line;
  std::size_t busy = 0, chunks = 0;
  for (int z = 1; z < d.nz - 1; ++z)
    for (int y = 1; y < d.ny - 1; ++y)
      for (int c = 0; c < chunks_per_row; ++c, ++chunks) {
        const auto [lo, hi] = chunk_nodes(c, d.nx, line);
        bool medium = false;  // as classify_rows: density, or a wood node
        for (int x = lo; x <= hi && !medium; ++x) {
          const std::size_t i = d.index(x, y, z);
          medium = g.density[i] != 0.0f || g.material[i] == kMaterialWood;
        }
        busy += medium ? 1 : 0;
      }
  return mostly_idle(busy, chunks);
}

// How a sweep addresses the state (see the top of this file).
enum class Access {
  Pull,     // two levels: gather from src, store to the node's own entries in dst
  SwapOut,  // in place, even step: gather as Pull, store g_m into slot opposite(m) of q + c_m
  SwapIn,   // in place, odd step: f_m from the node's own slot opposite(m), g_m into its slot m
  Shifted,  // streaming by position: f_m(q, t) at (q - t s_m) mod L, collided in place
};

}  // namespace lblight::openmp
