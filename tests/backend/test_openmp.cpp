// What only the OpenMP backend has: a thread count and a choice of store instructions, neither of
// which may change a result, and float16 storage that rounds as the GPU's does. The backend
// contract itself is tests/backend/conformance.cpp.
#include <catch2/catch.hpp>

#include "lblight/lattice/lb_model.h"
#include "lblight/lattice/sun.h"
#include "tests/support/reference_lattice.h"
#include "tests/backend/emulated_gpu.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {
std::array<double, 19> base(int j) { return base_boundary(j); }
}  // namespace

TEST_CASE("Results do not depend on the thread count", "[transport]") {
  const LatticeGeometry g = random_lattice({23, 17, 19}, 0.9f, 0.2, 3);
  const auto ch = channel({0.1, 0.8, 0.6}, true);
  const auto one = solve_totals(*cpu_backend(1), g, {ch}, system_for(0, base(9)), 25);
  const auto two = solve_totals(*cpu_backend(2), g, {ch}, system_for(0, base(9)), 25);
  CHECK(one == two);
}

TEST_CASE("Streaming and regular stores give identical results (uniform, empty and mixed rows)", "[transport]") {
  // rows of 37 nodes: two full cache-line chunks plus a shifted tail chunk
  const LatticeGeometry g = random_lattice({37, 21, 17}, 0.9f, 0.2, 13);
  REQUIRE(g.material_count == 2);
  const auto ch = channel({0.109, 0.891, -0.12}, true, {0.109, 0.891, -1.0}, false);
  const auto backend = cpu_backend();
  for (Precision p : {Precision::Float32, Precision::Float64}) {
    std::vector<std::vector<float>> out;
    for (StoreMode mode : {StoreMode::Regular, StoreMode::Streaming}) {
      auto solver = backend->create(g, {ch}, {p, 1, mode});
      solver->reset({system_for(0, base(7))});
      solver->step(31);
      std::vector<Residual> r;
      solver->measure(r);
      out.emplace_back(g.dims.count());
      solver->read_totals(0, out.back().data());
    }
    CHECK(out[0] == out[1]);
  }
}

TEST_CASE("Temporal blocking gives the same bits as stepping one step at a time", "[transport][time_block]") {
  // mixed, uniform and empty rows; z extents shorter and longer than a deep wavefront; step
  // counts that leave odd remainders, measures in between, two systems of two channels
  const auto backend = cpu_backend(2);
  std::vector<Precision> precisions = {Precision::Float32, Precision::Float64};
  if (backend->supports(Precision::Float16)) precisions.push_back(Precision::Float16);
  for (Dims d : {Dims{37, 21, 17}, Dims{20, 9, 6}}) {
    const LatticeGeometry g = random_lattice(d, 0.9f, 0.2, 5);
    const std::vector<ChannelMaterials> channels = {channel({0.1, 0.8, 0.6}, true, {0.3, 0.5, -1.0}, false),
                                                    channel({0.05, 0.9, 0.0}, false)};
    const std::vector<SystemSpec> batch = {system_for(0, base(5)), system_for(1, base(12))};
    for (Precision p : precisions)
      for (StoreMode stores : {StoreMode::Regular, StoreMode::Streaming}) {
        if (p == Precision::Float16 && stores == StoreMode::Streaming) continue;  // half never streams
        const auto run = [&](int block) {
          SolverOptions o;
          o.precision = p;
          o.max_systems = 2;
          o.stores = stores;
          o.time_block = block;
          auto s = backend->create(g, channels, o);
          s->reset(batch);
          std::vector<std::vector<float>> t;
          std::vector<std::array<double, 5>> sums;
          std::vector<Residual> r;
          for (int chunk : {1, 7, 12, 3, 9, 2}) {
            s->step_and_measure(chunk, r);  // the measure fused into the last pass when blocking
            for (const Residual& x : r) sums.push_back({x.diff_sq, x.total_sq, x.diff_max, x.total_max, x.deficit_sq});
            for (int k = 0; k < 2; ++k) {
              t.emplace_back(d.count());
              s->read_totals(k, t.back().data());
            }
          }
          return std::make_pair(t, sums);
        };
        const auto one = run(1);
        for (int block : {2, 3, 5, 8}) {
          INFO(d.nx << "x" << d.ny << "x" << d.nz << " " << to_string(p) << " time_block " << block);
          CHECK(run(block) == one);
        }
      }
  }
}

