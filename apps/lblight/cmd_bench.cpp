// lblight bench: lattice updates per second and the fraction of measured memory bandwidth.
#include <CLI/CLI.hpp>

#include <chrono>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <sstream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "backends/registry.h"
#include "lblight/core/error.h"
#include "lblight/core/relative_gap.h"
#include "lblight/solve/throughput.h"
#include "lblight/fluid/gas_solver.h"

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
  std::string shape = "uniform";
  double bandwidth_mib = 0;
  bool json = false, gas = false;
  std::vector<int> time_blocks;  // empty: 1 and 0 (automatic) on the CPU, 0 elsewhere
  bool in_place = true;          // also one run with the state in place, where the backend offers it
  std::vector<std::string> collisions{"cubic"};  // Omega's form on the CPU (SolverOptions::symmetric_collision)
};

// The gas solver (CPU, OpenMP) on a periodic size^3 box with a warm blob: node updates per second
// after a 2-step warm-up, timed over about a second.
nlohmann::json bench_gas(int size, int threads) {
  fluid::GasSettings s;
  s.dims = {size, size, size};
  s.buoyancy = 1e-4;
  s.threads = threads;
  fluid::GasSolver g(s);
  g.step(2);
  int steps = 2;
  double seconds = 0;
  for (;;) {
    const auto t0 = std::chrono::steady_clock::now();
    g.step(steps);
    seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (seconds > 1.0 || steps > 1 << 20) break;
    steps *= 2;
  }
  const double ups = static_cast<double>(s.dims.count()) * steps / seconds;
  return {{"lattice", {size, size, size}}, {"steps", steps}, {"seconds", seconds}, {"updates_per_second", ups},
          {"bytes_per_update", fluid::kGasBytesPerUpdate}, {"achieved_gbs", ups * fluid::kGasBytesPerUpdate / 1e9}};
}

