// The coarse interface every compute backend implements (OpenMP, CUDA). One virtual call per
// batch of steps, never per node. The orchestration in lblight/solve only talks to this.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "lblight/core/precision.h"
#include "lblight/lattice/collision_op.h"
#include "lblight/lattice/dense_grid.h"
#include "lblight/lattice/omega.h"

namespace lblight {

// What stays fixed while a lattice is solved: its shape, medium density and material per node.
// The boundary layer (docs/model.md sec. 4) must have density 0.
// A lattice standing on the ground has a layer of ground nodes (kMaterialGround, density 1,
// lattice/ground.h) whole interior rows wide; they are part of the solve, never of the medium.
struct LatticeGeometry {
  Dims dims;
  std::vector<float> density;          // dims.count() values in [0, 1]
  std::vector<std::uint8_t> material;  // dims.count() values < material_count
  int material_count = 1;

  bool has_material(std::uint8_t k) const;  // some node of density > 0 has material k
  // The density with ground nodes at 0: what outputs, masks and statistics of the medium use.
  std::vector<float> medium_density() const;
};

// Checks g against the contract above. Fewer than 3 nodes per edge is an input error
// (Error, InvalidInput); otherwise it throws std::logic_error naming `backend` unless there is
// one density and material per node, material_count in [1, kMaxMaterials], every
// material below it, finite non-negative densities, an empty boundary layer and ground nodes only
// in rows of ground (the CPU runs a row of one material with that material's collision). Backends call it
// before taking the arrays: a GPU kernel picks the collision operator by the material byte, so a
// stray value would silently use another material's (or an unset) operator.
void check_geometry(const LatticeGeometry& g, const char* backend);

// One colour channel: the collision matrix and the absorb flag of every material.
struct ChannelMaterials {
  std::array<OmegaMatrix, kMaxMaterials> omega{};
  std::array<bool, kMaxMaterials> absorbs{};
  // Stored totals are voxel averages (CollisionOp::total_gain; the calibrated model), not sums.
  std::array<bool, kMaxMaterials> voxel_average{};
};

// The collision operator backends apply for material k of a channel.
CollisionOp<double> channel_op(const ChannelMaterials& channel, int material);

// One linear system: a base solution (or a static bake) in one colour channel.
struct SystemSpec {
  int channel = 0;                    // index into the channels given to create()
  std::array<double, 19> boundary{};  // fixed boundary values f_i, i = 0..18
};

// How the stored totals (sum_m f_m per node) changed since the previous measure(), over the
// interior nodes. Sums and maxima only: a backend reduces on its device and returns these.
struct Residual {
  double diff_sq = 0.0;    // sum (total - previous total)^2
  double total_sq = 0.0;   // sum total^2
  double diff_max = 0.0;   // max |total - previous total|
  double total_max = 0.0;  // max |total|
  // Nodes whose material keeps f_0 (absorb false) hold a reservoir that refills at only rho per
  // step: (Omega f)_0 = sigma_a sum_j f_j - f_0 is what it still lacks. Thin fringes (small rho)
  // converge slowly this way, which no geometric extrapolation of the change sees.
  double deficit_sq = 0.0;   // sum (Omega f)_0^2 over such nodes with rho > 0
  double deficit_max = 0.0;  // max |(Omega f)_0| over them
  bool finite = true;      // false once any total is NaN or Inf
};

// How a CPU backend writes the lattice state: non-temporal ("streaming") stores skip the read for
// ownership but bypass the caches, so they pay off only for lattices larger than the cache.
enum class StoreMode { Auto, Regular, Streaming };

struct SolverOptions {
  Precision precision = Precision::Float32;
  int max_systems = 0;  // systems per batch; 0 lets the backend choose from its memory
  StoreMode stores = StoreMode::Auto;
  // CPU: run steps with flush-to-zero and denormals-are-zero set on each worker thread (the
  // caller's floating-point mode is restored afterwards). Subnormal values (below 1.2e-38 in
  // float32) are then 0 instead of costing a microcode assist per operation (docs/stability.md).
  // false keeps the caller's mode, for measurements. GPU backends ignore it.
  bool flush_denormals = true;
  // CPU: steps per pass over the lattice (temporal blocking, docs/performance.md): 1 steps one
  // at a time; k > 1 runs up to k steps in one wavefront pass; 0 lets the backend choose from its
  // cache size (1 where the state fits in the cache anyway). Results are the same bits for any
  // value. GPU backends ignore it.
  int time_block = 0;
  // CPU: false applies every material's Omega in the even/odd form (collide_pairs) even where the
  // symmetry-adapted form would do (collision_op.h, is_cubic), to measure what that form gains;
  // results agree up to float rounding. GPU backends ignore it.
  bool symmetric_collision = true;
  // CPU: rows (and chunks of rows) the light cannot have reached yet since the reset are left at
  // their 0 instead of being swept (the same bits: backends/openmp/lit_spans.h). false sweeps
  // everything, to measure what skipping saves. GPU backends ignore it.
  bool skip_dark = true;
  // CPU: on a sparse lattice (fewer than 3/4 of its chunks hold medium) keep direction m's values at
  // positions that move by c_m each step, so that streaming costs nothing and a step touches only
  // the nodes with medium and the boundary-fed entries; the same bits (backends/openmp,
  // docs/performance.md). false always sweeps every row. GPU backends ignore it.
  bool shift_streaming = true;
  // A backend that does not offer InPlace (bytes_per_system_in_place() == 0) refuses it at create().
  StateLayout layout = StateLayout::TwoLevels;
};

// A solver has up to three parts, one per client (docs/architecture.md, "The backend seam"):
//   LatticeSolver   batch stepping, what a bake runs: every backend has it;
//   KrylovVectors   the vector operations of a Krylov solve (solve/krylov.h), where offered;
//   StateAccess     raw state for tests and diagnostics, where offered.
class KrylovVectors;
class StateAccess;

// A lattice resident on a backend, able to run a batch of systems side by side.
class LatticeSolver {
 public:
  virtual ~LatticeSolver() = default;

