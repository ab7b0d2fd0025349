#include "lblight/pipeline/bake_output.h"

#include "lblight/lattice/lb_model.h"

#include "lblight/pipeline/relight.h"
#include "lblight/pipeline/work_units.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>

#include <spdlog/spdlog.h>

#include "lblight/compress/lbh_writer.h"
#include "lblight/core/input_file.h"
#include "lblight/core/system_info.h"
#include "lblight/core/version.h"
#include "lblight/io/nanovdb_io.h"
#include "lblight/io/vdb_io.h"
#include "lblight/lattice/ground.h"

namespace lblight {

namespace {
nlohmann::json finite_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }
}  // namespace

void write_raw_totals(const std::filesystem::path& file, const std::array<std::vector<float>, 3>& totals) {
  std::ofstream out(file, std::ios::binary);
  for (const std::vector<float>& c : totals)
    out.write(reinterpret_cast<const char*>(c.data()), static_cast<std::streamsize>(c.size() * sizeof(float)));
  out.flush();
  if (!out) throw_io("cannot write the totals (disk full?)", {file.string(), {}, {}});
}

void write_raw_flux(const std::filesystem::path& file, const std::array<FluxField, 3>& flux) {
  std::ofstream out(file, std::ios::binary);
  for (const FluxField& c : flux)
    for (const std::vector<float>& axis : c)
      out.write(reinterpret_cast<const char*>(axis.data()), static_cast<std::streamsize>(axis.size() * sizeof(float)));
  out.flush();
  if (!out) throw_io("cannot write the flux (disk full?)", {file.string(), {}, {}});
}

std::array<FluxField, 3> read_raw_flux(const std::filesystem::path& file, std::size_t nodes) {
  const std::uint64_t bytes = check_regular_file(file, "unit flux file");
  if (bytes != 9 * nodes * sizeof(float))
    throw_invalid("holds " + std::to_string(bytes) + " bytes, not the " + std::to_string(9 * nodes * sizeof(float)) +
                      " of 3 channels x 3 axes x " + std::to_string(nodes) + " lattice nodes",
                  {file.string(), {}, {}});
  std::ifstream in(file, std::ios::binary);
  std::array<FluxField, 3> flux;
  for (FluxField& c : flux)
    for (std::vector<float>& axis : c) {
      axis.resize(nodes);
      in.read(reinterpret_cast<char*>(axis.data()), static_cast<std::streamsize>(nodes * sizeof(float)));
    }
  if (!in) throw_io("cannot read", {file.string(), {}, {}});
  return flux;
}

std::array<std::vector<float>, 3> read_raw_totals(const std::filesystem::path& file, std::size_t nodes) {
  const std::uint64_t bytes = check_regular_file(file, "unit totals file");
  if (bytes != 3 * nodes * sizeof(float))
    throw_invalid("holds " + std::to_string(bytes) + " bytes, not the " + std::to_string(3 * nodes * sizeof(float)) +
                      " of 3 x " + std::to_string(nodes) + " lattice nodes",
                  {file.string(), {}, {}});
  std::ifstream in(file, std::ios::binary);
  std::array<std::vector<float>, 3> totals;
  for (std::vector<float>& c : totals) {
    c.resize(nodes);
    in.read(reinterpret_cast<char*>(c.data()), static_cast<std::streamsize>(nodes * sizeof(float)));
  }
  if (!in) throw_io("cannot read", {file.string(), {}, {}});
  return totals;
}

nlohmann::json material_json(const Material& m) {
  nlohmann::json j;
  j["name"] = m.name;
  j["absorb"] = m.absorbs;
  for (const char* key : {"sigma_a", "sigma_s", "g"}) j[key] = nlohmann::json::array();
  for (int c = 0; c < kChannels; ++c) {
    j["sigma_a"].push_back(m.channel[c].sigma_a);
    j["sigma_s"].push_back(m.channel[c].sigma_s);
    j["g"].push_back(m.channel[c].g);
  }
  return j;
}

