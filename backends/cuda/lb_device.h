// What one GPU thread does, as LBL_HOSTDEV functions over plain arguments. The CUDA/HIP kernels
// in cuda_backend.cu are thin wrappers around these, and tests/backend/emulated_gpu.cpp runs the
// very same functions over emulated launch grids on the CPU, so indexing, inflow and reductions are
// checked even on machines without a GPU. The physics itself is lattice/collide.h, the other
// per-node rules backend/node_rules.h.
#pragma once

#include <cstddef>
#include <cstdint>

#include "lblight/backend/node_rules.h"
#include "lblight/lattice/collide.h"
#include "lblight/lattice/lattice.h"

namespace lblight::gpu {

inline constexpr int kMaxBatch = 64;     // systems one launch updates side by side
inline constexpr int kMaxChannels = 3;   // distinct colour channels per lattice

// How a storage type converts to and from the float arithmetic. float here; the .cu file adds
// the half-precision specialisation.
template <typename T>
struct Storage;
template <>
struct Storage<float> {
  LBL_HOSTDEV static float load(float v) { return v; }
  LBL_HOSTDEV static float store(float v) { return v; }
};

// How a step addresses the state.
//   Push: two levels. Node i reads its own values f_m(i) in cur and pushes value m to node i + c_m
//   in next.
//   In place (StateLayout::InPlace, docs/model.md sec. 3.1): the AA pattern on one level
//   (cur == next), two kinds of step taking turns:
//   SwapOut: node i reads its own slots (the natural layout) and stores value m into its own slot
//            opposite(m). The state is then swapped: f_m(i) sits in slot opposite(m) of i - c_m.
//   SwapIn:  node i reads f_m from slot opposite(m) of i - c_m and stores value m into slot m of
//            i + c_m: the natural layout again.
// Either way a step's threads read and write the same entries, each entry one thread's, so no two
// race. In place, values leaving the lattice are dropped rather than stored: the slots they would
// land in hold the boundary's inflow (interior slots for the natural layout, boundary-node slots
// for the swapped one), which no step writes, so inflow_node fills each once.
enum class Access : int { Push, SwapOut, SwapIn };

// Everything a thread needs about the batch, passed by value to every kernel. Direction m of
// node i of system s sits at cur[s * system_stride + m * stride + i] (the current state, in the
// natural layout) and next[...] (where a step writes); a Krylov solve points cur and next at its
// vectors. In place cur == next, and `access` says how the next step runs (SwapIn: the state is
// swapped), which measure_node follows too.
template <typename T>
struct BatchArgs {
  Dims d;
  long long stride = 0;         // elements between direction arrays (>= node count)
  long long system_stride = 0;  // elements between systems
  int systems = 0;
  const float* density = nullptr;
  const std::uint8_t* material = nullptr;
  T* cur = nullptr;
  T* next = nullptr;
  float* totals = nullptr;      // systems x node count, as of the last measure
  Access access = Access::Push;
};

// Offset of node i + c_m from node i in a direction array.
LBL_HOSTDEV LBL_FORCEINLINE long long neighbour_shift(const Dims& d, int m) {
  return d3q19::cx(m) + d3q19::cy(m) * static_cast<long long>(d.nx) +
         d3q19::cz(m) * static_cast<long long>(d.nx) * d.ny;
}

// Where value f_m of a node sits relative to that node's slot 0, as a step of access A reads it.
template <Access A>
LBL_HOSTDEV LBL_FORCEINLINE long long read_offset(const Dims& d, long long stride, int m) {
  if (A == Access::SwapIn) return d3q19::opposite(m) * stride - neighbour_shift(d, m);
  return m * stride;
}
// The same for the access a's next step runs (a runtime choice, for inflow and measure).
template <typename T>
LBL_HOSTDEV LBL_FORCEINLINE long long read_offset(const BatchArgs<T>& a, int m) {
  return a.access == Access::SwapIn ? read_offset<Access::SwapIn>(a.d, a.stride, m)
                                    : read_offset<Access::Push>(a.d, a.stride, m);
}

// Interior node (x, y, z) touches the boundary layer (some c_m leads into it).
LBL_HOSTDEV LBL_FORCEINLINE bool next_to_boundary(const Dims& d, int x, int y, int z) {
  return x == 1 || y == 1 || z == 1 || x == d.nx - 2 || y == d.ny - 2 || z == d.nz - 2;
}

// Per-batch tables behind one small interface that step_node, inflow_node and measure_node take:
//   int channel(int s); unsigned absorb_bits(int c); float boundary(int s, int m);
//   const CollisionOp<float>& op(int c, int k);
// BatchTables holds them on the host (gpu_solver.h fills it per batch); the CUDA kernels read a
// copy in constant memory (cuda_backend.cu), the emulation reads this one.
struct BatchTables {
  CollisionOp<float> ops[kMaxChannels][kMaxMaterials];
  unsigned absorb[kMaxChannels];        // per channel: bit k set when material k absorbs
  int channels[kMaxBatch];              // per system: its channel
  float boundaries[kMaxBatch][19];      // per system: its boundary values
  float boundary_totals[kMaxBatch];     // per system: boundary_total(), rounded once as the CPU does
  int channel(int s) const { return channels[s]; }
  unsigned absorb_bits(int c) const { return absorb[c]; }
  float boundary(int s, int m) const { return boundaries[s][m]; }
  const CollisionOp<float>& op(int c, int k) const { return ops[c][k]; }
};

// One LB step for interior node (x, y, z) of systems [s_begin, s_end) of the batch, addressed
// as A says (a.access names the same; the launch picks the instance).
template <Access A, typename T, typename Tables>
LBL_HOSTDEV LBL_FORCEINLINE void step_node(const BatchArgs<T>& a, const Tables& tb, int x, int y, int z, int s_begin,
                                           int s_end) {
  const std::size_t i = a.d.index(x, y, z);
  const float rho = a.density[i];
  const unsigned k = a.material[i];
  const bool edge = A != Access::Push && next_to_boundary(a.d, x, y, z);
  for (int s = s_begin; s < s_end; ++s) {
    const int c = tb.channel(s);
    const T* src = a.cur + s * a.system_stride + i;
    T* dst = a.next + s * a.system_stride + i;
    float f[d3q19::kQ];
    LBL_UNROLL
    for (int m = 0; m < d3q19::kQ; ++m) f[m] = Storage<T>::load(src[read_offset<A>(a.d, a.stride, m)]);
    const float keep = f0_keep<float>(tb.absorb_bits(c), k);
    const auto push = [&](int m, float v) {
      if (edge && fed_by_boundary(a.d, x, y, z, d3q19::opposite(m))) return;  // in place: it leaves the lattice
      dst[A == Access::SwapOut ? d3q19::opposite(m) * a.stride : m * a.stride + neighbour_shift(a.d, m)] =
          Storage<T>::store(v);
    };
    // The operator picked with literal indices: its ~180 coefficients are then read at fixed
    // addresses (on the GPU, constant-bank operands of the FMAs) instead of through a per-thread
    // address, which costs a separate load each and serializes in a warp straddling two materials.
    static_assert(kMaxChannels == 3 && kMaxMaterials == 3, "one case per channel and material");
    switch (c * kMaxMaterials + static_cast<int>(k)) {
      case 0: collide_node(tb.op(0, 0), keep, rho, f, push); break;
      case 1: collide_node(tb.op(0, 1), keep, rho, f, push); break;
      case 2: collide_node(tb.op(0, 2), keep, rho, f, push); break;
      case 3: collide_node(tb.op(1, 0), keep, rho, f, push); break;
      case 4: collide_node(tb.op(1, 1), keep, rho, f, push); break;
      case 5: collide_node(tb.op(1, 2), keep, rho, f, push); break;
      case 6: collide_node(tb.op(2, 0), keep, rho, f, push); break;
      case 7: collide_node(tb.op(2, 1), keep, rho, f, push); break;
      default: collide_node(tb.op(2, 2), keep, rho, f, push); break;
    }
  }
}

// Writes the boundary-fed entries of interior node (x, y, z) into `level` (the state layout of
// every system) where a step of a.access reads them: the systems' boundary values, or 0 for a
// Krylov vector. Push and SwapOut read slot m of the node, SwapIn slot opposite(m) of the
// boundary node i - c_m; in place each layout has its own, written once.
template <typename T, typename Tables>
LBL_HOSTDEV LBL_FORCEINLINE void inflow_node(const BatchArgs<T>& a, const Tables& tb, T* level, bool zero, int x,
                                             int y, int z) {
  const std::size_t i = a.d.index(x, y, z);
  for (int s = 0; s < a.systems; ++s) {
    T* f = level + s * a.system_stride + i;
    for (int m = 1; m < d3q19::kQ; ++m)
      if (fed_by_boundary(a.d, x, y, z, m)) {
        f[read_offset(a, m)] = Storage<T>::store(zero ? 0.0f : tb.boundary(s, m));
      }
  }
}

// Totals of system s at interior node (x, y, z): stores them and returns how they changed
// (node_residual, backend/node_rules.h, over this layout).
template <typename T, typename Tables>
LBL_HOSTDEV LBL_FORCEINLINE NodeResidual measure_node(const BatchArgs<T>& a, const Tables& tb, int s, int x, int y,
                                                      int z) {
  const std::size_t i = a.d.index(x, y, z);
  const T* src = a.cur + s * a.system_stride + i;
  float f[d3q19::kQ];
  LBL_UNROLL
  for (int m = 0; m < d3q19::kQ; ++m) f[m] = Storage<T>::load(src[read_offset(a, m)]);
  float* total = a.totals + static_cast<std::size_t>(s) * a.d.count() + i;
  const int c = tb.channel(s);
  const unsigned k = a.material[i];
  return node_residual(tb.op(c, static_cast<int>(k)), f0_keep<float>(tb.absorb_bits(c), k) != 0.0f, a.density[i], f,
                       *total, *total);
}

// How step threads cover the interior: blocks of kStepThreads threads, bx along x times
// by = kStepThreads / bx rows along y, one z plane per block. Threads start at x = 0 (x = 0
// idles) so a warp's loads begin on a row's first element, aligned when nx is a multiple of 32.
// bx is the width in {128, 64, 32} that pads a row's nx - 1 threads least (the widest on ties):
// nx = 130 with 128-wide blocks would spend half its blocks on one node each, and nx <= 64 would
// leave half of every block idle.
//
// A thread steps its node for a run of the batch's systems. One run of all of them when the
// interior alone gives kStepFillThreads threads; a small lattice splits its systems into groups,
// one per copy of the z planes along the grid's z (block z = group * (nz - 2) + plane), so that
// 32^3 with 57 systems launches 19 x 27k threads of 3 systems each instead of 27k threads of 57,
// a quarter of what an H100 holds resident (132 SMs x 6 blocks of 128).
inline constexpr int kStepThreads = 128;
inline constexpr long long kStepFillThreads = 512 * 1024;
struct StepLaunch {
  int bx = kStepThreads, by = 1;       // block shape
  long long gx = 0, gy = 0, gz = 0;    // grid, in blocks
  int per_group = 1;                   // systems per thread (the last group may have fewer)
  int groups = 1;                      // copies of the z planes, one per run of systems
};
inline StepLaunch step_launch(const Dims& d, int systems, long long fill_threads = kStepFillThreads) {
  StepLaunch l;
  const long long row = d.nx - 1;  // threads x = 0 .. nx - 2
  long long best = -1;
  for (int bx = kStepThreads; bx >= 32; bx /= 2) {
    const long long padded = (row + bx - 1) / bx * bx;
    if (best < 0 || padded < best) {
      best = padded;
      l.bx = bx;
    }
  }
  l.by = kStepThreads / l.bx;
  l.gx = (row + l.bx - 1) / l.bx;
  l.gy = (d.ny - 2 + l.by - 1) / l.by;
  if (d.interior_count() == 0 || systems < 1) return l;  // nothing to step: gz = 0
  const long long planes = d.nz - 2, interior = static_cast<long long>(d.interior_count());
  long long groups = (fill_threads + interior - 1) / interior;
  if (groups > systems) groups = systems;
  if (groups > 65535 / planes) groups = 65535 / planes;  // the grid's z limit
  if (groups < 1) groups = 1;
  l.per_group = static_cast<int>((systems + groups - 1) / groups);
  l.groups = static_cast<int>((systems + l.per_group - 1) / l.per_group);  // no empty group
  l.gz = planes * l.groups;
  return l;
}
// The node of thread (tx, ty) in block (bx, by, bz) of such a launch (block shape bdx x bdy) and
// the systems [s_begin, s_end) it steps; false for threads off the interior, which return at once.
// OneRow (by == 1) is the same with y the same for the whole block: row addresses can then stay
// in the GPU's per-warp uniform registers (register counts: docs/performance.md).
template <bool OneRow>
LBL_HOSTDEV inline bool step_thread_node(const Dims& d, int per_group, int systems, unsigned bx, unsigned by,
                                         unsigned bz, unsigned bdx, unsigned bdy, unsigned tx, unsigned ty, int& x,
                                         int& y, int& z, int& s_begin, int& s_end) {
  const unsigned planes = static_cast<unsigned>(d.nz - 2);
  const unsigned group = bz / planes;  // block-uniform
  x = static_cast<int>(bx * bdx + tx);
  y = OneRow ? 1 + static_cast<int>(by) : 1 + static_cast<int>(by * bdy + ty);
  z = 1 + static_cast<int>(bz - group * planes);
  s_begin = static_cast<int>(group) * per_group;
  s_end = s_begin + per_group < systems ? s_begin + per_group : systems;
  return x >= 1 && x < d.nx - 1 && (OneRow || y < d.ny - 1);
}

// Only interior nodes next to the boundary layer receive inflow (fed_by_boundary). The inflow
// launch covers the rows (y, z) with y or z next to the boundary whole, one block per row
// striding along x, and the other rows' two end nodes (x = 1 and nx - 2), one thread per row:
// at 128^3 ~620 blocks of 128 threads instead of one per interior row (15876, nearly all idle),
// which counts because a Krylov solve runs it at every operator product.
inline constexpr int kInflowThreads = 128;
struct InflowLaunch {
  long long plane_rows = 0;  // blocks 0 .. plane_rows - 1: the rows of planes z = 1 and nz - 2
  long long face_rows = 0;   // blocks plane_rows .. face_rows - 1: rows y = 1, ny - 2 of the others
  long long end_rows = 0;    // rows needing their ends only, kInflowThreads per block after those
  long long blocks = 0;
};
// How many of the coordinates 1 and n - 2 are distinct interior ones (n - 2 = 1: a single one).
LBL_HOSTDEV inline int edge_coordinates(int n) { return n - 2 >= 2 ? 2 : (n - 2 == 1 ? 1 : 0); }
LBL_HOSTDEV inline int middle_coordinates(int n) { return n - 4 > 0 ? n - 4 : 0; }
inline InflowLaunch inflow_launch(const Dims& d) {
  InflowLaunch l;
  if (d.interior_count() == 0) return l;
  l.plane_rows = static_cast<long long>(edge_coordinates(d.nz)) * (d.ny - 2);
  l.face_rows = l.plane_rows + static_cast<long long>(middle_coordinates(d.nz)) * edge_coordinates(d.ny);
  l.end_rows = static_cast<long long>(middle_coordinates(d.ny)) * middle_coordinates(d.nz);
  l.blocks = l.face_rows + (l.end_rows + kInflowThreads - 1) / kInflowThreads;
  return l;
}
// Calls node(x, y, z) for the nodes thread tx of block b covers (block size `threads`).
template <typename Node>
LBL_HOSTDEV inline void inflow_thread_nodes(const Dims& d, const InflowLaunch& l, long long b, int tx, int threads,
                                            Node&& node) {
  int y, z;
  if (b < l.face_rows) {
    if (b < l.plane_rows) {  // z = 1 or nz - 2: every row
      z = b < d.ny - 2 ? 1 : d.nz - 2;
      y = 1 + static_cast<int>(b % (d.ny - 2));
    } else {  // a middle plane: rows y = 1 and ny - 2
      const long long r = b - l.plane_rows;
      const int ey = edge_coordinates(d.ny);
      z = 2 + static_cast<int>(r / ey);
      y = r % ey == 0 ? 1 : d.ny - 2;
    }
    for (int x = 1 + tx; x < d.nx - 1; x += threads) node(x, y, z);
    return;
  }
  const long long t = (b - l.face_rows) * threads + tx;
  if (t >= l.end_rows) return;
  const int my = middle_coordinates(d.ny);
  y = 2 + static_cast<int>(t % my);
  z = 2 + static_cast<int>(t / my);
  node(1, y, z);
  if (d.nx - 2 > 1) node(d.nx - 2, y, z);
}

// Interior node number n (x fastest) to coordinates.
LBL_HOSTDEV inline void interior_coords(const Dims& d, long long n, int& x, int& y, int& z) {
  const long long ix = d.nx - 2, iy = d.ny - 2;
  x = 1 + static_cast<int>(n % ix);
  y = 1 + static_cast<int>((n / ix) % iy);
  z = 1 + static_cast<int>(n / (ix * iy));
}

// Systems per launch: enough to fill the GPU several times over (4M node updates), and no more.
// At 128^3 one system is already ~2M threads, and a batch both runs until its slowest system
// converges and hands its solutions to the output (written alongside the next batch's solve)
// only when it ends; small lattices batch many systems to keep launches large.
inline int systems_to_fill(const Dims& d, int total_systems) {
  constexpr double kFillNodes = 4.0 * 1024 * 1024;
  const double interior = static_cast<double>(d.interior_count() > 0 ? d.interior_count() : 1);
  int want = static_cast<int>(kFillNodes / interior + 0.999999);
  if (want > kMaxBatch) want = kMaxBatch;
  if (want > total_systems) want = total_systems;
  return want < 1 ? 1 : want;
}

// Direction-array stride for GPU state: a multiple of 32 elements keeps every array aligned for
// coalesced access.
inline long long gpu_stride(const Dims& d) {
  const long long n = static_cast<long long>(d.count());
  return (n + 31) / 32 * 32;
}

}  // namespace lblight::gpu