  virtual int capacity() const = 0;  // systems one batch may hold
  // Starts a batch: interior state 0 (t = 0), boundary fixed to each system's values.
  virtual void reset(const std::vector<SystemSpec>& batch) = 0;
  virtual void step(int steps) = 0;
  // Recomputes the totals of every system in the batch and how much they changed since the
  // last measure (or since reset). out has one entry per system.
  virtual void measure(std::vector<Residual>& out) = 0;
  // step(steps) then measure(out); a backend may fuse the two (the CPU's temporal blocking).
  virtual void step_and_measure(int steps, std::vector<Residual>& out) {
    step(steps);
    measure(out);
  }
  // Totals (dims.count() values) as of the last measure().
  virtual void read_totals(int system, float* out) const = 0;
  virtual std::size_t bytes_in_use() const = 0;  // memory held on the backend's device
  // Steps run per pass over the state when step() is given that many (temporal blocking,
  // SolverOptions::time_block), as chosen at the last reset: what `bench` divides the memory
  // traffic per update by.
  virtual int steps_per_pass() const { return 1; }
  // Whether the last reset chose streaming by position (the CPU on sparse lattices,
  // docs/performance.md): a step then reads and writes only the nodes of swept_fraction() of
  // the interior, the chunks that hold medium, in one time level.
  virtual bool streams_by_position() const { return false; }
  virtual double swept_fraction() const { return 1.0; }

  // The other parts, or nullptr where this solver does not offer them.
  virtual KrylovVectors* krylov_vectors() { return nullptr; }
  virtual StateAccess* state_access() { return nullptr; }
};

// Vectors for Krylov solvers (solve/krylov.h), shaped like the state of system 0 of the batch
// and living on the backend's device; one call per vector operation. A step is affine,
// T(x) = A x + b; the steady state solves (I - A) x = b. Vectors exclude what the boundary
// fixes (those entries stay 0), so A is one step with all boundary values 0.
class KrylovVectors {
 public:
  virtual ~KrylovVectors() = default;
  virtual void vectors_reserve(int count) = 0;
  virtual void vector_from_state(int v) = 0;       // v = the current state of system 0
  virtual void vector_to_state(int v) = 0;         // system 0's state = v (boundary kept)
  virtual void vector_step_offset(int v) = 0;      // v = b = T(0)
  virtual void vector_apply(int x, int y) = 0;     // y = A x
  virtual void vector_axpby(double a, int x, double b, int y) = 0;  // y = a x + b y
  virtual double vector_dot(int x, int y) = 0;     // summed in a fixed order (deterministic)

