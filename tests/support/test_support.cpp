#include "tests/support/test_support.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "backends/openmp/openmp_backend.h"
#include "lblight/pipeline/bake_output.h"
#include "lblight/lattice/d3q19.h"

namespace lblight::test {

using d3q19::kQ;

LatticeGeometry uniform_lattice(Dims d, float rho) {
  LatticeGeometry g;
  g.dims = d;
  g.density.assign(d.count(), 0.0f);
  g.material.assign(d.count(), 0);
  for (int z = 1; z < d.nz - 1; ++z)
    for (int y = 1; y < d.ny - 1; ++y)
      for (int x = 1; x < d.nx - 1; ++x) g.density[d.index(x, y, z)] = rho;
  return g;
}

LatticeGeometry random_lattice(Dims d, float max_rho, double wood_fraction, unsigned seed, float min_rho) {
  LatticeGeometry g = uniform_lattice(d, 0.0f);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  bool wood = false;
  for (int z = 1; z < d.nz - 1; ++z)
    for (int y = 1; y < d.ny - 1; ++y)
      for (int x = 1; x < d.nx - 1; ++x) {
        const std::size_t i = d.index(x, y, z);
        const float r = u(rng);
        g.density[i] = r < 0.2f ? 0.0f : min_rho + (max_rho - min_rho) * u(rng);
        if (u(rng) < wood_fraction && g.density[i] > 0) {
          g.material[i] = 1;
          wood = true;
        }
      }
  g.material_count = wood ? 2 : 1;
  return g;
}

ChannelMaterials channel(const OpticalParams& medium, bool absorbs, const OpticalParams& wood, bool wood_absorbs) {
  ChannelMaterials ch;
  ch.omega[0] = build_omega(medium);
  ch.absorbs[0] = absorbs;
  ch.omega[1] = build_omega(wood);
  ch.absorbs[1] = wood_absorbs;
  return ch;
}

std::vector<BrokenGeometry> broken_geometries() {
  const Dims d{6, 5, 7};
  const LatticeGeometry ok = random_lattice(d, 0.9f, 0.3, 4, 0.1f);
  std::vector<BrokenGeometry> out;
  const auto add = [&](const std::string& fault, const std::string& expect, auto&& edit) {
    out.push_back({fault, expect, ok});
    edit(out.back().g);
  };
  add("material byte 2 of 2 materials", "material 2 at node (2, 3, 4)",
      [&](LatticeGeometry& g) { g.material[d.index(2, 3, 4)] = 2; });
  add("wood byte with one material", "allowed below 1", [&](LatticeGeometry& g) {
    g.material_count = 1;
    for (auto& m : g.material) m = 0;
    g.material[d.index(1, 1, 1)] = 1;
  });
  add("short density array", "densities", [&](LatticeGeometry& g) { g.density.pop_back(); });
  add("short material array", "materials", [&](LatticeGeometry& g) { g.material.resize(3); });
  add("NaN density", "density nan", [&](LatticeGeometry& g) { g.density[d.index(3, 2, 2)] = std::nanf(""); });
  add("negative density", "density -", [&](LatticeGeometry& g) { g.density[d.index(3, 2, 2)] = -0.5f; });
  add("density on the boundary", "on the boundary", [&](LatticeGeometry& g) { g.density[d.index(0, 2, 2)] = 0.5f; });
  add("material_count 0", "material_count 0", [&](LatticeGeometry& g) { g.material_count = 0; });
  return out;
}

SystemSpec system_for(int channel, const std::array<double, 19>& boundary) {
  SystemSpec s;
  s.channel = channel;
  s.boundary = boundary;
  return s;
}

int lattice_direction(int x, int y, int z) {
  for (int m = 1; m < d3q19::kQ; ++m)
    if (d3q19::cx(m) == x && d3q19::cy(m) == y && d3q19::cz(m) == z) return m;
  throw std::logic_error("no D3Q19 direction (" + std::to_string(x) + ", " + std::to_string(y) + ", " +
                         std::to_string(z) + ")");
}

std::unique_ptr<Backend> cpu_backend(int threads) { return make_openmp_backend(threads); }

BakedModel bake_first_model(const Scene& scene, const std::filesystem::path& out_dir, bool write_in_background) {
  // Copies each result before the output takes its totals.
  class Keep final : public BakeObserver {
   public:
    Keep(BakeOutput& out, std::vector<SolutionResult>& kept) : out_(out), kept_(kept) {}
    void solution_done(const ModelPlan& mp, SolutionResult& r) override {
      kept_.push_back(r);
      out_.add(mp, r);
    }

   private:
    BakeOutput& out_;
    std::vector<SolutionResult>& kept_;
  };
  BakedModel b{make_plan(scene), {}};
  const ModelPlan& mp = b.model();
  auto backend = make_openmp_backend(0);
  BakeOutput out(b.plan, out_dir, {"test", "cpu", backend->description()}, write_in_background);
  Keep keep(out, b.kept);
  bake_model(mp, *backend, {}, keep);
  out.finish_model(mp);
  out.commit(1.0);
  return b;
}

StateAccess& state_of(LatticeSolver& solver) {
  if (StateAccess* s = solver.state_access()) return *s;
  throw std::logic_error("this solver offers no state access");
}

KrylovVectors& krylov_of(LatticeSolver& solver) {
  if (KrylovVectors* v = solver.krylov_vectors()) return *v;
  throw std::logic_error("this solver offers no Krylov vectors");
}

std::vector<float> solve_totals(const Backend& backend, const LatticeGeometry& g, const std::vector<ChannelMaterials>& ch,
                                const SystemSpec& sys, int steps, Precision p) {
  return solve_batch_totals(backend, g, ch, {sys}, steps, p).at(0);
}

std::vector<std::vector<float>> solve_batch_totals(const Backend& b, const LatticeGeometry& g,
                                                   const std::vector<ChannelMaterials>& ch,
                                                   const std::vector<SystemSpec>& batch, int steps, Precision p) {
  auto solver = b.create(g, ch, {p, static_cast<int>(batch.size())});
  solver->reset(batch);
  solver->step(steps);
  std::vector<Residual> r;
  solver->measure(r);
  std::vector<std::vector<float>> out;
  for (std::size_t s = 0; s < batch.size(); ++s) {
    out.emplace_back(g.dims.count());
    solver->read_totals(static_cast<int>(s), out.back().data());
  }
  return out;
}

const std::vector<ChannelMaterials>& leaf_channels() {
  static const std::vector<ChannelMaterials> ch = {channel({0.109, 0.891, -0.12}, true, {0.109, 0.891, -1.0}, false),
                                                   channel({0.091, 0.909, 0.09}, true, {0.091, 0.909, -1.0}, false),
                                                   channel({0.118, 0.882, -0.33}, true, {0.118, 0.882, -1.0}, false)};
  return ch;
}

std::vector<double> solve_totals_f64(const Backend& backend, const LatticeGeometry& g,
                                     const std::vector<ChannelMaterials>& ch, const SystemSpec& sys, int steps) {
  SolverOptions so;
  so.precision = Precision::Float64;
  so.max_systems = 1;
  auto solver = backend.create(g, ch, so);
  solver->reset({sys});
  solver->step(steps);
  std::vector<double> f;
  state_of(*solver).read_state(0, f);
  const std::size_t n = g.dims.count();
  std::vector<double> t(n, 0.0);
  for (int m = 0; m < kQ; ++m)
    for (std::size_t i = 0; i < n; ++i) t[i] += f[m * n + i];
  return t;
}

TempDir::TempDir() {
  std::string tmpl = (std::filesystem::temp_directory_path() / "lblight-test-XXXXXX").string();
  if (!mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
  path_ = tmpl;
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

// The lblight under test: $LBLIGHT_EXE when set (a relocated build, such as the bundle
// scripts/device-bundle.sh makes for GPU machines without the Debian packages), else the one built
// alongside these tests.
std::string lblight_exe() {
  const char* env = std::getenv("LBLIGHT_EXE");
  return env && *env ? std::string(env) : std::string(LBLIGHT_EXE);
}

CliResult run_cli(const std::string& args, const std::filesystem::path& cwd) {
  TempDir io;
  const std::string cmd = (cwd.empty() ? "" : "cd '" + cwd.string() + "' && ") + std::string("'") + lblight_exe() +
                          "' " + args + " >'" + (io / "out").string() + "' 2>'" + (io / "err").string() + "'";
  const int status = std::system(cmd.c_str());
  CliResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = read_text(io / "out");
  r.err = read_text(io / "err");
  return r;
}

void write_text(const std::filesystem::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
}

std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

DenseFrame cube_frame(int n, double voxel) {
  return {{n, n, n}, {0, 0, 0}, {voxel, 0, 0, 0, 0, voxel, 0, 0, 0, 0, voxel, 0, 0, 0, 0, 1}};
}

void write_density_vdb(const std::filesystem::path& file, const DenseFrame& frame, const std::vector<float>& density) {
  write_vdb(file, frame, {{"density", &density, nullptr, true, {}}}, nlohmann::json::object());
}

}  // namespace lblight::test
