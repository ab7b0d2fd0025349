// The forest section (lblight/scene/forest.h): listed and generated instances, deterministic
// placement that keeps its spacing, and the checks against instance_rotation.
#include <catch2/catch.hpp>

#include <chrono>
#include <cmath>
#include <map>

#include "lblight/scene/scene.h"
#include "tests/support/expect_error.h"

using namespace lblight;
using lblight::test::expect_invalid_input;

namespace {

// An input error whose message mentions every one of `words`.
template <class F>
void expect_invalid(F&& f, std::initializer_list<const char*> words) {
  const Error e = expect_invalid_input(std::forward<F>(f), "");
  for (const char* w : words) {
    INFO(e.what());
    CHECK(std::string(e.what()).find(w) != std::string::npos);
  }
}

std::string forest_scene(const std::string& forest, const std::string& rotation = "yaw") {
  return R"({"version": 1, "models": [
      {"name": "tree", "density": {"type": "procedural", "shape": "plant", "resolution": 16}, "material": "leaf"},
      {"name": "bush", "density": {"type": "procedural", "shape": "plant", "resolution": 12, "seed": 3}, "material": "leaf"}],
    "lighting": {"mode": "base", "sun_range": {"min_elevation": 0, "max_elevation": 90}, "instance_rotation": ")" +
         rotation + R"("}, "forest": )" + forest + "}";
}

const char* kGenerator = R"({"instances": [{"model": "tree", "position": [1, 2, 0], "yaw_degrees": 90, "scale": 1.5}],
  "generator": {"area": [0, 0, 100, 50], "count": 400, "min_spacing": 2.0, "yaw_degrees": [0, 360],
                "scale": [0.8, 1.2], "models": [{"model": "tree", "weight": 3}, {"model": "bush", "weight": 1}],
                "seed": 7}})";

}  // namespace

TEST_CASE("A forest's generator places its instances deterministically, apart, by weight", "[scene]") {
  const Scene s = parse_scene(forest_scene(kGenerator), "forest.json");
  const std::vector<ForestInstance> a = forest_instances(s.forest, "forest.json");
  const std::vector<ForestInstance> b = forest_instances(s.forest, "forest.json");
  REQUIRE(a.size() == 401);
  CHECK(a[0].model == "tree");
  CHECK(a[0].yaw_degrees == 90.0);
  CHECK(a[0].scale == 1.5);
  std::map<std::string, int> per_model;
  double closest = 1e9;
  for (std::size_t i = 1; i < a.size(); ++i) {
    CHECK(a[i].position[0] == b[i].position[0]);  // the same numbers every time
    CHECK(a[i].yaw_degrees == b[i].yaw_degrees);
    CHECK(a[i].position[0] >= 0.0);
    CHECK(a[i].position[0] <= 100.0);
    CHECK(a[i].position[1] >= 0.0);
    CHECK(a[i].position[1] <= 50.0);
    CHECK(a[i].scale >= 0.8);
    CHECK(a[i].scale <= 1.2);
    ++per_model[a[i].model];
    for (std::size_t j = 1; j < i; ++j)
      closest = std::min(closest, std::hypot(a[i].position[0] - a[j].position[0], a[i].position[1] - a[j].position[1]));
  }
  CHECK(closest >= 2.0);
  CHECK(per_model["tree"] > 2 * per_model["bush"]);  // weights 3 : 1
  CHECK(per_model["bush"] > 50);
}

TEST_CASE("A forest's errors name the field, the value and what is allowed", "[scene]") {
  // a rotated copy of a model baked for instance_rotation none
  expect_invalid([] { parse_scene(forest_scene(kGenerator, "none"), "f.json"); }, {"/forest/instances/0", "yaw_degrees", "instance_rotation"});
  expect_invalid([] { parse_scene(forest_scene(R"({"generator": {"area": [0, 0, 10, 10], "count": 5, "yaw_degrees": [0, 90], "models": [{"model": "tree"}]}})", "none"), "f.json"); },
                 {"/forest/generator", "yaw_degrees", "instance_rotation"});
  expect_invalid([] { parse_scene(forest_scene(R"({"instances": [{"model": "oak", "position": [0, 0, 0]}]})"), "f.json"); },
                 {"/forest/instances/0", "unknown model 'oak'", "tree"});
  expect_invalid([] { parse_scene(forest_scene(R"({"instances": [{"model": "tree", "position": [0, 0]}]})"), "f.json"); },
                 {"/forest/instances/0/position", "[x, y, z]"});
  expect_invalid([] { parse_scene(forest_scene(R"({"generator": {"area": [0, 0, 10, 10], "count": 5, "density": 1, "models": [{"model": "tree"}]}})"), "f.json"); },
                 {"/forest/generator", "count or density"});
  expect_invalid([] { parse_scene(forest_scene(R"({"instances": [{"model": "tree", "position": [0, 0, 0], "scale": 0}]})"), "f.json"); },
                 {"scale"});
  // an area that cannot hold the count at that spacing: named when the instances are made, at
  // once (random placement fits about 25 discs of diameter 2 in 12 x 12), not after a million tries
  const Scene s = parse_scene(forest_scene(R"({"generator": {"area": [0, 0, 10, 10], "count": 500, "min_spacing": 2, "models": [{"model": "tree"}]}})"), "f.json");
  expect_invalid([&] { forest_instances(s.forest, "f.json"); }, {"/forest/generator", "cannot place 500", "fits about 25"});
  const Scene big = parse_scene(forest_scene(R"({"generator": {"area": [0, 0, 100, 100], "count": 1000000, "min_spacing": 3, "models": [{"model": "tree"}]}})"), "f.json");
  const auto t0 = std::chrono::steady_clock::now();
  expect_invalid([&] { forest_instances(big.forest, "f.json"); }, {"/forest/generator", "cannot place 1000000"});
  CHECK(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < 1.0);
}
