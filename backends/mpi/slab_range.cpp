#include "backends/mpi/mpi_backend.h"

#include <stdexcept>

namespace lblight {

SlabRange slab_range(int nz, int ranks, int rank) {
  const int layers = nz - 2;
  if (ranks < 1 || rank < 0 || rank >= ranks || layers < ranks)
    throw std::logic_error("slab_range: " + std::to_string(ranks) + " ranks for " + std::to_string(layers) + " layers");
  const int base = layers / ranks, extra = layers % ranks;
  SlabRange r;
  r.first = 1 + rank * base + std::min(rank, extra);
  r.last = r.first + base + (rank < extra ? 1 : 0) - 1;
  return r;
}

}  // namespace lblight