TEST_CASE("float16 storage on the CPU rounds as the GPU's float16 mode does, and its error against float32 is bounded",
          "[transport][float16]") {
  const auto cpu = cpu_backend();
  const auto gpu = make_emulated_gpu_backend();
  if (!cpu->supports(Precision::Float16) || !gpu->supports(Precision::Float16)) {
    WARN("SKIPPED: this compiler has no _Float16");
    return;
  }
  // rows of 35 interior nodes (a converted chunk of 32 and a shifted tail) and of 18 (shorter than
  // a chunk: node by node); leaves and wood mixed in rows
  for (Dims d : {Dims{37, 21, 19}, Dims{20, 14, 15}}) {
    const LatticeGeometry g = random_lattice(d, 0.9f, 0.2, 13);
    const std::vector<ChannelMaterials> channels = {channel({0.05, 0.9, 0.6}, true, {0.3, 0.5, 0.0}, false)};
    const std::vector<SystemSpec> batch = {system_for(0, base(6)), system_for(0, base(11))};
    const auto run = [&](const Backend& b, Precision p) {
      auto s = b.create(g, channels, {p, 2});
      s->reset(batch);
      s->step(150);
      std::vector<Residual> r;
      s->measure(r);
      for (const Residual& x : r) CHECK(x.finite);
      std::vector<std::vector<float>> t(batch.size(), std::vector<float>(d.count()));
      for (std::size_t k = 0; k < batch.size(); ++k) s->read_totals(static_cast<int>(k), t[k].data());
      return t;
    };
    const auto c16 = run(*cpu, Precision::Float16), c32 = run(*cpu, Precision::Float32);
    const auto g16 = run(*gpu, Precision::Float16);
    for (std::size_t k = 0; k < batch.size(); ++k) {
      const double error = relative_gap(c16[k], c32[k]).l2, apart = relative_gap(c16[k], g16[k]).l2;
      INFO(d.nx << "x" << d.ny << "x" << d.nz << " system " << k << ": float16 vs float32 " << error
                << ", CPU vs GPU float16 " << apart);
      CHECK(error > 1e-5);  // it really is stored in 16 bits
      CHECK(error < 1e-2);
      CHECK(apart < 0.1 * error);  // the same rounding: only the float32 arithmetic's order differs
    }
  }
}

TEST_CASE("Skipping rows the light has not reached gives the same bits as sweeping them", "[transport][skip_dark]") {
  // Fronts halfway across the lattice after the early checks; light entering through every kind
  // of face (axes, edges' diagonals, ambient, a sun's three faces); rows longer than a chunk
  // (37: two chunks and a shifted tail) and shorter (12); step by step and blocked; a state
  // written in the middle (after which nothing may be skipped).
  const auto backend = cpu_backend(2);
  std::vector<Precision> precisions = {Precision::Float32, Precision::Float64};
  if (backend->supports(Precision::Float16)) precisions.push_back(Precision::Float16);
  const auto sun = static_boundary(decompose_direction({0.3, -0.5, -0.8}), 1.0, 0.0);
  for (Dims d : {Dims{37, 21, 17}, Dims{12, 19, 23}}) {
    const LatticeGeometry g = random_lattice(d, 0.9f, 0.2, 7);
    const std::vector<ChannelMaterials> channels = {channel({0.1, 0.8, 0.6}, true, {0.3, 0.5, -1.0}, false)};
    std::vector<std::vector<SystemSpec>> batches;
    for (int j : {0, 1, 4, 6, 7, 10, 13, 18}) batches.push_back({system_for(0, base(j))});
    batches.push_back({system_for(0, base(2)), system_for(0, base(15))});
    batches.push_back({system_for(0, sun)});
    for (Precision p : precisions)
      for (int block : {1, 3})
        for (const auto& batch : batches) {
          const auto run = [&](bool skip) {
            SolverOptions o;
            o.precision = p;
            o.max_systems = 2;
            o.time_block = block;
            o.skip_dark = skip;
            auto s = backend->create(g, channels, o);
            s->reset(batch);
            std::vector<std::vector<float>> t;
            std::vector<Residual> r;
            for (int chunk : {1, 2, 3, 4, 6, 9, 30}) {
              if (chunk == 6) {  // light everywhere, which the next steps must carry on from
                StateAccess* a = s->state_access();
                REQUIRE(a);
                std::vector<double> f;
                a->read_state(0, f);
                for (double& v : f) v += 1e-3;
                a->write_state(0, f);
              }
              s->step_and_measure(chunk, r);
              for (int k = 0; k < static_cast<int>(batch.size()); ++k) {
                t.emplace_back(d.count());
                s->read_totals(k, t.back().data());
              }
            }
            return t;
          };
          INFO(d.nx << "x" << d.ny << "x" << d.nz << " " << to_string(p) << " time_block " << block << " boundary "
                    << batch.front().boundary[1] << "," << batch.front().boundary[5]);
          const bool same = run(true) == run(false);
          CHECK(same);
        }
  }
}