// Self-describing (docs/output-format.md, "What a .vdb says about itself"): the density grid
// carries what a shader needs without manifest.json beside the file.
nlohmann::json material_metadata(const ModelPlan& mp, bool has_wood) {
  const auto& m = mp.grid.index_to_world;
  nlohmann::json j;
  j["lblight_voxel_size"] = std::sqrt(m[0] * m[0] + m[4] * m[4] + m[8] * m[8]);
  j["lblight_material_medium"] = material_json(mp.spec->material).dump();
  if (has_wood) j["lblight_material_wood"] = material_json(mp.spec->wood_material).dump();
  j["lblight_density_meaning"] =
      "density d in 0..1 scales the material: extinction per world unit = d (sigma_a + sigma_s) / "
      "lblight_voxel_size, scattering d sigma_s / lblight_voxel_size (sigma per voxel edge and colour channel "
      "in lblight_material_medium, or lblight_material_wood where brown > 0.5)";
  j["lblight_lb_model"] = mp.model.name();
  j["lblight_delta_m"] = mp.model.calibrated && mp.model.delta_m;  // as the manifest's solved_with_delta_m
  return j;
}

std::array<double, 3> lattice_origin_world(const ModelPlan& mp) {
  const auto& m = mp.grid.index_to_world;
  std::array<double, 3> o{};
  for (int r = 0; r < 3; ++r)
    o[r] = m[r * 4 + 0] * mp.lattice_index_min[0] + m[r * 4 + 1] * mp.lattice_index_min[1] +
           m[r * 4 + 2] * mp.lattice_index_min[2] + m[r * 4 + 3];
  return o;
}

nlohmann::json lattice_json(const ModelPlan& mp) {
  nlohmann::json j;
  const Dims& d = mp.lattice.dims;
  j["dims"] = {d.nx, d.ny, d.nz};
  j["margin"] = mp.spec->margin;
  j["index_min"] = mp.lattice_index_min;
  const auto vs = mp.grid.voxel_size();
  j["voxel_size"] = vs;
  j["origin"] = lattice_origin_world(mp);
  j["index_to_world"] = mp.grid.index_to_world;
  return j;
}

nlohmann::json savings_json(const ModelPlan& mp) {
  const PlanSavings& sv = mp.savings;
  const Dims& f = sv.full_lattice;
  const Dims& d = mp.lattice.dims;
  nlohmann::json j;
  nlohmann::json left = nlohmann::json::array();
  for (int idx : sv.solutions_left_out) left.push_back(base_grid_name(idx));
  j["solutions_left_out"] = left;
  j["solutions_solved"] = mp.solved_solutions();
  j["ambient_from_sum"] = sv.ambient_from_sum;
  j["channels_solved"] = sv.channels_solved;
  j["cropped"] = sv.cropped;
  j["full_lattice_dims"] = {f.nx, f.ny, f.nz};
  j["lattice_node_fraction"] = f.count() > 0 ? static_cast<double>(d.count()) / static_cast<double>(f.count()) : 1.0;
  // Lattice updates relative to baking 19 solutions x 3 channels on the uncropped lattice.
  j["work_fraction"] = static_cast<double>(mp.systems()) * static_cast<double>(d.interior_count()) /
                       (19.0 * 3.0 * static_cast<double>(std::max<std::size_t>(1, f.interior_count())));
  return j;
}

BakeOutput::BakeOutput(const BakePlan& plan, const std::filesystem::path& target, BakeRunInfo info,
                       bool write_in_background, OutputKind kind)
    : plan_(plan), dir_(target, kind), info_(std::move(info)), worker_(write_in_background) {
  if (info_.unit.is_object() && info_.unit.contains("solutions")) unit_solutions_ = info_.unit["solutions"].size();
}

std::size_t BakeOutput::solutions_expected(const ModelPlan& mp) const {
  return unit_solutions_ ? unit_solutions_ : mp.solutions.size();
}

BakeOutput::~BakeOutput() = default;