  // Fused forms BiCGStab runs (one pass over memory each where a backend fuses them; composed of
  // the operations above by default). Vectors named in one call are distinct.
  virtual void vector_apply_minus(int x, int y) {  // y = x - A x
    vector_apply(x, y);
    vector_axpby(1.0, x, -1.0, y);
  }
  virtual void vector_combine(double a, int x, double b, int y, double c, int z) {  // z = a x + b y + c z
    vector_axpby(b, y, c, z);
    vector_axpby(a, x, 1.0, z);
  }
  virtual void vector_dots(int x, int y, int u, int w, double& xy, double& uw) {  // x.y and u.w
    xy = vector_dot(x, y);
    uw = vector_dot(u, w);
  }
};

// Raw state access for tests, diagnostics and the accelerated solver (solve/dsa.h): 19 * count
// values, direction-major, the values f_m(node) a step starts from (whatever the backend's own
// layout).
class StateAccess {
 public:
  using ModeShapes = std::array<std::array<double, 19>, kMaxMaterials>;
  virtual ~StateAccess() = default;
  virtual void read_state(int system, std::vector<double>& f) const = 0;
  // Keeps the boundary-fed entries at their boundary values.
  virtual void write_state(int system, const std::vector<double>& f) = 0;
  // f_m(q) += shape[material(q)][m] * phi(q) at every interior node q (phi: count values), the
  // boundary-fed entries kept. This default reads and writes the whole state through the two
  // calls above; a backend does it in place where it can.
  virtual void add_mode(int system, const std::vector<double>& phi, const ModeShapes& shape,
                        const std::vector<std::uint8_t>& material);
};

class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string name() const = 0;         // "cpu" or "cuda"
  virtual std::string description() const = 0;  // device and configuration, for logs and manifests
  virtual bool supports(Precision p) const = 0;
  // True when the solver keeps the host's cores busy (OpenMP); false when the host mostly waits
  // on a device, so a bake can write its output on another thread meanwhile.
  virtual bool occupies_host_cores() const = 0;
  // False on the ranks of a distributed backend that only solve their part: they run the same
  // bake, and one rank writes its output.
  virtual bool writes_output() const { return true; }
  // Memory one system needs, and what the device has free, for planning batches.
  virtual std::size_t bytes_per_system(const Dims& dims, Precision p) const = 0;
  // The same with StateLayout::InPlace; 0 where the backend does not offer it.
  virtual std::size_t bytes_per_system_in_place(const Dims&, Precision) const { return 0; }
  // True where the backend runs such a lattice faster in place than with two levels (measured:
  // docs/performance.md), so a bake that may choose does. rewrites_state: the solve rewrites the
  // state between steps (Krylov vectors, DSA corrections), which a backend may do in the natural
  // layout only. The geometry, not only its size: a CPU streams sparse lattices by position, in
  // the two-level layout.
  virtual bool prefers_in_place(const LatticeGeometry&, Precision, bool /*rewrites_state*/) const { return false; }
  virtual std::size_t bytes_per_lattice(const Dims& dims) const = 0;
  virtual std::size_t available_bytes() const = 0;
  // Systems a batch should hold when memory allows: the CPU gains nothing from more than one
  // solution at a time; a GPU fills better with many systems per launch on small lattices.
  virtual int preferred_batch(const Dims& dims, Precision p, int total_systems) const = 0;
  virtual std::unique_ptr<LatticeSolver> create(const LatticeGeometry& geometry,
                                                const std::vector<ChannelMaterials>& channels,
                                                const SolverOptions& options) const = 0;
  // Sustained copy bandwidth of the device's main memory in bytes/s, counting the bytes read
  // plus the bytes written (the same accounting as lattice updates).
  virtual double measure_copy_bandwidth(std::size_t bytes) const = 0;
  // Size of the largest cache in front of that memory (a GPU's L2, a CPU's L3), 0 when unknown:
  // a lattice whose state fits in it is timed against the cache, not the memory.
  virtual std::size_t cache_bytes() const { return 0; }
};

// "float32, float64" for the CPU: the storage precisions `backend` supports, for messages.
std::string supported_precisions(const Backend& backend);

// Bytes one lattice update of one system moves at minimum: 19 values in and out, plus the
// density and material of the node.
inline double bytes_per_update(Precision p) { return 2.0 * 19.0 * bytes_per_value(p) + 4.0 + 1.0; }

}  // namespace lblight
