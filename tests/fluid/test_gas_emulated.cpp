// The gas solver's per-node update (lblight/fluid/gas_node.h) run as a GPU would run it: four
// launches per step (collide, then stream the flow, the temperature and the smoke), one thread per
// node in blocks of 128 that run in reverse order, over plain arrays in the place of device memory.
// It must give GasSolver's fields bit for bit: the node functions depend on nothing but their node
// and the previous launch, whatever the order of threads.
#include <catch2/catch.hpp>

#include <array>
#include <type_traits>
#include <vector>

#include "lblight/fluid/gas_node.h"
#include "lblight/fluid/gas_solver.h"

using namespace lblight;
using namespace lblight::fluid;

namespace {

constexpr std::size_t kBlock = 128;

// Device memory of the emulated GPU, started as GasSolver starts (at rest, temperature ambient,
// no smoke; solid nodes 0).
struct EmulatedGas {
  GasSettings s;
  std::size_t n;
  std::vector<float> f, f_post, t, t_post, c, c_post;
  std::vector<double> rho, ux, uy, uz, temperature, smoke;

  explicit EmulatedGas(const GasSettings& settings)
      : s(settings), n(settings.dims.count()), f(d3q19::kQ * n, 0.0f), f_post(f), t(kQ7 * n, 0.0f), t_post(t),
        c(kQ7 * n, 0.0f), c_post(c), rho(n, 1.0), ux(n, 0.0), uy(n, 0.0), uz(n, 0.0), temperature(n, s.t_ambient),
        smoke(n, 0.0) {
    if (s.solid.empty()) s.solid.assign(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
      if (s.solid[i]) continue;
      for (int m = 0; m < d3q19::kQ; ++m) f[m * n + i] = static_cast<float>(equilibrium<double>(m, 1.0, 0.0, 0.0, 0.0));
      for (int k = 0; k < kQ7; ++k) t[k * n + i] = static_cast<float>(scalar_equilibrium(k, s.t_ambient, 0.0, 0.0, 0.0));
    }
  }

  GasView view() {
    GasView v = settings_view(s);
    v.f = f.data(), v.t = t.data(), v.c = c.data();
    v.f_post = f_post.data(), v.t_post = t_post.data(), v.c_post = c_post.data();
    v.rho = rho.data(), v.ux = ux.data(), v.uy = uy.data(), v.uz = uz.data();
    v.temperature = temperature.data(), v.smoke = smoke.data();
    return v;
  }

  // One launch over every node: blocks of kBlock threads, the last block first.
  template <typename Thread>
  void launch(Thread&& thread) const {
    const std::size_t blocks = (n + kBlock - 1) / kBlock;
    for (std::size_t b = blocks; b-- > 0;)
      for (std::size_t tx = 0; tx < kBlock; ++tx)
        if (b * kBlock + tx < n) thread(b * kBlock + tx);
  }

  void step() {
    const GasView v = view();
    const std::size_t nx = static_cast<std::size_t>(s.dims.nx), ny = static_cast<std::size_t>(s.dims.ny);
    // A stream launch: thread i streams node i of one lattice.
    auto stream = [&](auto q, GasLattice lattice, const float* post, float* next) {
      launch([&](std::size_t i) {
        stream_node<decltype(q)::value>(v, lattice, post, next, static_cast<int>(i % nx), static_cast<int>(i / nx % ny),
                                        static_cast<int>(i / (nx * ny)));
      });
    };
    launch([&](std::size_t i) { collide_node(v, i); });
    stream(std::integral_constant<int, d3q19::kQ>{}, kFlowLattice, v.f_post, f.data());
    stream(std::integral_constant<int, kQ7>{}, kTemperatureLattice, v.t_post, t.data());
    stream(std::integral_constant<int, kQ7>{}, kSmokeLattice, v.c_post, c.data());
  }

  // What GasSolver's accessors compute, from these arrays.
  std::vector<double> sums(const std::vector<float>& g, int q) const {
    std::vector<double> out(n, 0.0);
    for (std::size_t i = 0; i < n; ++i)
      if (!s.solid[i]) out[i] = q == d3q19::kQ ? scalar_sum<d3q19::kQ>(g.data(), n, i) : scalar_sum<kQ7>(g.data(), n, i);
    return out;
  }
};

// A box with every kind of boundary: a wall at -x, an outlet at +x, periodic in y, the floor a
// wall with a round inlet, an open top; warm smoky gas rising, a sideways body force.
GasSettings every_boundary(bool obstacle) {
  GasSettings s;
  s.dims = {12, 10, 14};
  s.tau = 0.6;
  s.tau_temperature = 0.55;
  s.tau_smoke = 0.52;
  s.force = {1e-5, 0, 0};
  s.buoyancy = 1e-3;
  s.t_ambient = 28;
  s.faces = {FaceType::Wall, FaceType::Open, FaceType::Periodic, FaceType::Periodic, FaceType::Wall, FaceType::Open};
  s.inlet.enabled = true;
  s.inlet.x0 = 3, s.inlet.x1 = 7, s.inlet.y0 = 2, s.inlet.y1 = 6;
  s.inlet.mask.assign(static_cast<std::size_t>(s.dims.nx) * s.dims.ny, 0);
  for (int y = 2; y <= 6; ++y)
    for (int x = 3; x <= 7; ++x)
      if ((x - 5) * (x - 5) + (y - 4) * (y - 4) <= 4) s.inlet.mask[static_cast<std::size_t>(y) * s.dims.nx + x] = 1;
  s.inlet.speed = 0.05;
  s.inlet.temperature = 40;
  s.inlet.smoke = 1;
  if (obstacle) {
    s.solid.assign(s.dims.count(), 0);
    for (int z = 7; z < 10; ++z)
      for (int y = 3; y < 6; ++y)
        for (int x = 4; x < 7; ++x) s.solid[s.dims.index(x, y, z)] = 1;
  }
  s.threads = 2;
  return s;
}

}  // namespace

TEST_CASE("Gas node functions launched as on a GPU give the solver's fields bit for bit", "[fluid][emulated]") {
  for (bool obstacle : {true, false}) {
    INFO((obstacle ? "with" : "without") << " an obstacle");
    const GasSettings settings = every_boundary(obstacle);
    GasSolver solver(settings);
    EmulatedGas gpu(settings);
    for (int step = 0; step < 60; ++step) {
      solver.step();
      gpu.step();
    }
    const auto u = solver.velocity();
    CHECK(u[0] == gpu.ux);
    CHECK(u[1] == gpu.uy);
    CHECK(u[2] == gpu.uz);
    CHECK(solver.density() == gpu.sums(gpu.f, d3q19::kQ));
    CHECK(solver.temperature() == gpu.sums(gpu.t, kQ7));
    const std::vector<double> smoke = gpu.sums(gpu.c, kQ7);
    CHECK(solver.smoke() == smoke);
    // The run did something: smoke came in and warm gas rose.
    double total = 0;
    for (double v : smoke) total += v;
    CHECK(total > 1.0);
    CHECK(u[2][settings.dims.index(5, 4, 3)] > 0.0);
  }
}