namespace {
// Lattice layer 1 (the ground) takes the values of layer 2.
void copy_up_to_ground(const Dims& d, std::vector<float>& v) {
  for (int y = 0; y < d.ny; ++y)
    for (int x = 0; x < d.nx; ++x) v[d.index(x, y, 1)] = v[d.index(x, y, 2)];
}

// The solution's value in open air (an empty lattice), per colour channel: its boundary's moving
// values, over a ground with the open ground's reflection in place of the light from below.
std::array<double, 3> open_air_value(const ModelPlan& mp, const SolutionPlan& s) {
  std::array<double, 3> v{};
  for (int c = 0; c < 3; ++c) {
    const auto b = mp.ground.on ? with_open_ground(s.boundary, mp.ground.albedo[static_cast<std::size_t>(c)], mp.ground.share)
                                : s.boundary;
    for (int m = 1; m < 19; ++m) v[static_cast<std::size_t>(c)] += b[static_cast<std::size_t>(m)];
  }
  return v;
}

std::string light_units(const ModelPlan& mp, const SolutionPlan& s) {
  std::string u = "1 = the open-air light of a unit sun";
  if (mp.ground.on)
    u += "'s beam; the ground (albedo " + message_number(mp.ground.albedo[0]) + ", " + message_number(mp.ground.albedo[1]) +
         ", " + message_number(mp.ground.albedo[2]) +
         ") hides the light from below and sends back albedo x the light sent down";
  const auto v = open_air_value(mp, s);
  std::string value = message_number(v[0]);
  if (v[1] != v[0] || v[2] != v[0]) value += ", " + message_number(v[1]) + ", " + message_number(v[2]) + " (R, G, B)";
  return u + "; this solution is " + value + " in open air";
}

nlohmann::json lattice_box_json(const ModelPlan& mp) {
  const Dims& d = mp.lattice.dims;
  return {{"lblight_lattice_min", mp.lattice_index_min}, {"lblight_lattice_dims", {d.nx, d.ny, d.nz}}};
}
DenseFrame dense_frame(const ModelPlan& mp) { return {mp.lattice.dims, mp.lattice_index_min, mp.grid.index_to_world}; }
DenseFrame lbh_frame(const ModelPlan& mp) { return {mp.lattice.dims, mp.lattice_index_min, mp.grid.index_to_world}; }
constexpr int kBackgroundParallelGrids = 4;
nlohmann::json merged(nlohmann::json a, const nlohmann::json& b) {
  a.update(b);
  return a;
}
double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

// Opens <model>.vdb and queues its density (and brown) grids; the solutions follow as they come.
void BakeOutput::start_model(const ModelPlan& mp, bool flux) {
  model_ = &mp;
  flux_grids_ = flux;
  done_.clear();
  encoded_.assign(solutions_expected(mp), LbhEncoded{});
  half_error_.assign(solutions_expected(mp), 0.0);
  output_seconds_ = 0;
  // A scene model's light is written on its occupied nodes and their 26 neighbours only (what a
  // renderer interpolates between), never the boundary layer's source values; the coarse forest
  // lattices keep their whole box, whose boundary is the open-air light relighting needs there.
  keep_.clear();
  medium_density_ = mp.lattice.medium_density();
  if (mp.role == PlanRole::Model && !plan_.scene->output.full_box) keep_ = near_medium(mp.lattice.dims, medium_density_, 1);
  if (!plan_.scene->output.vdb) return;
  const bool has_wood = mp.lattice.has_material(kMaterialWood);
  const nlohmann::json file_meta = {{"creator", std::string("lblight ") + kVersion},
                                    {"lblight_model", mp.spec->name},
                                    {"lblight_scene_hash", plan_.scene->hash}};
  // In the background, up to 4 grids compress at once (Blosc is serial per grid and would
  // otherwise fall behind a GPU); inline, the OpenMP solver needs the cores back after each grid.
  const int parallel_grids = worker_.background() ? kBackgroundParallelGrids : 1;
  const ModelExtras* extras = extras_for(mp);
  const std::size_t extra_grids = extras ? extras->grids.size() : 0;
  vdb_ = std::make_unique<VdbStreamWriter>(dir_.path(mp.spec->name + ".vdb"), dense_frame(mp),
                                           static_cast<int>(1 + has_wood + extra_grids +
                                                            solutions_expected(mp) * (grids_per_solution() + (flux ? 3 : 0))),
                                           extras ? merged(file_meta, extras->file_metadata) : file_meta,
                                           parallel_grids);
  worker_.post([this, &mp, has_wood] {
    const auto t0 = std::chrono::steady_clock::now();
    const nlohmann::json box = lattice_box_json(mp);
    vdb_->add({"density", &medium_density_, nullptr, true, merged(box, material_metadata(mp, has_wood))});
    if (has_wood) {
      std::vector<float> brown(mp.lattice.dims.count());
      for (std::size_t i = 0; i < brown.size(); ++i)
        brown[i] = mp.lattice.material[i] == kMaterialWood && mp.lattice.density[i] > 0.0f ? 1.0f : 0.0f;
      vdb_->add({"brown", &brown, nullptr, false, box});
    }
    output_seconds_ += since(t0);
  });
  if (extras)
    worker_.post([this, &mp, extras] {
      const auto t0 = std::chrono::steady_clock::now();
      for (const ModelExtras::Grid& e : extras->grids) {
        const bool scalar = !e.scalar.empty();
        vdb_->add({e.name, scalar ? &e.scalar : nullptr, scalar ? nullptr : &e.rgb, false,
                   merged(lattice_box_json(mp), e.metadata)});
      }
      output_seconds_ += since(t0);
    });
}

void BakeOutput::set_extras(const ModelPlan& mp, ModelExtras extras) {
  if (model_ == &mp) throw Error(ErrorCategory::Internal, "bake output: extras after the model's first solution");
  extras_model_ = &mp;
  extras_ = std::move(extras);
}

const ModelExtras* BakeOutput::extras_for(const ModelPlan& mp) const { return extras_model_ == &mp ? &extras_ : nullptr; }

void BakeOutput::add(const ModelPlan& mp, SolutionResult& result) {
  // Whether the model's solutions come with their flux (BakeOptions::moments on a backend with
  // state access) shows in its first one; the file announces its grids up front.
  if (model_ != &mp) start_model(mp, !result.flux[0][0].empty());
  if (done_.size() >= encoded_.size())
    throw Error(ErrorCategory::Internal, "bake output: more solutions than planned for model '" + mp.spec->name + "'");
  // The worker owns the totals from here; the manifest row keeps everything else.
  auto totals = std::make_shared<std::array<std::vector<float>, 3>>(std::move(result.totals));
  std::shared_ptr<std::array<std::vector<float>, 3>> std_error;
  if (grids_per_solution() == 2) {
    if (result.std_error[0].empty())
      throw Error(ErrorCategory::Internal, "bake output: a reference solution without its standard error");
    std_error = std::make_shared<std::array<std::vector<float>, 3>>(std::move(result.std_error));
  }
  // A solution without flux in a model with flux grids: a B00 solved from a source in a bake
  // without all 18 directional solutions (bake.h, BakeOptions::moments); its flux is written as 0,
  // the ambient light taken as isotropic, and its grids say so.
  std::shared_ptr<std::array<FluxField, 3>> flux;
  const bool flux_missing = flux_grids_ && result.flux[0][0].empty();
  if (flux_missing)
    for (FluxField& f : result.flux)
      for (auto& axis : f) axis.assign(mp.lattice.dims.count(), 0.0f);
  if (flux_grids_) flux = std::make_shared<std::array<FluxField, 3>>(std::move(result.flux));
  done_.push_back(result);
  const SolutionResult& r = done_.back();
  const std::size_t slot = done_.size() - 1;

  DenseGridOut g;
  g.name = r.plan.grid_name;
  g.metadata = lattice_box_json(mp);
  g.metadata["lblight_solution"] = r.plan.index;
  g.metadata["lblight_direction"] = r.plan.direction;
  g.metadata["lblight_iterations"] = r.iterations;
  g.metadata["lblight_error_estimate"] = r.error_estimate;
  g.metadata["lblight_converged"] = r.converged;
  g.metadata["lblight_units"] = light_units(mp, r.plan);
  g.metadata["lblight_active"] = keep_.empty() ? "the whole lattice box, boundary source values included"
                                               : "occupied nodes and their 26 neighbours (0 elsewhere)";
  LbhSolutionIn lbh_in{r.plan.grid_name, r.plan.index, r.plan.direction, nullptr};
  std::string raw_file, raw_flux_file;  // a unit's share of a model: its totals (and flux) as solved, for the merge
  if (unit_solutions_) {
    raw_file = mp.spec->name + "." + r.plan.grid_name + ".totals";
    raw_files_[r.plan.grid_name] = raw_file;
    if (flux && !flux_missing) {
      raw_flux_file = mp.spec->name + "." + r.plan.grid_name + ".flux";
      raw_flux_files_[r.plan.grid_name] = raw_flux_file;
    }
  }
  worker_.post([this, &mp, totals, std_error, flux, flux_missing, g = std::move(g), lbh_in, slot, raw_file, raw_flux_file]() mutable {
    const auto t0 = std::chrono::steady_clock::now();
    if (!raw_file.empty()) write_raw_totals(dir_.path(raw_file), *totals);
    if (!raw_flux_file.empty()) write_raw_flux(dir_.path(raw_flux_file), *flux);
    // The ground layer's own totals mix what arrives from above with the boundary below it; a
    // renderer interpolating down to the ground should see the light just above it instead.
    std::vector<std::array<std::vector<float>, 3>*> grids{totals.get(), std_error.get()};
    if (flux)
      for (FluxField& f : *flux) grids.push_back(&f);
    if (mp.ground.on)
      for (auto* grid : grids)
        if (grid)
          for (auto& c : *grid) copy_up_to_ground(mp.lattice.dims, c);
    if (!keep_.empty())
      for (auto* grid : grids)
        if (grid)
          for (auto& c : *grid)
            for (std::size_t i = 0; i < c.size(); ++i)
              if (!keep_[i]) c[i] = 0.0f;
    const LbhOutputSpec& lbh = plan_.scene->output.lbh;
    if (lbh.enabled) {
      lbh_in.rgb = totals.get();
      encoded_[slot] = encode_lbh_solution(lbh_frame(mp), lbh_in,
                                           {lbh.threshold, lbh.relative, lbh.coefficients});
    }
    if (vdb_) {
      g.rgb = totals.get();
      g.half = plan_.scene->output.half;
      if (g.half) half_error_[slot] = half_rounding_error(*totals);
      vdb_->add(g);
      if (std_error) {
        DenseGridOut se = g;
        se.name += "_se";
        se.rgb = std_error.get();
        vdb_->add(se);
      }
      if (flux)  // docs/output-format.md: <grid>_flux_r/_g/_b, (x, y, z) in lattice axes
        for (int c = 0; c < 3; ++c) {
          DenseGridOut j = g;
          j.name += std::string("_flux_") + "rgb"[c];
          j.rgb = &(*flux)[static_cast<std::size_t>(c)];
          j.metadata["lblight_units"] = std::string("flux vector sum_m f_m n_m of the ") + kChannelNames[c] +
                                        " channel along the index axes, in the light's units (a beam of light L "
                                        "has flux L times its direction of travel)";
          j.metadata["lblight_moment"] =
              flux_missing ? "flux not available for this solution: written as 0 (its light taken as isotropic)" : "flux";
          vdb_->add(j);
        }
    }
    output_seconds_ += since(t0);
  });
}

void BakeOutput::set_peak_bytes(const ModelPlan&, std::size_t bytes) { peak_bytes_ = std::max(peak_bytes_, bytes); }

void BakeOutput::finish_model(const ModelPlan& mp) {
  if (model_ != &mp) start_model(mp, false);  // a model without solutions still gets its density
  const auto t_wait = std::chrono::steady_clock::now();
  worker_.wait();
  const double waited = since(t_wait);
  const bool write_grids = plan_.scene->output.vdb;
  const std::string file_name = mp.spec->name + ".vdb";
  if (vdb_) {
    vdb_->close();
    const double mib = static_cast<double>(vdb_->bytes_written()) / 1048576.0;
    if (worker_.background())  // compression also ran on other threads: its sum is CPU time
      spdlog::info("{}: {} grids, {:.1f} MiB, written alongside the solve ({:.2f} s after it); output thread busy "
                   "{:.2f} s, compression {:.2f} s of CPU time (up to {} grids at once)",
                   file_name, vdb_->grids_written(), mib, waited, output_seconds_, vdb_->compress_seconds(),
                   kBackgroundParallelGrids);
    else
      spdlog::info("{}: {} grids, {:.1f} MiB, converted and written in {:.2f} s (compression {:.2f} s of it)",
                   file_name, vdb_->grids_written(), mib, output_seconds_, vdb_->compress_seconds());
    vdb_.reset();
  }
  const std::string nanovdb_name = mp.spec->name + ".nvdb";
  const bool nanovdb = write_grids && plan_.scene->output.nanovdb;
  if (nanovdb) {  // the finished .vdb converted whole (io/nanovdb_io.h)
    const auto t0 = std::chrono::steady_clock::now();
    const NanoVdbWritten n = write_nanovdb(dir_.path(file_name), dir_.path(nanovdb_name));
    spdlog::info("{}: {} grids, {:.1f} MiB, converted from {} in {:.2f} s", nanovdb_name, n.grids,
                 static_cast<double>(n.bytes) / 1048576.0, file_name, since(t0));
  }

  // Manifest rows and .lbh solutions in index order (a B00 summed from the others arrives last).
  std::vector<std::size_t> order(done_.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return done_[a].plan.index < done_[b].plan.index; });