int run_bench(const BenchArgs& a) {
  auto backend = make_backend({a.backend, usable_threads(a.threads), a.device});
  if (!backend->occupies_host_cores() &&
      std::find(a.collisions.begin(), a.collisions.end(), "pairs") != a.collisions.end())
    throw_invalid("--collision pairs: only the cpu backend takes it (the " + backend->name() +
                  " backend picks each operator's form itself)");
  for (const std::string& pname : a.precisions)
    if (!backend->supports(parse_precision(pname)))
      throw_invalid("--precision " + pname + ": the " + backend->name() + " backend does not store it; allowed here: " +
                    supported_precisions(*backend));
  // Every size refused up front when its lattice and systems do not fit (not a bare "out of
  // memory" minutes in): the state of --systems systems, two levels, plus the lattice itself.
  const double memory = static_cast<double>(backend->available_bytes());
  for (const std::string& pname : a.precisions)
    for (int size : a.sizes) {
      const Dims d{size, size, size};
      const double need = static_cast<double>(backend->bytes_per_lattice(d)) +
                          a.systems * static_cast<double>(backend->bytes_per_system(d, parse_precision(pname)));
      if (memory > 0 && need > 0.9 * memory)
        throw Error(ErrorCategory::Unavailable,
                    "--size " + std::to_string(size) + " in " + pname + " with --systems " + std::to_string(a.systems) +
                        " needs " + format_bytes(need) + " on " + backend->name() + ", which has " +
                        format_bytes(memory) + " to spare; allowed: a smaller --size or fewer --systems",
                    {"--size", {}, {}});
    }
  const std::size_t probe = a.bandwidth_mib > 0 ? static_cast<std::size_t>(a.bandwidth_mib * 1024 * 1024)
                                                 : (backend->name() == "cpu" ? (512u << 20) : (1024u << 20));
  spdlog::info("measuring copy bandwidth with {} buffers on {}", format_bytes(static_cast<double>(probe)),
               backend->description());
  double bandwidth = backend->measure_copy_bandwidth(probe);

  nlohmann::json out;
  out["backend"] = {{"name", backend->name()}, {"description", backend->description()}};
  out["runs"] = nlohmann::json::array();
  RunContext ctx;
  ctx.cancel = &g_interrupted;  // a long --steps stops on Ctrl-C
  const std::size_t cache = backend->cache_bytes();
  std::vector<int> blocks = a.time_blocks;
  if (blocks.empty()) blocks = backend->occupies_host_cores() ? std::vector<int>{1, 0} : std::vector<int>{0};
  for (const std::string& pname : a.precisions) {
    const Precision precision = parse_precision(pname);
    for (int size : a.sizes) {
      const LatticeGeometry lat = bench_lattice(a.shape, size);
      // the two-level runs, then one in place (no temporal blocking) where offered
      std::vector<std::pair<int, StateLayout>> variants;
      for (int block : blocks) variants.push_back({block, StateLayout::TwoLevels});
      if (a.in_place && backend->bytes_per_system_in_place(lat.dims, precision) > 0) variants.push_back({1, StateLayout::InPlace});
      for (const auto& [block, layout] : variants)
        for (const std::string& collision : a.collisions) {
          const ThroughputRun run = measure_throughput(*backend, lat, precision, a.systems, a.steps, 0.3, 2.0, block,
                                                       layout, collision == "cubic", ctx);
          // What one update moves to and from memory: the whole update's bytes once per pass
          // over the state, i.e. divided by the steps one pass runs (temporal blocking), and
          // only for the nodes a step sweeps (streaming by position; an estimate from below:
          // it leaves out the boundary rewrite and the checks' reading of every node).
          const double nominal = bytes_per_update(precision),
                       moved = nominal * run.swept_fraction / run.steps_per_pass;
          out["runs"].push_back({{"lattice", {lat.dims.nx, lat.dims.ny, lat.dims.nz}},
                                 {"precision", pname},
                                 {"systems", a.systems},
                                 {"time_block", block},
                                 {"state", run.by_position ? std::string("by-position") : to_string(layout)},
                                 {"swept_fraction", run.swept_fraction},
                                 {"collision", collision},
                                 {"steps_per_pass", run.steps_per_pass},
                                 {"steps", run.steps},
                                 {"seconds", run.seconds},
                                 {"updates_per_second_per_channel", run.updates_per_second},
                                 {"bytes_per_update", nominal},
                                 {"memory_bytes_per_update", moved},
                                 {"achieved_gbs", run.updates_per_second * nominal / 1e9},
                                 {"memory_gbs", run.updates_per_second * moved / 1e9},
                                 {"state_bytes", run.state_bytes},
                                 {"state_within_cache", cache > 0 && run.state_bytes <= 2.0 * static_cast<double>(cache)}});
        }
    }
  }
  if (a.gas)
    for (int size : a.sizes) out["gas_runs"].push_back(bench_gas(size, usable_threads(a.threads)));
  // The probe runs before and after the lattice runs; the larger figure is the reference, so the
  // fraction is never flattered by a momentarily slow probe on a shared machine.
  const double after = backend->measure_copy_bandwidth(probe);
  if (after > bandwidth)
    spdlog::info("copy bandwidth was {:.1f} GB/s before and {:.1f} GB/s after the runs; using the larger",
                 bandwidth / 1e9, after / 1e9);
  bandwidth = std::max(bandwidth, after);
  out["copy_bandwidth_gbs"] = bandwidth / 1e9;
  out["cache_bytes"] = cache;
  Table table({"lattice", "precision", "state", "Omega", "systems", "steps/pass", "steps", "seconds", "MLUPS/channel", "B/update moved",
               "memory GB/s", "of copy bw", "effective"});
  bool any_cached = false, any_by_position = false;
  for (auto& run : out["runs"]) {
    // effective: the nominal bytes of every update over the copy bandwidth (above 1 once a pass
    // runs several steps); of copy bw: what actually crossed the memory bus
    const double effective = run["achieved_gbs"].get<double>() * 1e9 / bandwidth;
    const double fraction = run["memory_gbs"].get<double>() * 1e9 / bandwidth;
    run["fraction_of_copy_bandwidth"] = fraction;
    run["effective_fraction_of_copy_bandwidth"] = effective;
    const bool cached = run["state_within_cache"].get<bool>();
    any_cached = any_cached || cached;
    any_by_position = any_by_position || run["state"] == "by-position";
    char mlups[32], moved[32], gbs[32], frac[32], eff[32];
    std::snprintf(mlups, sizeof mlups, "%.1f", run["updates_per_second_per_channel"].get<double>() / 1e6);
    std::snprintf(moved, sizeof moved, "%.1f", run["memory_bytes_per_update"].get<double>());
    std::snprintf(gbs, sizeof gbs, "%.1f", run["memory_gbs"].get<double>());
    std::snprintf(frac, sizeof frac, "%.2f%s", fraction, cached ? " (c)" : "");
    std::snprintf(eff, sizeof eff, "%.2f", effective);
    const auto& l = run["lattice"];
    table.add({std::to_string(l[0].get<int>()) + "x" + std::to_string(l[1].get<int>()) + "x" +
                   std::to_string(l[2].get<int>()),
               run["precision"], run["state"], run["collision"], std::to_string(run["systems"].get<int>()),
               std::to_string(run["steps_per_pass"].get<int>()), std::to_string(run["steps"].get<int>()),
               format_seconds(run["seconds"].get<double>()), mlups, moved, gbs, frac, eff});
  }
  // Storage error: each other precision against float32 after the same 2N steps from the same
  // start (arithmetic is float32 or better everywhere; only what is stored differs).
  Table errors({"lattice", "precision", "steps", "rel. L2 vs float32", "rel. max vs float32"});
  bool any_error = false;
  if (backend->supports(Precision::Float32))
    for (int size : a.sizes) {
      std::vector<float> ref;
      for (const std::string& pname : a.precisions) {
        const Precision precision = parse_precision(pname);
        if (precision == Precision::Float32 || !backend->supports(precision)) continue;
        const int steps = 2 * size;
        if (ref.empty()) ref = bench_totals(*backend, bench_lattice(a.shape, size), Precision::Float32, steps);
        const std::vector<float> got = bench_totals(*backend, bench_lattice(a.shape, size), precision, steps);
        const RelativeGap gap = relative_gap(got, ref);
        const double l2 = gap.l2, mx = gap.max;
        char el2[32], emx[32];
        std::snprintf(el2, sizeof el2, "%.2e", l2);
        std::snprintf(emx, sizeof emx, "%.2e", mx);
        errors.add({std::to_string(size) + "^3", pname, std::to_string(steps), el2, emx});
        out["storage_error"].push_back({{"size", size}, {"precision", pname}, {"steps", steps},
                                        {"relative_l2_vs_float32", l2}, {"relative_max_vs_float32", mx}});
        any_error = true;
      }
    }
  std::string gas_text;
  if (a.gas) {
    Table gas({"gas lattice", "steps", "seconds", "M node updates/s", "GB/s", "of copy bw"});
    for (auto& run : out["gas_runs"]) {
      const double fraction = run["achieved_gbs"].get<double>() * 1e9 / bandwidth;
      run["fraction_of_copy_bandwidth"] = fraction;
      char ups[32], gbs[32], frac[32];
      std::snprintf(ups, sizeof ups, "%.1f", run["updates_per_second"].get<double>() / 1e6);
      std::snprintf(gbs, sizeof gbs, "%.1f", run["achieved_gbs"].get<double>());
      std::snprintf(frac, sizeof frac, "%.2f", fraction);
      gas.add({std::to_string(run["lattice"][0].get<int>()) + "^3", std::to_string(run["steps"].get<int>()),
               format_seconds(run["seconds"].get<double>()), ups, gbs, frac});
    }
    gas_text = "gas solver (CPU; flow + temperature + smoke per update, " + std::to_string(fluid::kGasBytesPerUpdate) +
               " bytes):\n" + gas.str();
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
              << " bytes in float32 (19 values in, 19 out, density and material) per pass over the state; a pass of "
                 "k steps (temporal blocking) moves 1/k of that per update; effective = the full bytes of every "
                 "update over the copy bandwidth\n";
    if (any_by_position)
      std::cout << "by-position: streaming by position (the lattice is sparse): a step collides in place only the "
                   "cache lines of nodes that hold medium, so an update moves that fraction of the bytes (counted from "
                   "below: without the boundary rewrite and the checks' reading of every node); MLUPS still count "
                   "every interior node\n";
    if (any_cached)
      std::cout << "(c): the state is at most twice the " << format_bytes(static_cast<double>(cache))
                << " cache, so that run is timed partly against the cache, not the memory\n";
    if (any_error) std::cout << "storage error after the same steps from the same start:\n" << errors.str();
    std::cout << gas_text;
  }
  return 0;
}

}  // namespace