TEST_CASE("Chunks without medium or without wood match the literal reference update", "[transport]") {
  // The row kernels run a chunk (a cache line of nodes) without medium as streaming alone and a
  // chunk without wood in a mixed row as the medium's collision alone. Rows of 37 nodes: chunks
  // 1-16, 17-32 and the shifted tail 20-35; each kind of chunk made somewhere.
  const Dims d{37, 13, 11};
  LatticeGeometry g = random_lattice(d, 0.95f, 0.15, 21);
  REQUIRE(g.material_count == 2);
  const auto clear = [&](int y, int z, int lo, int hi, bool medium_too) {
    for (int x = lo; x <= hi; ++x) {
      const std::size_t i = d.index(x, y, z);
      g.material[i] = 0;
      if (medium_too) g.density[i] = 0.0f;
    }
  };
  for (int z = 1; z < d.nz - 1; ++z)
    for (int y = 1; y < d.ny - 1; ++y) switch ((y + 2 * z) % 5) {
        case 0: clear(y, z, 1, 16, true); break;    // no medium in the first chunk
        case 1: clear(y, z, 17, 32, false); break;  // no wood in the second (the row still mixed)
        case 2: clear(y, z, 20, 35, true); break;   // no medium in the tail
        case 3: clear(y, z, 1, 35, false); break;   // one material
        default: break;                             // as drawn
      }
  const OpticalParams leaf{0.109, 0.891, -0.12}, bark{0.2, 0.7, -1.0};
  const auto backend = cpu_backend(2);
  for (StateLayout layout : {StateLayout::TwoLevels, StateLayout::InPlace})
    for (bool absorbs : {true, false})
      for (int sol : {0, 2, 14}) {
        INFO((layout == StateLayout::InPlace ? "in place" : "two levels") << ", solution " << sol << ", absorbs " << absorbs);
        ReferenceLattice ref(g, {build_omega(leaf), build_omega(bark)}, {absorbs, false}, base(sol));
        ref.step(29);
        SolverOptions o;
        o.precision = Precision::Float64;
        o.layout = layout;
        auto s = backend->create(g, {channel(leaf, absorbs, bark)}, o);
        s->reset({system_for(0, base(sol))});
        s->step(29);
        std::vector<Residual> r;
        s->measure(r);
        std::vector<float> got(d.count());
        s->read_totals(0, got.data());
        CHECK(max_relative_difference(ref.totals(), std::vector<double>(got.begin(), got.end()), 1e-3) < 1e-6);
      }
}