  nlohmann::json model;
  model["name"] = mp.spec->name;
  model["role"] = mp.role == PlanRole::Model ? "model" : mp.role == PlanRole::ForestCoarse ? "forest" : "forest_alone";
  if (mp.role == PlanRole::ForestAlone) model["alone_model"] = mp.alone_model;
  model["file"] = write_grids ? nlohmann::json(file_name) : nlohmann::json(nullptr);
  if (nanovdb) model["nanovdb_file"] = nanovdb_name;
  model["source"] = mp.grid.description;
  model["lattice"] = lattice_json(mp);
  model["materials"] = {{"medium", material_json(mp.spec->material)}};
  if (mp.lattice.has_material(kMaterialWood)) model["materials"]["wood"] = material_json(mp.spec->wood_material);
  if (mp.ground.on)
    model["ground"] = {{"albedo", mp.ground.albedo},
                       {"layer_index_z", mp.lattice_index_min[2] + 1},
                       {"empty_layers_above", mp.ground.gap}};
  model["occupied_nodes"] = mp.stats.occupied;
  model["wood_nodes"] = mp.stats.wood;
  model["distinct_channels"] = mp.channels.size();
  model["savings"] = savings_json(mp);
  model["lb_model"] = plan_.scene->solver.model.name();
  if (plan_.scene->solver.model.calibrated) {  // which corrections the light was solved with (render reads delta_m)
    LbModel lb = plan_.scene->solver.model;
    nlohmann::json switches = nlohmann::json::object();
    for (int k = 0; k < static_cast<int>(kCalibrationNames.size()); ++k)
      switches[kCalibrationNames[static_cast<std::size_t>(k)]] = *calibration_switch(lb, k);
    model["lb_calibration"] = switches;
  }
  model["steps"] = {{"mode", to_string(mp.steps.mode)},
                    {"method", to_string(mp.steps.method)},
                    {"tolerance", mp.steps.tolerance},
                    {"check_interval", mp.steps.check_interval},
                    {"min_steps", mp.steps.min_steps},
                    {"max_steps", mp.steps.max_steps}};
  if (mp.steps.mode != IterationMode::Auto) model["steps"]["fixed_steps"] = mp.steps.fixed_steps;
  if (!mp.steps.method_note.empty()) model["steps"]["method_note"] = mp.steps.method_note;
  model["peak_memory_bytes"] = peak_bytes_;
  model["solutions"] = nlohmann::json::array();

