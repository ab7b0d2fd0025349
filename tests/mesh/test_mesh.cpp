// Meshes in: the OBJ reader, leaf / wood classification by name, and the voxeliser ([Steele2009] sec. 5.1)
// against exact analytic occupied fractions and a brute-force reference.
#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include <atomic>
#include <cmath>
#include <random>
#include <sstream>

#include "lblight/io/vdb_io.h"
#include "lblight/mesh/classify.h"
#include "lblight/mesh/obj_reader.h"
#include "lblight/mesh/tri_box.h"
#include "lblight/mesh/voxelize.h"
#include "lblight/scene/load_model.h"
#include "lblight/scene/mesh_source.h"
#include "tests/support/expect_error.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;
namespace fs = std::filesystem;

namespace {

// The shipped example plant (wood and leaf parts), shared by the voxeliser tests.
fs::path bush_obj_path() { return fs::path(LBLIGHT_SOURCE_DIR) / "configs" / "meshes" / "bush.obj"; }

TriangleMesh parse(const std::string& text) {
  std::istringstream in(text);
  return parse_obj(in, "test.obj");
}

// The message of the InvalidInput error `f` must throw, for several checks of its words.
template <class F>
std::string invalid_message(F&& f) {
  return expect_invalid_input(std::forward<F>(f), "").what();
}

// An axis-aligned box [lo, hi]^3 as 6 outward-facing quads (12 triangles) with material `mtl`.
std::string box_obj(double lo, double hi, const std::string& mtl = "bark", int first_vertex = 1) {
  std::ostringstream s;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) s << "v " << (i ? hi : lo) << " " << (j ? hi : lo) << " " << (k ? hi : lo) << "\n";
  s << "usemtl " << mtl << "\n";
  const int v = first_vertex;  // vertex (i, j, k) is v + i + 2j + 4k
  const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : faces) s << "f " << v + f[0] << " " << v + f[1] << " " << v + f[2] << " " << v + f[3] << "\n";
  return s.str();
}

VoxelizeOptions unit_bounds(int resolution, int supersample) {
  VoxelizeOptions o;
  o.resolution = resolution;
  o.supersample = supersample;
  o.has_bounds = true;
  o.bounds_min = {0, 0, 0};
  o.bounds_max = {1, 1, 1};
  return o;
}

VoxelizeResult run(const TriangleMesh& m, const VoxelizeOptions& o) {
  return voxelize(m, classify_parts(m, {}, {}).part_class, o);
}

// Fine indices in [lo, hi] that fall into coarse cell c (S fine cells per coarse cell).
int overlap(int lo, int hi, int c, int S) { return std::max(0, std::min(hi, c * S + S - 1) - std::max(lo, c * S) + 1); }

}  // namespace

TEST_CASE("OBJ: groups, materials, polygons, negative indices, vertex colours", "[mesh]") {
  const TriangleMesh m = parse(
      "# comment\n"
      "mtllib plant.mtl\n"
      "v 0 0 0\nv 1 0 0 1.0\nv 1 1 0 0.2 0.8 0.1\nv 0 1 0\r\n"
      "vt 0 0\nvn 0 0 1\ns off\n"
      "o Tree\ng Trunk\nusemtl Bark\n"
      "f 1/1/1 2/1/1 3/1/1 4/1/1\n"          // quad: 2 triangles
      "usemtl Leaves\n"
      "f -4//1 -3//1 \\\n -2//1\n"            // negative indices, continued line
      "o Other\nf 1 2 3 4 1\n"                // pentagon; `o` starts without the previous group
      "l 1 2\np 3\ncurv 0 1 1 2\n");
  REQUIRE(m.vertices.size() == 4);
  REQUIRE(m.triangles.size() == 2 + 1 + 3);
  CHECK(m.triangles[0] == std::array<std::uint32_t, 3>{0, 1, 2});
  CHECK(m.triangles[1] == std::array<std::uint32_t, 3>{0, 2, 3});
  CHECK(m.triangles[2] == std::array<std::uint32_t, 3>{0, 1, 2});
  CHECK(m.polygons == 2);
  CHECK(m.ignored_lines == 2);
  CHECK(m.unknown_statements == 1);
  REQUIRE(m.parts.size() == 3);
  CHECK(m.parts[0] == MeshPart{"Tree", "Trunk", "Bark"});
  CHECK(m.parts[1] == MeshPart{"Tree", "Trunk", "Leaves"});
  CHECK(m.parts[2] == MeshPart{"Other", "", "Leaves"});
  CHECK(m.triangle_part == std::vector<std::uint32_t>{0, 0, 1, 2, 2, 2});
}

