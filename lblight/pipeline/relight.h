// Relighting from base solutions (`lblight relight`, docs/output-format.md, docs/forest.md): the
// light of a static bake assembled as light = s (w_a B_a + w_b B_b + w_c B_c) + a B00 with the
// weights of the sun's direction on the 32-face polyhedron (docs/model.md sec. 4.1), as the .lbh
// reader does per sample. The same numbers a static bake of that sun gives, up to float rounding
// (tests/cli/test_relight_cli.cpp).
#pragma once

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "lblight/core/run_context.h"
#include "lblight/io/vdb_io.h"
#include "lblight/lattice/dense_grid.h"
#include "lblight/lattice/sun.h"
#include "lblight/solve/flux.h"

namespace lblight {

struct RelightRequest {
  Vec3d toward_sun{0, 0, 1};
  double intensity = 1.0;  // s
  double ambient = 0.0;    // a: light of radiance a from every direction (x B00)
  double sky = 0.0;        // light of radiance `sky` from the upper hemisphere only
};

// (base solution, weight) pairs for a sun given as the direction toward it, in the frame of the
// lattice being relit: the sun's three directions (weights x intensity, negligible ones dropped),
// then B00 x ambient, then the sky: its radiance on every downward lattice direction and half of
// it on the level ones (which stand for the band around the horizon), so a sky of S is the upper
// half of an ambient of S (open air: 9 S against 18 S; docs/forest.md sec. 4). Yaw turns map the
// sky onto itself. Error(InvalidInput) for a zero or non-finite direction.
std::vector<std::pair<int, double>> relight_weights(const RelightRequest& request);

// The checks every reader of a bake's base solution applies before using its values (relight,
// render, compare, forests): grid `solution` of `file` is on the density's lattice box and
// transform, tagged (lblight_solution, when present) as that solution, and finite everywhere.
// Error(InvalidInput) naming the file, the grid and what differs: a grid copied in from another
// bake, renamed, or damaged would otherwise relight into a plausible wrong picture.
void check_base_solution_grid(const DenseGridIn& grid, int solution, const DenseFrame& density_frame,
                              const std::filesystem::path& file);

// The manifest.json beside `vdb` (when there is one) gives the model it names the lattice box of
// `frame`; Error(InvalidInput) naming the .vdb when it does not (a .vdb copied in from another bake).
void check_manifest_lattice(const std::filesystem::path& vdb, const DenseFrame& frame);

// The base-solution grids of one bake .vdb (density, brown and the B.. grids asked for), on the
// bake's lattice box.
class BaseSolutions {
 public:
  // Reads `solutions` (every B.. grid the file has when nullopt). Error(InvalidInput) naming the
  // file when it is not an lblight bake, or when a listed solution was left out by the bake
  // (`why`: what needed it).
  BaseSolutions(const std::filesystem::path& vdb, const std::optional<std::set<int>>& solutions, const std::string& why,
                const RunContext& ctx = {});
  const std::filesystem::path& file() const { return file_; }
  const DenseFrame& frame() const { return frame_; }
  const std::vector<float>& density() const { return density_; }
  const std::vector<float>& wood() const { return wood_; }  // empty when the model has none
  const nlohmann::json& density_metadata() const { return density_metadata_; }  // materials, voxel size
  bool has(int solution) const { return grids_.count(solution) > 0; }
  // sum_k weight_k B_k per channel, in double and rounded once, at `nodes` (every node when
  // null); out[c] must hold frame().dims.count() values.
  void combine(const std::vector<std::pair<int, double>>& weights, std::array<std::vector<float>, 3>& out,
               const std::vector<std::size_t>* nodes = nullptr) const;
  // Whether every solution read came with its flux grids (<Bnn>_flux_r/_g/_b; a bake with
  // output.moments), and their sum with the same weights (per channel, per axis).
  bool has_flux() const { return has_flux_; }
  void combine_flux(const std::vector<std::pair<int, double>>& weights, std::array<FluxField, 3>& out,
                    const std::vector<std::size_t>* nodes = nullptr) const;

 private:
  std::filesystem::path file_;
  DenseFrame frame_;
  std::vector<float> density_, wood_;
  nlohmann::json density_metadata_;
  std::map<int, std::array<std::vector<float>, 3>> grids_;
  std::map<int, std::array<FluxField, 3>> flux_;
  bool has_flux_ = false;
};

struct RelitModel {
  DenseFrame frame;                            // the bake's lattice box
  std::array<std::vector<float>, 3> light;     // 0 outside the occupied nodes and their neighbours
  std::vector<float> density;                  // on the same frame
  std::vector<float> wood;                     // 1 on wood nodes; empty when the model has none
  nlohmann::json density_metadata;            // the bake's density metadata: materials, voxel size
  std::vector<std::pair<int, double>> weights; // (base solution, weight) used
  std::array<FluxField, 3> flux;               // per channel and axis; empty when the bake has no moments
};

// One bake .vdb relit. Error(InvalidInput) naming the file and the grid when the bake left out a
// solution this sun needs (a sun outside the scene's sun_range, or an instance rotation it did
// not declare) or holds a static bake.
RelitModel relight_model(const std::filesystem::path& vdb, const RelightRequest& request, const RunContext& ctx = {});

}  // namespace lblight