  // Haar-compressed streams next to the .vdb when the scene asks for them (docs/model.md sec. 7).
  const LbhOutputSpec& lbh = plan_.scene->output.lbh;
  const std::string lbh_name = mp.spec->name + ".lbh";
  std::vector<LbhEncoded> encoded;
  if (lbh.enabled && !done_.empty()) {
    for (std::size_t i : order) encoded.push_back(std::move(encoded_[i]));
    write_lbh(dir_.path(lbh_name), lbh_frame(mp), encoded);
    model["lbh_file"] = lbh_name;
    double raw = 0, packed = 0, worst_rms = 0;
    std::size_t q8 = 0;
    for (const LbhEncoded& e : encoded) {
      q8 += e.encoding == lbh::Encoding::Q8;
      raw += static_cast<double>(e.stats.float_rgb_bytes);
      packed += static_cast<double>(e.stats.stream_bytes);
      worst_rms = std::max(worst_rms, e.stats.max_abs_value > 0 ? e.stats.rms_error / e.stats.max_abs_value : 0.0);
    }
    spdlog::info("{}: {} solution(s), {:.2f} MiB float RGB -> {:.2f} MiB ({:.2f}:1, {} coefficients), RMS error "
                 "<= {:.2f}% of a solution's max",
                 lbh_name, encoded.size(), raw / 1048576.0, packed / 1048576.0, raw / packed,
                 q8 == encoded.size() ? "8-bit" : q8 == 0 ? "f32" : "8-bit and f32", 100.0 * worst_rms);
  }

