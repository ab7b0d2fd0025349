// gpu_pipeline_sim: the host side of a GPU bake, timed on a machine without a GPU.
//
// Runs what `lblight bake --backend cuda` runs (plan and voxelisation with the device starting
// alongside, the CUDA backend's batching, BakeOutput writing each solution on its background
// thread while the next one solves, manifest, staged directory), against a simulated device:
// its kernels take the time that `--bandwidth` x `--fraction` gives for the bytes they move and
// run asynchronously as launches do (the host blocks only in measure and read_totals), and its
// totals come from a reference bake of the same scene, so the output compresses as the real one
// does. It answers whether the host keeps up with a GPU running at a given fraction of its copy
// bandwidth, and what wall time that predicts (docs/performance.md).
//
//   gpu_pipeline_sim configs/plant-128.json --reference out/plant-128/tree.vdb -o /tmp/sim
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <future>
#include <map>
#include <thread>

#include "backends/cuda/lb_device.h"
#include "lblight/core/error.h"
#include "lblight/io/output_dir.h"
#include "lblight/pipeline/run_bake.h"
#include "lblight/io/vdb_io.h"
#include "lblight/lattice/sun.h"

using namespace lblight;
using Clock = std::chrono::steady_clock;

namespace {

double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct DeviceModel {
  double startup_s = 0.5;        // driver and context creation
  double bandwidth = 3.0e12;     // measured device copy bandwidth, bytes/s (read + write)
  double fraction = 0.8;         // of it, reached by the step kernel
  double host_link = 10.0e9;     // device to pageable host memory, bytes/s
};

// Reference totals per base solution (B00..B18), densely over the lattice.
class Reference {
 public:
  void load(const std::string& file, const Dims& dims) {
    for (int i = 0; i < 19; ++i) {
      DenseGridIn g = read_vdb_grid_dense(file, base_grid_name(i));
      const Dims& f = g.frame.dims;
      if (f.nx != dims.nx || f.ny != dims.ny || f.nz != dims.nz)
        throw Error(ErrorCategory::InvalidInput, file + ": grid " + base_grid_name(i) +
                                                     " is not over this scene's lattice (a reference must come "
                                                     "from a bake of the same scene)");
      grids_[i] = std::move(g.values);
    }
  }
  bool empty() const { return grids_.empty(); }
  // The solution a system's boundary values belong to; -1 for anything but a base solution.
  static int solution_of(const SystemSpec& s) {
    for (int i = 0; i < 19; ++i)
      if (s.boundary == base_boundary(i)) return i;
    return -1;
  }
  // Totals of `solution` in `channel`, or a smooth, noisy stand-in when there is no reference.
  void fill(int solution, int channel, const Dims& d, float* out) const {
    const auto it = grids_.find(solution);
    if (it != grids_.end()) {
      const std::vector<float>& v = it->second[static_cast<std::size_t>(channel)];
      std::copy(v.begin(), v.end(), out);
      return;
    }
    std::uint32_t h = 2463534242u + static_cast<std::uint32_t>(solution * 3 + channel);
    for (int z = 0; z < d.nz; ++z)
      for (int y = 0; y < d.ny; ++y)
        for (int x = 0; x < d.nx; ++x) {
          h ^= h << 13, h ^= h >> 17, h ^= h << 5;
          const double smooth = std::exp(-0.01 * (x + 2 * y + 3 * z)) + 0.05;
          out[d.index(x, y, z)] = static_cast<float>(smooth * (1.0 + 1e-3 * (h * 2.3283064e-10 - 0.5)));
        }
  }

 private:
  std::map<int, std::array<std::vector<float>, 3>> grids_;
};

// A lattice on the simulated device: work is queued on a device clock; the host waits only
// where the CUDA backend synchronises (measure, read_totals).
class SimSolver final : public LatticeSolver {
 public:
  SimSolver(const LatticeGeometry& g, const DeviceModel& m, const Reference& ref, Precision p, int capacity,
            double& kernel_seconds)
      : d_(g.dims), m_(m), ref_(ref), p_(p), capacity_(capacity), kernel_seconds_(kernel_seconds) {}

