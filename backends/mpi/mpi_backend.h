// One lattice across MPI ranks (docs/scale-out.md, "One lattice across ranks"): the interior
// layers split into slabs along z, one per rank, each solved by the CPU backend with its
// neighbours' edge layers as ghosts, exchanged every step. Every rank runs the same bake; rank 0
// writes the output.
#pragma once

#include <memory>

#include "lblight/backend/backend.h"

namespace lblight {

// The interior layers [first, last] of rank `rank` of `ranks` for a lattice nz layers high
// (boundary layers 0 and nz - 1 excluded): nz - 2 layers as even as they split, the lower ranks
// taking one more. Needs ranks <= nz - 2.
struct SlabRange {
  int first = 1, last = 0;
};
SlabRange slab_range(int nz, int ranks, int rank);

// Initialises MPI on first use (a process started without mpirun is a single rank) and
// finalises it at exit. threads: per rank, as for the CPU backend.
std::unique_ptr<Backend> make_mpi_backend(int threads);

}  // namespace lblight
