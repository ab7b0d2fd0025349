// The conformance cases of lblight_tests: the OpenMP backend on 1 and 2 threads, and with its
// state updated in place (StateLayout::InPlace), and the CUDA backend's kernels emulated on the
// CPU, with the default launch (on small lattices a batch's systems split into groups of threads)
// and with every system of a batch on each thread.
#include "tests/backend/conformance.h"
#include "tests/backend/emulated_gpu.h"
#include "tests/support/test_support.h"

namespace lblight::test {

namespace {

// The OpenMP backend creating every solver with one level of state, updated in place.
class InPlaceCpu final : public Backend {
 public:
  InPlaceCpu() : cpu_(cpu_backend(2)) {}
  std::string name() const override { return cpu_->name(); }
  std::string description() const override { return cpu_->description() + ", in place"; }
  bool supports(Precision p) const override { return cpu_->supports(p); }
  bool occupies_host_cores() const override { return true; }
  std::size_t bytes_per_system(const Dims& d, Precision p) const override { return cpu_->bytes_per_system_in_place(d, p); }
  std::size_t bytes_per_lattice(const Dims& d) const override { return cpu_->bytes_per_lattice(d); }
  std::size_t available_bytes() const override { return cpu_->available_bytes(); }
  int preferred_batch(const Dims& d, Precision p, int total) const override { return cpu_->preferred_batch(d, p, total); }
  std::unique_ptr<LatticeSolver> create(const LatticeGeometry& g, const std::vector<ChannelMaterials>& channels,
                                        const SolverOptions& options) const override {
    SolverOptions o = options;
    o.layout = StateLayout::InPlace;
    return cpu_->create(g, channels, o);
  }
  double measure_copy_bandwidth(std::size_t bytes) const override { return cpu_->measure_copy_bandwidth(bytes); }

 private:
  std::unique_ptr<Backend> cpu_;
};

}  // namespace

std::vector<BoundBackend> conformance_backends() {
  return {{"cpu, 1 thread", cpu_backend(1)},
          {"cpu, 2 threads", cpu_backend(2)},
          {"cpu, in place", std::make_shared<InPlaceCpu>()},
          {"emulated-gpu", make_emulated_gpu_backend()},
          {"emulated-gpu, all of a batch's systems on each thread", make_emulated_gpu_backend(1)}};
}

}  // namespace lblight::test