  int capacity() const override { return capacity_; }
  void reset(const std::vector<SystemSpec>& batch) override {
    batch_ = batch;
    queue(static_cast<double>(batch.size()) * 2 * 19 * value_bytes() * interior() / m_.bandwidth);  // memset
  }
  void step(int steps) override {
    queue(steps * static_cast<double>(batch_.size()) * interior() * bytes_per_update(p_) / (m_.fraction * m_.bandwidth));
  }
  void measure(std::vector<Residual>& out) override {
    // reads 19 values, reads and writes the total, per node and system
    queue(static_cast<double>(batch_.size()) * interior() * (19 * value_bytes() + 8 + 5) / (m_.fraction * m_.bandwidth));
    wait();
    out.assign(batch_.size(), Residual{});
    for (Residual& r : out) r.total_sq = r.total_max = 1.0;
  }
  void read_totals(int system, float* out) const override {
    wait();
    std::this_thread::sleep_for(std::chrono::duration<double>(static_cast<double>(d_.count()) * 4 / m_.host_link));
    const SystemSpec& s = batch_.at(static_cast<std::size_t>(system));
    ref_.fill(Reference::solution_of(s), s.channel, d_, out);
  }
  std::size_t bytes_in_use() const override { return 0; }

 private:
  double value_bytes() const { return p_ == Precision::Float16 ? 2.0 : 4.0; }
  double interior() const { return static_cast<double>(d_.interior_count()); }
  void queue(double seconds) {
    const auto now = Clock::now();
    if (busy_until_ < now) busy_until_ = now;
    busy_until_ += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
    kernel_seconds_ += seconds;
  }
  void wait() const { std::this_thread::sleep_until(busy_until_); }

  Dims d_;
  const DeviceModel& m_;
  const Reference& ref_;
  Precision p_;
  int capacity_;
  double& kernel_seconds_;
  std::vector<SystemSpec> batch_;
  Clock::time_point busy_until_ = Clock::now();
};

class SimBackend final : public Backend {
 public:
  SimBackend(const DeviceModel& m, const Reference& ref) : m_(m), ref_(ref) {
    std::this_thread::sleep_for(std::chrono::duration<double>(m.startup_s));
  }
  std::string name() const override { return "simulated-gpu"; }
  std::string description() const override {
    char buf[160];
    std::snprintf(buf, sizeof buf, "simulated GPU: %.0f GB/s copy, kernels at %.0f%% of it, %.2f s start-up",
                  m_.bandwidth / 1e9, 100 * m_.fraction, m_.startup_s);
    return buf;
  }
  bool supports(Precision p) const override { return p != Precision::Float64; }
  bool occupies_host_cores() const override { return false; }
  std::size_t bytes_per_system(const Dims& d, Precision p) const override {
    return 2 * 19 * d.count() * (p == Precision::Float16 ? 2 : 4) + d.count() * sizeof(float);
  }
  std::size_t bytes_per_lattice(const Dims& d) const override { return d.count() * 5; }
  std::size_t available_bytes() const override { return std::size_t{78} << 30; }
  int preferred_batch(const Dims& d, Precision, int total) const override { return gpu::systems_to_fill(d, total); }
  std::unique_ptr<LatticeSolver> create(const LatticeGeometry& g, const std::vector<ChannelMaterials>&,
                                        const SolverOptions& o) const override {
    return std::make_unique<SimSolver>(g, m_, ref_, o.precision, o.max_systems, kernel_seconds);
  }
  double measure_copy_bandwidth(std::size_t) const override { return m_.bandwidth; }

  mutable double kernel_seconds = 0;  // device time queued, all lattices

 private:
  const DeviceModel& m_;
  const Reference& ref_;
};

// Remembers when the last solution arrived (run_bake writes it).
class LastSolution final : public BakeObserver {
 public:
  void solution_done(const ModelPlan&, SolutionResult&) override { last_ = Clock::now(); }
  Clock::time_point last() const { return last_; }