TEST_CASE("OBJ: bad input gives InvalidInput naming file and line, never a crash", "[mesh]") {
  CHECK_THAT(invalid_message([] { parse("v 0 0 0\nv 1 0\n"); }), Catch::Contains("test.obj:2") && Catch::Contains("3 coordinates"));
  CHECK_THAT(invalid_message([] { parse("v 0 0 0\nv 1 nan 0\n"); }), Catch::Contains("test.obj:2") && Catch::Contains("not a finite"));
  CHECK_THAT(invalid_message([] { parse("v 0 0 inf\n"); }), Catch::Contains("not a finite"));
  CHECK_THAT(invalid_message([] { parse("v 0 0 1e999\n"); }), Catch::Contains("not a finite"));
  CHECK_THAT(invalid_message([] { parse("v 0 0 x\n"); }), Catch::Contains("not a number"));
  CHECK_THAT(invalid_message([] { parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"); }),
             Catch::Contains("test.obj:4") && Catch::Contains("vertex 4") && Catch::Contains("only 3"));
  CHECK_THAT(invalid_message([] { parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n"); }), Catch::Contains("test.obj:4"));
  CHECK_THAT(invalid_message([] { parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"); }), Catch::Contains("index 0"));
  CHECK_THAT(invalid_message([] { parse("v 0 0 0\nv 1 0 0\nf 1 2\n"); }), Catch::Contains("at least 3"));
  CHECK_THAT(invalid_message([] { parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 a\n"); }), Catch::Contains("not a vertex index"));
  // Forward references are allowed (the whole file's vertices count).
  CHECK(parse("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").triangles.size() == 1);

  TempDir tmp;
  CHECK_THAT(invalid_message([&] { read_mesh(tmp / "missing.obj"); }), Catch::Contains("does not exist"));
  write_text(tmp / "empty.obj", "# nothing\nv 0 0 0\nl 1 1\n");
  CHECK_THAT(invalid_message([&] { read_mesh(tmp / "empty.obj"); }), Catch::Contains("no faces"));
  write_text(tmp / "mesh.stl", "solid x\n");
  CHECK_THAT(invalid_message([&] { read_mesh(tmp / "mesh.stl"); }), Catch::Contains("unsupported format"));
}

TEST_CASE("Leaf and wood by material, group or object name", "[mesh]") {
  CHECK(name_matches("leaf", "Rosa_canina_LEAF_01"));
  CHECK_FALSE(name_matches("leaf", "bark"));
  CHECK(name_matches("tw?g*", "Twig_3"));
  CHECK_FALSE(name_matches("tw?g", "Twig_3"));  // a glob matches the whole name

  const TriangleMesh m = parse(
      "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
      "g crown\nusemtl Leaves_Mat\nf 1 2 3\n"      // material decides: leaf
      "g Trunk\nusemtl Material.001\nf 1 2 3\n"    // material matches nothing, group does: wood
      "g x\nusemtl leafstalk\nf 1 2 3\n"           // both 'leaf' and 'stem'? only 'leaf' matches: leaf
      "g y\nusemtl pinecone\nf 1 2 3\nf 1 2 3\n"); // nothing matches: leaf, counted
  const Classification c = classify_parts(m, {}, {});
  REQUIRE(c.part_class.size() == 4);
  CHECK(c.part_class[0] == TriangleClass::Leaf);
  CHECK(c.part_class[1] == TriangleClass::Wood);
  CHECK(c.part_class[2] == TriangleClass::Leaf);
  CHECK(c.part_class[3] == TriangleClass::Leaf);
  CHECK(c.unmatched_triangles == 2);
  CHECK(c.unmatched_parts.size() == 1);
  CHECK(c.leaf_triangles == 4);
  CHECK(c.wood_triangles == 1);
  // The longest matching pattern wins across the lists; ties go to leaf.
  const Classification d = classify_parts(m, {}, {"leafstalk", "pinecone"});
  CHECK(d.part_class[2] == TriangleClass::Wood);
  CHECK(d.part_class[3] == TriangleClass::Wood);
  CHECK(d.part_class[1] == TriangleClass::Leaf);  // given wood patterns replace the defaults: 'Trunk' no longer matches
  CHECK(d.unmatched_triangles == 1);
  const Classification e = classify_parts(m, {"leaves_mat"}, {"leaves_mat"});
  CHECK(e.part_class[0] == TriangleClass::Leaf);
}

TEST_CASE("Voxelising a closed box gives the exact occupied fractions", "[mesh]") {
  const int R = 4, S = 8;
  SECTION("faces inside fine cells: box [0.1, 0.9] in the unit box") {
    // Fine coordinates 3.2 .. 28.8: the shell of fine cells 3..28 is touched.
    const VoxelizeResult r = run(parse(box_obj(0.1, 0.9)), unit_bounds(R, S));
    REQUIRE(r.grid.dims == Dims{R, R, R});
    std::uint64_t total = 0;
    for (int k = 0; k < R; ++k)
      for (int j = 0; j < R; ++j)
        for (int i = 0; i < R; ++i) {
          const int all = overlap(3, 28, i, S) * overlap(3, 28, j, S) * overlap(3, 28, k, S);
          const int inner = overlap(4, 27, i, S) * overlap(4, 27, j, S) * overlap(4, 27, k, S);
          INFO(i << " " << j << " " << k);
          CHECK(r.grid.density[r.grid.dims.index(i, j, k)] == static_cast<float>(all - inner) / (S * S * S));
          CHECK(r.grid.material[r.grid.dims.index(i, j, k)] == ((all - inner) > 0 ? kMaterialWood : kMaterialMedium));
          total += static_cast<std::uint64_t>(all - inner);
        }
    CHECK(r.stats.fine_occupied == total);
    CHECK(total == 26u * 26 * 26 - 24u * 24 * 24);
    CHECK(r.stats.fine_wood == total);
    CHECK(r.stats.fine_leaf == 0);
  }
  SECTION("faces on the border of the grid: the mesh's own bounds") {
    // No bounds: the box is the grid, its faces lie on the outer planes of the fine grid.
    const VoxelizeResult r = run(parse(box_obj(-0.5, 1.5)), [] {
      VoxelizeOptions o;
      o.resolution = 4;
      o.supersample = 8;
      return o;
    }());
    REQUIRE(r.grid.dims == Dims{R, R, R});
    for (int k = 0; k < R; ++k)
      for (int j = 0; j < R; ++j)
        for (int i = 0; i < R; ++i) {
          const int inner = overlap(1, 30, i, S) * overlap(1, 30, j, S) * overlap(1, 30, k, S);
          CHECK(r.grid.density[r.grid.dims.index(i, j, k)] == static_cast<float>(S * S * S - inner) / (S * S * S));
        }
    // Voxel centres: node (i, j, k) at -0.5 + (i + 0.5) * 0.5.
    const auto& m = r.grid.index_to_world;
    CHECK(m[0] == Approx(0.5));
    CHECK(m[3] == Approx(-0.25));
    CHECK(m[7] == Approx(-0.25));
    CHECK(m[11] == Approx(-0.25));
  }
  SECTION("solid fill: every fine cell whose centre is inside, plus the surface") {
    for (FillMode fill : {FillMode::Parity, FillMode::Winding}) {
      VoxelizeOptions o = unit_bounds(R, S);
      o.fill = fill;
      const VoxelizeResult r = run(parse(box_obj(0.1, 0.9)), o);
      for (int k = 0; k < R; ++k)
        for (int j = 0; j < R; ++j)
          for (int i = 0; i < R; ++i) {
            const int all = overlap(3, 28, i, S) * overlap(3, 28, j, S) * overlap(3, 28, k, S);
            CHECK(r.grid.density[r.grid.dims.index(i, j, k)] == static_cast<float>(all) / (S * S * S));
          }
      CHECK(r.stats.open_columns == 0);
    }
  }
}

TEST_CASE("Overlapping closed parts: winding fills the union, parity the symmetric difference", "[mesh]") {
  // Boxes [0.1, 0.6]^3 and [0.35, 0.9]^3 (fine 3.2..19.2 and 11.2..28.8 at N = 32).
  const TriangleMesh m = parse(box_obj(0.1, 0.6, "bark", 1) + box_obj(0.35, 0.9, "bark", 9));
  auto count = [&](FillMode f) {
    VoxelizeOptions o = unit_bounds(4, 8);
    o.fill = f;
    return run(m, o).stats.fine_occupied;
  };
  // Cell centres strictly inside: 3..18 and 11..28 per axis; surfaces add the shells 3..19, 11..28.
  auto in_a = [](int x) { return x >= 3 && x <= 19; };
  auto in_b = [](int x) { return x >= 11 && x <= 28; };
  std::uint64_t uni = 0, sym = 0;
  for (int z = 0; z < 32; ++z)
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x) {
        const bool a = in_a(x) && in_a(y) && in_a(z), b = in_b(x) && in_b(y) && in_b(z);
        const bool a_in = x >= 3 && x <= 18 && y >= 3 && y <= 18 && z >= 3 && z <= 18;
        const bool b_in = x >= 11 && y >= 11 && z >= 11 && x <= 28 && y <= 28 && z <= 28;
        const bool a_surf = a && !(x >= 4 && x <= 18 && y >= 4 && y <= 18 && z >= 4 && z <= 18);
        const bool b_surf = b && !(x >= 12 && y >= 12 && z >= 12 && x <= 27 && y <= 27 && z <= 27);
        uni += a_in || b_in || a_surf || b_surf;
        sym += (a_in != b_in) || a_surf || b_surf;
      }
  CHECK(count(FillMode::Winding) == uni);
  CHECK(count(FillMode::Parity) == sym);
}

TEST_CASE("Voxelising one triangle gives the exact occupied fractions", "[mesh]") {
  // Right triangle in the plane z = 16.5 (fine units, N = 32): x >= 3.2, y >= 3.2, x + y <= 32.5.
  // A closed fine cell [a, a+1] x [b, b+1] touches it iff a >= 3, b >= 3 and
  // max(a, 3.2) + max(b, 3.2) <= 32.5 (its lowest corner inside the triangle's half plane).
  const int R = 4, S = 8, N = R * S;
  const double f = 1.0 / N;
  std::ostringstream obj;
  obj << "v " << 3.2 * f << " " << 3.2 * f << " " << 16.5 * f << "\n"
      << "v " << 29.3 * f << " " << 3.2 * f << " " << 16.5 * f << "\n"
      << "v " << 3.2 * f << " " << 29.3 * f << " " << 16.5 * f << "\nf 1 2 3\n";
  const VoxelizeResult r = run(parse(obj.str()), unit_bounds(R, S));
  std::vector<int> expect(static_cast<std::size_t>(R * R * R), 0);
  for (int b = 0; b < N; ++b)
    for (int a = 0; a < N; ++a)
      if (a >= 3 && b >= 3 && std::max<double>(a, 3.2) + std::max<double>(b, 3.2) <= 32.5)
        ++expect[static_cast<std::size_t>((2 * R + b / S) * R + a / S)];  // k = 16 / 8 = 2
  std::uint64_t total = 0;
  for (int k = 0; k < R; ++k)
    for (int j = 0; j < R; ++j)
      for (int i = 0; i < R; ++i) {
        const int e = expect[static_cast<std::size_t>((k * R + j) * R + i)];
        total += static_cast<std::uint64_t>(e);
        INFO(i << " " << j << " " << k);
        CHECK(r.grid.density[r.grid.dims.index(i, j, k)] == static_cast<float>(e) / (S * S * S));
      }
  CHECK(r.stats.fine_occupied == total);
  CHECK(r.grid.material[r.grid.dims.index(1, 1, 2)] == kMaterialMedium);  // no name: leaf
}

TEST_CASE("Voxeliser matches a brute-force triangle/box test on every fine cell", "[mesh]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.1, 1.1);  // some triangles stick out of the box
  TriangleMesh m;
  m.source = "random";
  m.parts = {{"", "", "leaf"}, {"", "", "bark"}};
  for (int t = 0; t < 24; ++t) {
    const Vec3 c{u(rng), u(rng), u(rng)};
    for (int k = 0; k < 3; ++k) m.vertices.push_back({c[0] + 0.3 * (u(rng) - 0.5), c[1] + 0.3 * (u(rng) - 0.5), c[2] + 0.3 * (u(rng) - 0.5)});
    m.triangles.push_back({static_cast<std::uint32_t>(3 * t), static_cast<std::uint32_t>(3 * t + 1), static_cast<std::uint32_t>(3 * t + 2)});
    m.triangle_part.push_back(static_cast<std::uint32_t>(t % 2));
  }
  // Axis-aligned triangles too (normals along the axes, edges along the axes).
  for (int a = 0; a < 3; ++a) {
    const std::uint32_t base = static_cast<std::uint32_t>(m.vertices.size());
    Vec3 p0{0.3137, 0.4211, 0.5329}, p1 = p0, p2 = p0;  // on no fine-cell plane for these grids
    p1[(a + 1) % 3] += 0.3719;
    p2[(a + 2) % 3] += 0.2903;
    m.vertices.insert(m.vertices.end(), {p0, p1, p2});
    m.triangles.push_back({base, base + 1, base + 2});
    m.triangle_part.push_back(0);
  }
  for (auto [R, S] : {std::pair{9, 8}, std::pair{20, 5}, std::pair{4, 64}, std::pair{30, 3}}) {
    const int N = R * S;
    const VoxelizeResult r = voxelize(m, {TriangleClass::Leaf, TriangleClass::Wood}, unit_bounds(R, S));
    std::vector<std::uint8_t> hit(static_cast<std::size_t>(N) * N * N, 0);  // bit 0 leaf, bit 1 wood
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      Vec3 v[3];
      for (int q = 0; q < 3; ++q)
        for (int a = 0; a < 3; ++a) v[q][a] = m.vertices[m.triangles[t][q]][a] * N;
      int lo[3], hi[3];
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::max(0, static_cast<int>(std::floor(std::min({v[0][a], v[1][a], v[2][a]}))) - 1);
        hi[a] = std::min(N - 1, static_cast<int>(std::floor(std::max({v[0][a], v[1][a], v[2][a]}))) + 1);
      }
      for (int z = lo[2]; z <= hi[2]; ++z)
        for (int y = lo[1]; y <= hi[1]; ++y)
          for (int x = lo[0]; x <= hi[0]; ++x)
            if (triangle_box_overlap(v[0], v[1], v[2], {x + 0.5, y + 0.5, z + 0.5}, {0.5, 0.5, 0.5}))
              hit[(static_cast<std::size_t>(z) * N + y) * N + x] |= static_cast<std::uint8_t>(1u << (m.triangle_part[t]));
    }
    int wrong = 0;
    for (int k = 0; k < R; ++k)
      for (int j = 0; j < R; ++j)
        for (int i = 0; i < R; ++i) {
          int occ = 0, leaf = 0, wood = 0;
          for (int z = k * S; z < k * S + S; ++z)
            for (int y = j * S; y < j * S + S; ++y)
              for (int x = i * S; x < i * S + S; ++x) {
                const std::uint8_t h = hit[(static_cast<std::size_t>(z) * N + y) * N + x];
                occ += h != 0;
                leaf += (h & 1) != 0;
                wood += (h & 2) != 0;
              }
          const std::size_t n = r.grid.dims.index(i, j, k);
          wrong += r.grid.density[n] != static_cast<float>(occ) / (S * S * S);
          wrong += r.grid.material[n] != (wood > leaf ? kMaterialWood : kMaterialMedium);
        }
    INFO("R " << R << " S " << S);
    CHECK(wrong == 0);
  }
}

TEST_CASE("Leaf area maps to total density: sum = area x |n|_1 / (S h^2), up to the edge term", "[mesh]") {
  // 27 leaves of random orientation, one in each of 3x3x3 slots so that none share a fine cell.
  // The fine cells a convex planar region T touches are those whose centre lies in T + cell, of
  // volume (mixed volumes, cell of edge hf) A |n|_1 hf + (X + Y + Z) hf^2 + hf^3, with
  // |n|_1 = |nx|+|ny|+|nz| (the cell's width along the normal) and X, Y, Z the extents of T's
  // bounding box: that is the expected count for a randomly placed T (docs/voxelization.md).
  // Bounds that need no averaging: at least A |n|_1 / hf^2, at most (A + P r + pi r^2) |n|_1 / hf^2
  // with r = sqrt(3)/2 hf.
  for (unsigned seed : {5u, 6u, 7u, 8u}) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double kPi = std::acos(-1.0);
  TriangleMesh m;
  m.parts = {{"", "", "leaf"}};
  double lower = 0, upper = 0, expected = 0;
  const int R = 12, S = 8;
  const double hf = 1.0 / (R * S), r = std::sqrt(3.0) / 2 * hf;
  for (int s = 0; s < 27; ++s) {
    const Vec3 c{(s % 3 + 0.5) / 3, (s / 3 % 3 + 0.5) / 3, (s / 9 + 0.5) / 3};
    // a random rotation of a triangle of legs 0.2 and 0.15
    const double th = std::acos(2 * u(rng) - 1), ph = 2 * kPi * u(rng), ps = 2 * kPi * u(rng);
    const Vec3 n{std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)};
    const Vec3 helper = std::abs(n[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    Vec3 e1 = cross3(n, helper);
    const double l1 = std::sqrt(dot3(e1, e1));
    for (double& x : e1) x /= l1;
    const Vec3 e2 = cross3(n, e1);
    const Vec3 a{std::cos(ps) * e1[0] + std::sin(ps) * e2[0], std::cos(ps) * e1[1] + std::sin(ps) * e2[1],
                 std::cos(ps) * e1[2] + std::sin(ps) * e2[2]};
    const Vec3 b = cross3(n, a);
    const std::uint32_t base = static_cast<std::uint32_t>(m.vertices.size());
    const Vec3 p0{c[0] - 0.07 * a[0] - 0.05 * b[0], c[1] - 0.07 * a[1] - 0.05 * b[1], c[2] - 0.07 * a[2] - 0.05 * b[2]};
    m.vertices.push_back(p0);
    m.vertices.push_back({p0[0] + 0.2 * a[0], p0[1] + 0.2 * a[1], p0[2] + 0.2 * a[2]});
    m.vertices.push_back({p0[0] + 0.15 * b[0], p0[1] + 0.15 * b[1], p0[2] + 0.15 * b[2]});
    m.triangles.push_back({base, base + 1, base + 2});
    m.triangle_part.push_back(0);
    const double area = 0.5 * 0.2 * 0.15, perimeter = 0.2 + 0.15 + 0.25;
    const double w = std::abs(n[0]) + std::abs(n[1]) + std::abs(n[2]);
    lower += area * w / (hf * hf);
    upper += (area + perimeter * r + kPi * r * r) * w / (hf * hf);
    double extents = 0;
    for (int k = 0; k < 3; ++k)
      extents += std::max({m.vertices[base][k], m.vertices[base + 1][k], m.vertices[base + 2][k]}) -
                 std::min({m.vertices[base][k], m.vertices[base + 1][k], m.vertices[base + 2][k]});
    expected += area * w / (hf * hf) + extents / hf + 1.0;
  }
  const VoxelizeResult res = voxelize(m, {TriangleClass::Leaf}, unit_bounds(R, S));
  double density_sum = 0;
  for (float d : res.grid.density) density_sum += d;
  const double fine = density_sum * S * S * S;
  CHECK(fine == Approx(static_cast<double>(res.stats.fine_occupied)));
  INFO("seed " << seed << ": fine cells " << fine << ", area term " << lower << ", bound " << upper << ", expected " << expected);
  CHECK(fine >= lower);
  CHECK(fine <= upper);
  // One placement is not an average, but over 27 leaves the count is within 1.5% of the expectation.
  CHECK(fine == Approx(expected).epsilon(0.015));
  }
}

TEST_CASE("Brown when wood touches more fine cells than leaves, ties green", "[mesh]") {
  // Three nodes of one world unit (bounds [0, 3] x [0, 1] x [0, 1], resolution 3, S = 8). In each,
  // two horizontal squares at z = 0.3 and 0.7; a square [u0, u1]^2 with u0 = 0.05, u1 = 0.95 touches
  // 8 x 8 fine cells, a half-size one [0.05, 0.45]^2 touches 4 x 4.
  auto square = [](double x0, double size, double z, const std::string& mtl, int& v) {
    std::ostringstream s;
    s << "usemtl " << mtl << "\n";
    s << "v " << x0 << " 0.05 " << z << "\nv " << x0 + size << " 0.05 " << z << "\nv " << x0 + size << " "
      << 0.05 + size << " " << z << "\nv " << x0 << " " << 0.05 + size << " " << z << "\n";
    s << "f " << v << " " << v + 1 << " " << v + 2 << " " << v + 3 << "\n";
    v += 4;
    return s.str();
  };
  int v = 1;
  std::string obj;
  // (one call per statement: `v` numbers the vertices in file order)
  obj += square(0.05, 0.9, 0.3, "bark", v);
  obj += square(0.05, 0.4, 0.7, "leaves", v);  // node 0: 64 wood, 16 leaf
  obj += square(1.05, 0.4, 0.3, "bark", v);
  obj += square(1.05, 0.9, 0.7, "leaves", v);  // node 1: 16 wood, 64 leaf
  obj += square(2.05, 0.9, 0.3, "bark", v);
  obj += square(2.05, 0.9, 0.7, "leaves", v);  // node 2: 64 and 64, a tie
  obj += square(0.05, 0.4, 0.3, "leaves", v);  // node 0, in the bark's plane: these cells count for both
  VoxelizeOptions o;
  o.resolution = 3;
  o.supersample = 8;
  o.has_bounds = true;
  o.bounds_min = {0, 0, 0};
  o.bounds_max = {3, 1, 1};
  const VoxelizeResult r = run(parse(obj), o);
  REQUIRE(r.grid.dims == Dims{3, 1, 1});
  CHECK(r.grid.material[0] == kMaterialWood);
  CHECK(r.grid.material[1] == kMaterialMedium);
  CHECK(r.grid.material[2] == kMaterialMedium);  // tie: green
  CHECK(r.grid.density[0] == 80.0f / 512);
  CHECK(r.grid.density[2] == 128.0f / 512);
  CHECK(r.stats.fine_both == 16);
  CHECK(r.stats.brown_nodes == 1);
}

TEST_CASE("Voxeliser: degenerate and outside triangles are skipped and counted, bad meshes throw", "[mesh]") {
  TriangleMesh m = parse(
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 5 5 5\nv 6 5 5\nv 5 6 5\n"
      "f 1 2 3\n"   // fine
      "f 1 2 4\n"   // collinear: zero area
      "f 1 1 3\n"   // repeated vertex
      "f 5 6 7\n"); // outside the bounds below
  VoxelizeOptions o = unit_bounds(4, 4);
  VoxelizeResult r = run(m, o);
  CHECK(r.stats.degenerate == 2);
  CHECK(r.stats.outside == 1);
  CHECK(r.stats.fine_occupied > 0);
  // Without bounds the box is the triangles with area: (0..6)^2 x (0..5).
  o.has_bounds = false;
  r = run(m, o);
  CHECK(r.grid.voxel_size()[0] == Approx(6.0 / 4));
  CHECK(r.stats.outside == 0);

  CHECK_THAT(invalid_message([] { run(parse("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"), VoxelizeOptions{}); }),
             Catch::Contains("zero area"));
  CHECK_THAT(invalid_message([] { run(parse("v 5 5 5\nv 6 5 5\nv 5 6 5\nf 1 2 3\n"), unit_bounds(4, 4)); }),
             Catch::Contains("inside the voxelisation box"));
  TriangleMesh nan = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  nan.vertices[1][2] = std::nan("");
  CHECK_THAT(invalid_message([&] { run(nan, VoxelizeOptions{}); }), Catch::Contains("not finite"));
  VoxelizeOptions bad;
  bad.supersample = 65;
  CHECK_THAT(invalid_message([&] { run(m, bad); }), Catch::Contains("supersample"));
}

TEST_CASE("Voxeliser: non-manifold and open meshes are fine, fill of an open mesh is reported", "[mesh]") {
  // Three triangles sharing one edge (non-manifold), and a box without its top face.
  std::string open = box_obj(0.1, 0.9);
  const std::size_t top = open.find("f 5 6 8 7\n");
  REQUIRE(top != std::string::npos);
  open.erase(top, 10);
  const TriangleMesh m = parse(open + "v 0.5 0.5 0.5\nv 0.5 0.2 0.2\nv 0.2 0.5 0.2\nv 0.8 0.8 0.2\n"
                                      "f 9 10 11\nf 9 10 12\nf 9 10 11\n");
  VoxelizeOptions o = unit_bounds(4, 8);
  CHECK(run(m, o).stats.fine_occupied > 0);
  o.fill = FillMode::Parity;
  const VoxelizeResult r = run(m, o);
  CHECK(r.stats.open_columns > 0);
  for (float d : r.grid.density) CHECK((d >= 0.0f && d <= 1.0f));
}

TEST_CASE("Voxeliser: same result on any thread count, padding keeps the transform", "[mesh]") {
  const TriangleMesh m = read_mesh(bush_obj_path());
  const Classification c = classify_parts(m, {}, {});
  CHECK(c.unmatched_triangles == 0);
  CHECK(c.wood_triangles > 0);
  CHECK(c.leaf_triangles > 0);
  VoxelizeOptions o;
  o.resolution = 24;
  RunContext one, two;
  one.threads = 1;
  two.threads = 2;
  const VoxelizeResult a = voxelize(m, c.part_class, o, {}, one);
  o.padding = 2;
  const VoxelizeResult b = voxelize(m, c.part_class, o, {}, two);
  CHECK(b.grid.dims == Dims{a.grid.dims.nx + 4, a.grid.dims.ny + 4, a.grid.dims.nz + 4});
  CHECK(b.grid.index_min == std::array<int, 3>{-2, -2, -2});
  CHECK(b.grid.index_to_world == a.grid.index_to_world);
  int differ = 0;
  for (int k = 0; k < a.grid.dims.nz; ++k)
    for (int j = 0; j < a.grid.dims.ny; ++j)
      for (int i = 0; i < a.grid.dims.nx; ++i) {
        const std::size_t p = a.grid.dims.index(i, j, k), q = b.grid.dims.index(i + 2, j + 2, k + 2);
        differ += a.grid.density[p] != b.grid.density[q] || a.grid.material[p] != b.grid.material[q];
      }
  CHECK(differ == 0);
  CHECK(a.stats.brown_nodes > 0);
  CHECK(a.grid.dims.longest() == 24);
}

TEST_CASE("Voxeliser and model loading stop with Cancelled once the flag is set", "[mesh]") {
  const TriangleMesh m = read_mesh(bush_obj_path());
  const Classification c = classify_parts(m, {}, {});
  std::atomic<bool> cancel{false};
  VoxelizeOptions o;
  o.resolution = 16;
  RunContext ctx;
  ctx.cancel = &cancel;
  CHECK(voxelize(m, c.part_class, o, {}, ctx).stats.occupied_nodes > 0);  // an unset flag changes nothing
  cancel = true;
  expect_error(ErrorCategory::Cancelled, [&] { voxelize(m, c.part_class, o, {}, ctx); });
  MeshSource src;
  src.path = bush_obj_path();
  src.resolution = 16;
  expect_error(ErrorCategory::Cancelled, [&] { voxelize_mesh_source(src, 0, {}, ctx); });
}

TEST_CASE("lblight voxelize writes density and brown grids that reopen with OpenVDB", "[mesh][cli]") {
  TempDir tmp;
  write_text(tmp / "box.obj", box_obj(0.1, 0.9) + "v 0.3 0.3 0.52\nv 0.7 0.3 0.52\nv 0.3 0.7 0.52\nusemtl leaves\nf 9 10 11\n");
  const CliResult r = run_cli("voxelize box.obj -r 4 --supersample 8 --bounds 0 0 0 1 1 1 -o box.vdb", tmp.path());
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  CHECK(r.out.find("13 triangles (1 leaf, 12 wood") != std::string::npos);
  const DenseGridIn d = read_vdb_grid_dense(tmp / "box.vdb", "density");
  CHECK(d.frame.dims == Dims{4, 4, 4});
  CHECK(d.frame.index_to_world[0] == Approx(0.25));
  CHECK(d.frame.index_to_world[3] == Approx(0.125));
  const int S = 8;
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i) {
        if (k == 2 && i < 3 && j < 3) continue;  // the leaf triangle adds cells here
        const int all = overlap(3, 28, i, S) * overlap(3, 28, j, S) * overlap(3, 28, k, S);
        const int inner = overlap(4, 27, i, S) * overlap(4, 27, j, S) * overlap(4, 27, k, S);
        CHECK(d.values[0][d.frame.dims.index(i, j, k)] == static_cast<float>(all - inner) / 512);
      }
  const DenseGridIn b = read_vdb_grid_dense(tmp / "box.vdb", "brown");
  CHECK(b.values[0][b.frame.dims.index(0, 0, 0)] == 1.0f);
  CHECK(b.values[0][b.frame.dims.index(1, 1, 1)] == 0.0f);  // empty node
  const nlohmann::json info = inspect_vdb(tmp / "box.vdb");
  CHECK(info["file_metadata"]["lblight_supersample"] == 8);
  CHECK(info["file_metadata"]["lblight_triangles"] == 13);
  for (const auto& g : info["grids"])
    if (g["name"] == "density") CHECK(g["class"] == "fog volume");

  // Bad input: exit code 2, a message naming the file and line, no output left behind.
  write_text(tmp / "bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 nan\nf 1 2 3\n");
  const CliResult bad = run_cli("voxelize bad.obj -o bad.vdb", tmp.path());
  CHECK(bad.exit_code == 2);
  CHECK(bad.err.find("bad.obj:3") != std::string::npos);
  CHECK_FALSE(fs::exists(tmp / "bad.vdb"));
  const CliResult missing = run_cli("voxelize nothere.obj", tmp.path());
  CHECK(missing.exit_code == 2);
  CHECK(missing.err.find("does not exist") != std::string::npos);
  // the output must be a .vdb: "-o box.obj" would have replaced the input mesh with a VDB
  const std::string mesh_before = read_text(tmp / "box.obj");
  CHECK(run_cli("voxelize box.obj -r 4 -o box.obj", tmp.path()).exit_code == 2);
  CHECK(read_text(tmp / "box.obj") == mesh_before);
  CHECK(run_cli("voxelize box.obj -r 4 -o box.txt", tmp.path()).exit_code == 2);
  // nodes narrower than OpenVDB transforms hold: an input error before any work, not a failed write
  write_text(tmp / "tiny.obj", "v 0 0 0\nv 0.001 0 0\nv 0 0.001 0\nf 1 2 3\n");
  const CliResult small = run_cli("voxelize tiny.obj -r 128 -o tiny.vdb", tmp.path());
  CHECK(small.exit_code == 2);
  CHECK(small.err.find("allowed: at least 2e-05") != std::string::npos);
  CHECK(run_cli("voxelize tiny.obj -r 32 -o tiny.vdb", tmp.path()).exit_code == 0);  // 3.1e-05 wide
  fs::remove(tmp / "tiny.vdb");
  int leftovers = 0;
  for (const auto& e : fs::directory_iterator(tmp.path())) leftovers += e.path().filename().string()[0] == '.';
  CHECK(leftovers == 0);
}

TEST_CASE("A scene's mesh source voxelises inside bake, with density_scale and errors located", "[mesh][cli]") {
  TempDir tmp;
  write_text(tmp / "plant.obj", box_obj(0.1, 0.9, "trunk_bark") + "v 0.3 0.3 0.5\nv 0.7 0.3 0.5\nv 0.3 0.7 0.5\n"
                                                                  "usemtl foliage\nf 9 10 11\n");
  const std::string scene = R"({"version": 1, "models": [{"name": "p",
      "density": {"type": "mesh", "path": "plant.obj", "resolution": 6, "supersample": 4, "density_scale": 0.5},
      "material": "leaf", "wood_material": "bark"}],
      "lighting": {"mode": "base", "solutions": "0,6"}, "solver": {"iterations": "paper"}})";
  write_text(tmp / "scene.json", scene);
  const Scene s = load_scene(tmp / "scene.json");
  const ModelGrid g = load_model_grid(s.models[0], s);
  CHECK(g.dims == Dims{6, 6, 6});
  CHECK(g.wood_nodes() > 0);
  float mx = 0;
  for (float d : g.density) mx = std::max(mx, d);
  CHECK(mx <= 0.5f);
  CHECK(g.description.find("plant.obj") != std::string::npos);
  const CliResult r = run_cli("bake scene.json -o out", tmp.path());
  INFO(r.err);
  CHECK(r.exit_code == 0);
  CHECK(fs::exists(tmp / "out" / "p.vdb"));

  write_text(tmp / "bad.json", R"({"version": 1, "models": [{"name": "p",
      "density": {"type": "mesh", "path": "nothere.obj"}, "material": "leaf"}]})");
  const CliResult bad = run_cli("bake bad.json -o out2", tmp.path());
  CHECK(bad.exit_code == 2);
  CHECK(bad.err.find("bad.json") != std::string::npos);
  CHECK(bad.err.find("/models/0/density") != std::string::npos);
  CHECK(bad.err.find("nothere.obj") != std::string::npos);
  write_text(tmp / "bad2.json", R"({"version": 1, "models": [{"name": "p",
      "density": {"type": "mesh", "path": "plant.obj", "fill": "solid"}, "material": "leaf"}]})");
  const CliResult bad2 = run_cli("validate bad2.json --no-timing", tmp.path());
  CHECK(bad2.exit_code == 2);
  CHECK(bad2.err.find("/models/0/density/fill") != std::string::npos);
}

TEST_CASE("The shipped example scenes validate", "[mesh][cli][configs]") {
  for (const char* name : {"plant.json", "dogrose.json", "pmma.json", "cloud.json", "default.json"}) {
    const CliResult r = run_cli(std::string("validate --no-timing configs/") + name, LBLIGHT_SOURCE_DIR);
    INFO(name << ": " << r.err);
    CHECK(r.exit_code == 0);
    CHECK(r.out.find("scene is valid") != std::string::npos);
  }
}
