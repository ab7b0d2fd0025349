// lblight bench: lattice updates per second and the fraction of measured memory bandwidth.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <chrono>
#include <iostream>
#include <sstream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/backend/registry.h"
#include "lblight/core/error.h"
#include "lblight/lattice/sun.h"
#include "lblight/scene/procedural.h"
#include "lblight/solve/plan.h"

namespace lblight::cli {
namespace {

struct BenchArgs {
  std::string backend = "auto";
  int threads = 0;
  int device = 0;
  std::vector<int> sizes{128};
  int steps = 0;
  std::vector<std::string> precisions{"float32"};
  int systems = 1;
  double bandwidth_mib = 0;
  bool json = false;
};

int run_bench(const BenchArgs& a) {
  auto backend = make_backend({a.backend, a.threads, a.device});
  const std::size_t probe = a.bandwidth_mib > 0 ? static_cast<std::size_t>(a.bandwidth_mib * 1024 * 1024)
                                                 : (backend->name() == "cpu" ? (512u << 20) : (1024u << 20));
  spdlog::info("measuring copy bandwidth with {} buffers on {}", format_bytes(static_cast<double>(probe)),
               backend->description());
  const double bandwidth = backend->measure_copy_bandwidth(probe);

  nlohmann::json out;
  out["backend"] = {{"name", backend->name()}, {"description", backend->description()}};
  out["copy_bandwidth_gbs"] = bandwidth / 1e9;
  out["runs"] = nlohmann::json::array();
  Table table({"lattice", "precision", "systems", "steps", "seconds", "MLUPS/channel", "GB/s", "of copy bw"});
  for (const std::string& pname : a.precisions) {
    const Precision precision = parse_precision(pname);
    if (!backend->supports(precision)) {
      spdlog::warn("skipping {}: the {} backend does not store it", pname, backend->name());
      continue;
    }
    for (int size : a.sizes) {
      // A procedural cloud fills the lattice: realistic mix of dense, thin and empty rows.
      ProceduralSource src;
      src.shape = "cloud";
      src.resolution = size - 2;
      ModelGrid grid = make_procedural(src);
      LatticeGeometry lat = build_lattice(grid, 1);
      ChannelMaterials ch;
      ch.omega[0] = build_omega({0.008, 0.792, 0.9});
      SolverOptions so;
      so.precision = precision;
      so.max_systems = a.systems;
      auto solver = backend->create(lat, {ch}, so);
      std::vector<SystemSpec> batch(static_cast<std::size_t>(a.systems));
      for (int s = 0; s < a.systems; ++s) {
        const auto b = base_boundary(1 + s % 18);
        for (int i = 0; i < 19; ++i) batch[static_cast<std::size_t>(s)].boundary[i] = b[i];
      }
      solver->reset(batch);
      solver->step(2);  // warm up
      int steps = a.steps;
      if (steps <= 0) {  // about two seconds of work
        const auto t0 = std::chrono::steady_clock::now();
        solver->step(2);
        const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / 2;
        steps = std::max(4, std::min(2000, static_cast<int>(2.0 / std::max(dt, 1e-6))));
      }
      const auto t0 = std::chrono::steady_clock::now();
      solver->step(steps);
      std::vector<Residual> r;
      solver->measure(r);  // also synchronises asynchronous backends
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      const double updates = static_cast<double>(lat.dims.interior_count()) * steps * a.systems;
      const double lups = updates / seconds;
      const double bytes = lups * bytes_per_update(precision);
      const double fraction = bytes / bandwidth;
      const std::string dims = std::to_string(lat.dims.nx) + "x" + std::to_string(lat.dims.ny) + "x" +
                               std::to_string(lat.dims.nz);
      char mlups[32], gbs[32], frac[32];
      std::snprintf(mlups, sizeof mlups, "%.1f", lups / 1e6);
      std::snprintf(gbs, sizeof gbs, "%.1f", bytes / 1e9);
      std::snprintf(frac, sizeof frac, "%.2f", fraction);
      table.add({dims, pname, std::to_string(a.systems), std::to_string(steps), format_seconds(seconds), mlups, gbs, frac});
      out["runs"].push_back({{"lattice", {lat.dims.nx, lat.dims.ny, lat.dims.nz}},
                             {"precision", pname},
                             {"systems", a.systems},
                             {"steps", steps},
                             {"seconds", seconds},
                             {"updates_per_second_per_channel", lups},
                             {"bytes_per_update", bytes_per_update(precision)},
                             {"achieved_gbs", bytes / 1e9},
                             {"fraction_of_copy_bandwidth", fraction}});
    }
  }
  if (a.json) {
    std::cout << out.dump(2) << "\n";
  } else {
    std::cout << "backend: " << backend->description() << "\n";
    char bw[64];
    std::snprintf(bw, sizeof bw, "%.1f GB/s", bandwidth / 1e9);
    std::cout << "measured copy bandwidth (bytes read + written per second): " << bw << "\n";
    std::cout << table.str();
    std::cout << "one lattice update moves " << bytes_per_update(Precision::Float32)
              << " bytes in float32 (19 values in, 19 out, density and material)\n";
  }
  return 0;
}

}  // namespace

Command add_bench_command(CLI::App& app, const GlobalOptions&) {
  auto a = std::make_shared<BenchArgs>();
  CLI::App* cmd = app.add_subcommand(
      "bench", "Measure lattice updates per second per channel on a procedural cloud lattice and the fraction of "
               "the device's copy bandwidth (measured in the same run) that they represent.");
  cmd->add_option("--backend", a->backend, "auto, cpu or cuda")->check(CLI::IsMember({"auto", "cpu", "cuda"}))->capture_default_str();
  cmd->add_option("--threads", a->threads, "CPU threads (0 = all)")->check(CLI::Range(0, 4096));
  cmd->add_option("--device", a->device, "GPU ordinal")->check(CLI::Range(0, 64));
  cmd->add_option("--size", a->sizes, "Lattice edge length(s), e.g. --size 64 128 256")->check(CLI::Range(8, 2048))->capture_default_str();
  cmd->add_option("--steps", a->steps, "Timed steps (default: about two seconds' worth)")->check(CLI::Range(1, 1000000));
  cmd->add_option("--precision", a->precisions, "float32, float64, float16 (one or more)")
      ->check(CLI::IsMember({"float32", "float64", "float16"}))
      ->capture_default_str();
  cmd->add_option("--systems", a->systems, "Systems solved side by side (GPU batching)")->check(CLI::Range(1, 64))->capture_default_str();
  cmd->add_option("--bandwidth-mib", a->bandwidth_mib, "Buffer size of the bandwidth probe in MiB");
  cmd->add_flag("--json", a->json, "Print JSON");
  return {cmd, [a] { return run_bench(*a); }};
}

}  // namespace lblight::cli