 private:
  Clock::time_point last_ = Clock::now();
};

int run(const std::string& scene_file, const std::string& reference, const std::string& output, DeviceModel m,
        Precision precision) {
  const auto t0 = Clock::now();
  const Scene scene = load_scene(scene_file);
  StagedDirectory::check_target(output, OutputKind::Bake);
  Reference ref;
  auto starting = std::async(std::launch::async, [&] { return std::make_unique<SimBackend>(m, ref); });
  PlanOverrides ov;
  ov.precision = precision;
  const BakePlan plan = make_plan(scene, ov);
  auto backend = starting.get();
  const double ready = since(t0);
  for (const ModelPlan& mp : plan.models)
    if (mp.steps.mode == IterationMode::Auto)
      throw Error(ErrorCategory::InvalidInput, "model '" + mp.spec->name +
                                                   "': the simulated device has no convergence to measure; use a "
                                                   "scene with \"iterations\": \"paper\" or a fixed count");
  if (!reference.empty()) {
    if (plan.models.size() != 1) throw Error(ErrorCategory::InvalidInput, "--reference needs a one-model scene");
    const auto r0 = Clock::now();
    ref.load(reference, plan.models[0].lattice.dims);
    spdlog::info("reference totals loaded in {:.2f} s (not counted)", since(r0));
  }
  const auto t1 = Clock::now();
  const double not_counted = std::chrono::duration<double>(t1 - t0).count() - ready;

  LastSolution last;
  run_bake(plan, *backend, output, "gpu_pipeline_sim", last, {}, ready);
  const double solved = std::chrono::duration<double>(last.last() - t1).count();
  const double wall = ready + since(t1);
  std::printf("start-up and plan (overlapped)   %7.3f s\n", ready);
  std::printf("device time queued              %7.3f s (%s)\n", backend->kernel_seconds,
              backend->description().c_str());
  std::printf("solve, last solution at         %7.3f s after start\n", ready + solved);
  std::printf("output tail after the solve     %7.3f s\n", wall - ready - solved);
  std::printf("wall, as a bake would report it %7.3f s (reference loading, %.2f s, left out)\n", wall, not_counted);
  std::printf("host overhead over plan + device time: %.3f s\n", wall - ready - backend->kernel_seconds);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Times the host side of a GPU bake against a simulated device (see the source's header)"};
  std::string scene, reference, output = "gpu-pipeline-sim";
  std::string precision = "float32";
  DeviceModel m;
  double bandwidth_gbs = m.bandwidth / 1e9, link_gbs = m.host_link / 1e9;
  app.add_option("scene", scene, "Scene file (iterations \"paper\" or fixed)")->required();
  app.add_option("--reference", reference,
                 "A .vdb from a bake of the same one-model scene: its B00..B18 grids are the simulated totals "
                 "(default: a smooth, noisy stand-in)");
  app.add_option("-o,--output", output, "Output directory");
  app.add_option("--bandwidth", bandwidth_gbs, "Device copy bandwidth, GB/s")->check(CLI::PositiveNumber);
  app.add_option("--fraction", m.fraction, "Fraction of it the step kernel reaches")->check(CLI::Range(0.01, 2.0));
  app.add_option("--startup", m.startup_s, "Device start-up, seconds")->check(CLI::Range(0.0, 60.0));
  app.add_option("--host-link", link_gbs, "Device to host copy rate, GB/s")->check(CLI::PositiveNumber);
  app.add_option("--precision", precision, "Storage: float32 or float16")
      ->check(CLI::IsMember({"float32", "float16"}));
  CLI11_PARSE(app, argc, argv);
  m.bandwidth = bandwidth_gbs * 1e9;
  m.host_link = link_gbs * 1e9;
  try {
    return run(scene, reference, output, m, precision == "float16" ? Precision::Float16 : Precision::Float32);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}
