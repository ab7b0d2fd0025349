// Helpers shared by the tests: lattice builders, solving helpers, temporary folders and running
// the CLI. The literal reference LB is tests/support/reference_lattice.h (included here).
#pragma once

#include <array>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "lblight/backend/backend.h"
#include "lblight/core/relative_gap.h"
#include "lblight/io/vdb_io.h"
#include "lblight/solve/bake.h"
#include "lblight/solve/plan.h"
#include "lblight/lattice/omega.h"
#include "tests/support/reference_lattice.h"

namespace lblight::test {

LatticeGeometry uniform_lattice(Dims d, float rho);  // boundary layer empty
// Random densities in [min_rho, max_rho] on the interior (a fifth of the nodes empty), wood
// (material 1) where `wood_fraction` hits.
LatticeGeometry random_lattice(Dims d, float max_rho, double wood_fraction, unsigned seed, float min_rho = 0.0f);

ChannelMaterials channel(const OpticalParams& medium, bool absorbs,
                         const OpticalParams& wood = {0.1, 0.9, -1.0}, bool wood_absorbs = false);
SystemSpec system_for(int channel, const std::array<double, 19>& boundary);

// The lattice direction m (1..18) with velocity (x, y, z); throws std::logic_error for any other
// vector, which fails the calling test.
int lattice_direction(int x, int y, int z);

// Geometries that break LatticeGeometry's contract, one fault each, with a word the backend's
// error must contain (see check_geometry in lblight/backend/backend.h).
struct BrokenGeometry {
  std::string fault, expect;
  LatticeGeometry g;
};
std::vector<BrokenGeometry> broken_geometries();

std::unique_ptr<Backend> cpu_backend(int threads = 0);

// A solver's raw state and Krylov parts (backend.h); std::logic_error, failing the test, where
// the solver does not offer them.
StateAccess& state_of(LatticeSolver& solver);
KrylovVectors& krylov_of(LatticeSolver& solver);

// Runs `steps` steps and returns the totals of one system (after a measure()).
std::vector<float> solve_totals(const Backend& backend, const LatticeGeometry& g, const std::vector<ChannelMaterials>& ch,
                                const SystemSpec& sys, int steps, Precision p = Precision::Float32);

// Totals of every system of `batch` after `steps` steps, run side by side as one batch.
std::vector<std::vector<float>> solve_batch_totals(const Backend& backend, const LatticeGeometry& g,
                                                   const std::vector<ChannelMaterials>& ch,
                                                   const std::vector<SystemSpec>& batch, int steps,
                                                   Precision p = Precision::Float32);
// Three leaf-like channels that differ (absorbing, g per channel) with bark-like wood (g = -1).
const std::vector<ChannelMaterials>& leaf_channels();

// The same in double from the raw state (for float64 runs, whose totals read_totals rounds).
std::vector<double> solve_totals_f64(const Backend& backend, const LatticeGeometry& g,
                                     const std::vector<ChannelMaterials>& ch, const SystemSpec& sys, int steps);
// max_relative_difference(ref, got, floor), keep_worst(worst, v): lblight/core/relative_gap.h.

// Keeps every solution a bake hands over, by base solution index (-1: a static bake).
class KeepSolutions final : public BakeObserver {
 public:
  explicit KeepSolutions(std::map<int, SolutionResult>& out) : out_(out) {}
  void solution_done(const ModelPlan&, SolutionResult& r) override { out_[r.plan.index] = std::move(r); }

 private:
  std::map<int, SolutionResult>& out_;
};

class TempDir {
 public:
  TempDir();
  ~TempDir();
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

struct CliResult {
  int exit_code = -1;
  std::string out, err;
};
// Runs the lblight binary with `args` (a shell-quoted string) in `cwd`.
CliResult run_cli(const std::string& args, const std::filesystem::path& cwd = {});

void write_text(const std::filesystem::path& file, const std::string& text);
std::string read_text(const std::filesystem::path& file);

// n^3 nodes from index (0, 0, 0), cubic voxels `voxel` wide, no rotation or offset.
DenseFrame cube_frame(int n, double voxel);
// Writes `density` as the one grid "density" of `file` (lblight's own writer, no file metadata).
void write_density_vdb(const std::filesystem::path& file, const DenseFrame& frame, const std::vector<float>& density);

// Bakes the first model of `scene` on the OpenMP backend through a full BakeOutput into `out_dir`
// (grids, .lbh when asked, manifest), keeping each solution's result as it was before the
// output took its totals.
struct BakedModel {
  BakePlan plan;
  std::vector<SolutionResult> kept;
  const ModelPlan& model() const { return plan.models.at(0); }
};
BakedModel bake_first_model(const Scene& scene, const std::filesystem::path& out_dir,
                            bool write_in_background = false);

}  // namespace lblight::test