Command add_bench_command(CLI::App& app, const GlobalOptions&) {
  auto a = std::make_shared<BenchArgs>();
  CLI::App* cmd = app.add_subcommand(
      "bench", "Measure lattice updates per second per channel on a procedural lattice (a uniform medium unless "
               "--shape) and the fraction of the device's copy bandwidth (measured in the same run) that they "
               "represent.");
  cmd->add_option("--backend", a->backend, "auto, cpu or cuda")->check(CLI::IsMember({"auto", "cpu", "cuda"}))->capture_default_str();
  cmd->add_option("--threads", a->threads, "CPU threads (0 = all)")->check(CLI::Range(0, 4096));
  cmd->add_option("--device", a->device, "GPU ordinal")->check(CLI::Range(0, 64));
  cmd->add_option("--size", a->sizes, "Lattice edge length(s), e.g. --size 64 128 256")->check(CLI::Range(8, 2048))->capture_default_str();
  cmd->add_option("--steps", a->steps, "Timed steps (default: about two seconds' worth)")->check(CLI::Range(1, 1000000));
  cmd->add_option("--precision", a->precisions, "float32, float64, float16 (one or more)")
      ->check(CLI::IsMember({"float32", "float64", "float16"}))
      ->capture_default_str();
  cmd->add_option("--shape", a->shape, "Lattice content: uniform (every node collides), cloud or plant")
      ->check(CLI::IsMember({"uniform", "cloud", "plant"}))
      ->capture_default_str();
  cmd->add_option("--systems", a->systems, "Systems solved side by side (GPU batching)")->check(CLI::Range(1, 64))->capture_default_str();
  cmd->add_option("--bandwidth-mib", a->bandwidth_mib,
                  "Buffer size of the bandwidth probe in MiB (default 512 on the CPU, 1024 on a GPU; well above the "
                  "largest cache)")
      ->check(finite_range(1.0, 65536.0));
  cmd->add_option("--time-block", a->time_blocks,
                  "CPU steps per pass over the lattice, one run each (1 = one step per pass, 0 = the backend's "
                  "automatic temporal blocking; default on the CPU: 1 and 0 side by side)")
      ->check(CLI::Range(0, 64));
  cmd->add_flag("!--no-in-place", a->in_place,
                "Skip the run with the state updated in place (one copy, AA pattern) added by default where the backend offers it");
  cmd->add_option("--collision", a->collisions,
                  "Form of the collision on the CPU, one run each: cubic (the symmetry-adapted form wherever the "
                  "operator allows it, as bakes run) or pairs (the even/odd form for every operator, the kernel "
                  "before it); e.g. --collision cubic pairs compares them side by side")
      ->check(CLI::IsMember({"cubic", "pairs"}))
      ->capture_default_str();
  cmd->add_flag("--json", a->json, "Print JSON");
  cmd->add_flag("--gas", a->gas, "Also time the gas solver (docs/fluid.md) at each --size on the CPU");
  return {cmd, [a] { return run_bench(*a); }};
}

}  // namespace lblight::cli