  for (std::size_t k = 0; k < order.size(); ++k) {
    const SolutionResult& r = done_[order[k]];
    nlohmann::json s;
    s["index"] = r.plan.index;
    s["direction"] = r.plan.direction;
    s["grid"] = r.plan.grid_name;
    s["file"] = model["file"];
    s["iterations"] = r.iterations;
    if (r.warm_start) s["warm_start"] = true;
    if (r.photons > 0) s["photons"] = r.photons;
    if (r.plan.derived) s["derived"] = "sum of B01..B18 (docs/model.md sec. 4); iterations: the largest of theirs";
    s["seconds"] = r.seconds;
    s["error_estimate"] = finite_or_null(r.error_estimate);
    s["error_estimate_max"] = finite_or_null(r.error_estimate_max);
    s["converged"] = r.converged;
    if (mp.steps.method == SolverMethod::BiCGStab)
      s["krylov"] = {{"iterations", r.krylov_iterations}, {"relative_residual", r.krylov_residual}};
    nlohmann::json hist = nlohmann::json::array();
    for (const CheckPoint& c : r.history)
      hist.push_back({c.step, c.seconds, finite_or_null(c.change_l2), finite_or_null(c.error_estimate),
                      finite_or_null(c.error_estimate_max)});
    s["residual_history"] = hist;
    if (!encoded.empty()) s["compression"] = lbh_stats_json(encoded[k], lbh_name);
    if (plan_.scene->output.half) s["half_error_max"] = half_error_[order[k]];
    model["solutions"].push_back(s);
  }
  if (const ModelExtras* extras = extras_for(mp)) model.update(extras->manifest);
  extras_model_ = nullptr;
  extras_ = {};
  model_ = nullptr;
  done_.clear();
  encoded_.clear();
  peak_bytes_ = 0;
  models_.push_back(model);
}