TEST_CASE("Streaming by position on a sparse lattice gives the same bits as the pull, with states written and after it is left",
          "[transport][shifted]") {
  // A plant-like lattice: medium (wood among it) in a block that touches few chunks, light from
  // axes, edges, every face and a sun. The state is read while streaming by position, and
  // written (changed) midway or before the first step (a warm start), which keeps streaming by
  // position, or taken by a Krylov vector, which goes back to the pull: the same bits as a solver
  // that never streamed by position, all along.
  const Dims d{37, 15, 13};
  LatticeGeometry g = random_lattice(d, 0.9f, 0.2, 31);
  for (int z = 1; z < d.nz - 1; ++z)
    for (int y = 1; y < d.ny - 1; ++y)
      for (int x = 1; x < d.nx - 1; ++x)
        if (x < 18 || x > 34 || y < 4 || y > 9 || z < 3 || z > 8) {  // to the row's end: a partial last chunk
          g.density[d.index(x, y, z)] = 0.0f;
          g.material[d.index(x, y, z)] = 0;
        }
  const auto sun = static_boundary(decompose_direction({-0.4, 0.2, -0.7}), 1.0, 0.05);
  const std::vector<ChannelMaterials> channels = {channel({0.1, 0.8, 0.6}, true, {0.3, 0.5, -1.0}, false),
                                                  channel({0.02, 0.9, 0.3}, false, {0.3, 0.5, -1.0}, false)};
  const auto backend = cpu_backend(2);
  for (Precision p : {Precision::Float32, Precision::Float64, Precision::Float16})
    for (const std::vector<SystemSpec>& batch :
         {std::vector<SystemSpec>{system_for(0, base(0)), system_for(1, base(1))},
          std::vector<SystemSpec>{system_for(0, base(6)), system_for(1, base(11))}, std::vector<SystemSpec>{system_for(1, sun)}})
      for (int leave : {0, 1, 2}) {  // 0: a written state, 1: a Krylov vector, 2: a state written first
        if (!backend->supports(p)) continue;  // float16 needs the compiler's _Float16
        const auto run = [&](bool shift) {
          SolverOptions o;
          o.precision = p;
          o.max_systems = 2;
          o.shift_streaming = shift;
          auto s = backend->create(g, channels, o);
          s->reset(batch);
          // chosen where asked (fewer than 3/4 of the chunks hold medium), and said so to bench
          CHECK(s->streams_by_position() == shift);
          CHECK(s->swept_fraction() == Approx(shift ? 0.3 : 1.0).margin(shift ? 0.2 : 0.0));
          if (leave == 2)  // a warm start's state: positive values everywhere, one per entry
            for (int k = 0; k < static_cast<int>(batch.size()); ++k) {
              std::vector<double> f(static_cast<std::size_t>(d3q19::kQ) * d.count());
              for (std::size_t i = 0; i < f.size(); ++i) f[i] = 0.01 + 1e-4 * static_cast<double>((i * 7919 + k) % 997);
              s->state_access()->write_state(k, f);
            }
          std::vector<std::vector<double>> out;
          std::vector<Residual> r;
          for (int chunk : {1, 2, 5, 9, 20, 7}) {
            s->step_and_measure(chunk, r);
            for (const Residual& x : r) out.push_back({x.diff_sq, x.total_sq, x.diff_max, x.total_max, x.deficit_sq});
            for (int k = 0; k < static_cast<int>(batch.size()); ++k) {
              std::vector<float> t(d.count());
              s->read_totals(k, t.data());
              out.emplace_back(t.begin(), t.end());
              std::vector<double> f;
              s->state_access()->read_state(k, f);
              out.push_back(f);
            }
            if (chunk == 9 && leave == 0) {
              std::vector<double> f;
              s->state_access()->read_state(0, f);
              for (double& v : f) v *= 1.5;
              s->state_access()->write_state(0, f);
            }
            if (chunk == 9 && leave == 1) {
              s->krylov_vectors()->vectors_reserve(1);
              s->krylov_vectors()->vector_from_state(0);
            }
          }
          // a Krylov vector leaves for the pull at step 17; written states keep streaming by position
          CHECK(s->streams_by_position() == (shift && leave != 1));
          return out;
        };
        INFO(to_string(p) << ", first boundary " << batch.front().boundary[1] << ", "
                          << (leave == 0 ? "a state written midway" : leave == 1 ? "left by a Krylov vector" : "a state written first"));
        const bool same = run(true) == run(false);  // (not printed: megabytes of values)
        CHECK(same);
      }
}

TEST_CASE("The CPU picks in place only for dense lattices larger than its cache", "[transport][shifted]") {
  const auto backend = cpu_backend(2);
  const double cache = static_cast<double>(backend->cache_bytes());
  if (cache <= 0) {
    WARN("the host reports no last-level cache: the CPU never prefers in place, nothing to check");
    return;
  }
  // An edge whose two-level float32 state is twice the size in-place starts at.
  int n = 16;
  while (static_cast<double>(backend->bytes_per_system({n, n, n}, Precision::Float32)) <= 4.0 * cache) n += 8;
  const Dims d{n, n, n};
  LatticeGeometry dense = uniform_lattice(d, 0.5f);
  LatticeGeometry sparse = uniform_lattice(d, 0.0f);  // a plant-like block: most chunks without medium
  for (int z = 1; z < n / 3; ++z)
    for (int y = 1; y < n / 3; ++y)
      for (int x = 1; x < n / 3; ++x) sparse.density[d.index(x, y, z)] = 0.5f;
  CHECK(backend->prefers_in_place(dense, Precision::Float32, false));
  CHECK_FALSE(backend->prefers_in_place(sparse, Precision::Float32, false));  // it streams by position
  CHECK(backend->prefers_in_place(sparse, Precision::Float32, true));  // a rewritten state leaves that
  CHECK_FALSE(backend->prefers_in_place(dense, Precision::Float16, false));
  const Dims small{16, 16, 16};
  CHECK_FALSE(backend->prefers_in_place(uniform_lattice(small, 0.5f), Precision::Float32, false));
}