nlohmann::json forest_json(const ForestPlan& f) {
  nlohmann::json j;
  j["coarse"] = f.coarse;
  if (f.coarse) {
    j["cell_size"] = f.cell_size;
    j["cell_size_note"] = f.cell_size_note;
    j["coarse_file"] = std::string(kForestCoarseName) + ".vdb";
  }
  // The instance table: columns named once, one row per instance.
  j["instance_columns"] = {"model", "x", "y", "z", "yaw_degrees", "scale"};
  nlohmann::json rows = nlohmann::json::array();
  for (const ForestInstance& in : f.instances)
    rows.push_back({in.model, in.position[0], in.position[1], in.position[2], in.yaw_degrees, in.scale});
  j["instances"] = std::move(rows);
  return j;
}

nlohmann::json BakeOutput::commit(double total_seconds) {
  nlohmann::json m;
  m["lblight_version"] = kVersion;
  m["manifest_format"] = kManifestFormat;
  m["created"] = utc_timestamp();
  m["command"] = info_.command_line;
  m["scene"] = {{"file", plan_.scene->file.string()}, {"name", plan_.scene->name}, {"hash", plan_.scene->hash}};
  m["lighting"] = plan_.scene->lighting.mode == LightingMode::Base ? "base" : "static";
  m["backend"] = {{"name", info_.backend_name},
                  {"description", info_.backend_description},
                  {"precision", to_string(plan_.precision)}};
  if (!info_.reference.is_null()) m["reference"] = info_.reference;
  m["models"] = models_;
  m["units"] = "light: 1 = the open-air light of a unit sun (a directional base solution in empty space); B00 is 18 "
               "in open air";
  if (plan_.forest) m["forest"] = forest_json(*plan_.forest);
  if (plan_.scene->ground.enabled)
    m["ground"] = {{"height", plan_.scene->ground.height},
                   {"albedo", plan_.scene->ground.albedo},
                   {"units", "a ground of albedo A hides the light from below and sends back A x the light sent "
                             "down: a unit sun along a lattice direction from above is 1 + A in open air, one from "
                             "below 0, sky S is 9 S + 5 A S; each grid's lblight_units gives its open-air value "
                             "(docs/model.md sec. 4.3)"}};
  m["total_seconds"] = total_seconds;
  if (!info_.unit.is_null()) {
    m["unit"] = info_.unit;
    if (unit_solutions_) m["unit"]["totals"] = raw_files_;
    if (!raw_flux_files_.empty()) m["unit"]["flux"] = raw_flux_files_;
    m["unit"]["files"] = file_checksums(dir_.staging(), m);
  }
  write_file_atomically(dir_.path("manifest.json"), m.dump(2) + "\n");
  dir_.commit();
  return m;
}

}  // namespace lblight
