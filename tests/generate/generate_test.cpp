// The generator's meshes, read back through the stream readers.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <map>
#include <set>
#include <tuple>
#include <vector>

#include <glm/geometric.hpp>

#include "facetree/generate.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/stream.h"

namespace facetree {
namespace {

std::filesystem::path scratch(const std::string& name) {
  return std::filesystem::temp_directory_path() / ("facetree_gen_" + std::to_string(::getpid()) + "_" + name);
}

IndexedMesh readBack(const std::filesystem::path& path) {
  auto reader = openMesh(path);
  return loadMesh(*reader);
}

using PositionTriangle = std::array<float, 9>;

// Triangles by their corner positions, each rotated to start at its smallest corner, sorted.
std::vector<PositionTriangle> canonicalTriangles(const IndexedMesh& mesh) {
  std::vector<PositionTriangle> result;
  for (size_t t = 0; t < mesh.indices.size() / 3; ++t) {
    std::array<std::tuple<float, float, float>, 3> c;
    for (int k = 0; k < 3; ++k) {
      const glm::vec3 p = mesh.positions[mesh.indices[3 * t + k]];
      c[k] = {p.x, p.y, p.z};
    }
    const int first = static_cast<int>(std::min_element(c.begin(), c.end()) - c.begin());
    PositionTriangle out;
    for (int k = 0; k < 3; ++k) std::tie(out[3 * k], out[3 * k + 1], out[3 * k + 2]) = c[(first + k) % 3];
    result.push_back(out);
  }
  std::sort(result.begin(), result.end());
  return result;
}

// Every undirected index edge with the number of triangles using it.
std::map<std::pair<uint32_t, uint32_t>, int> edgeUse(const IndexedMesh& mesh) {
  std::map<std::pair<uint32_t, uint32_t>, int> use;
  for (size_t t = 0; t < mesh.indices.size() / 3; ++t)
    for (int k = 0; k < 3; ++k) {
      uint32_t a = mesh.indices[3 * t + k], b = mesh.indices[3 * t + (k + 1) % 3];
      ++use[{std::min(a, b), std::max(a, b)}];
    }
  return use;
}

double totalArea(const IndexedMesh& mesh) {
  double area = 0;
  for (size_t t = 0; t < mesh.indices.size() / 3; ++t) {
    const glm::dvec3 a(mesh.positions[mesh.indices[3 * t]]), b(mesh.positions[mesh.indices[3 * t + 1]]),
        c(mesh.positions[mesh.indices[3 * t + 2]]);
    area += 0.5 * glm::length(glm::cross(b - a, c - a));
  }
  return area;
}

TEST(Generate, FlatGridHasTheExactCountsAndFileSize) {
  const auto path = scratch("grid.ply");
  GenerateOptions options;
  options.triangles = 20000;  // 100 x 100 quads
  const GeneratedCounts counts = writeSyntheticMesh(SyntheticKind::Grid, options, path);
  EXPECT_EQ(counts.vertices, 101u * 101u);
  EXPECT_EQ(counts.triangles, 20000u);
  const IndexedMesh mesh = readBack(path);
  EXPECT_EQ(mesh.positions.size(), counts.vertices);
  EXPECT_EQ(mesh.indices.size(), 3 * counts.triangles);
  EXPECT_EQ(mesh.stats.degenerateTriangles, 0u);
  for (const glm::vec3& p : mesh.positions) ASSERT_EQ(p.z, 0.0f);
  // Interior edges are shared by two triangles, the border's 4*100 edges by one.
  int border = 0;
  for (const auto& [edge, use] : edgeUse(mesh)) {
    ASSERT_LE(use, 2);
    border += use == 1;
  }
  EXPECT_EQ(border, 400);
  EXPECT_NEAR(totalArea(mesh), 1000.0 * 1000.0, 1e-3);
  std::filesystem::remove(path);
}

TEST(Generate, StripIsOneRowOfSquareCells) {
  const auto path = scratch("strip.ply");
  GenerateOptions options;
  options.triangles = 1000;  // 500 cells
  const GeneratedCounts counts = writeSyntheticMesh(SyntheticKind::Strip, options, path);
  EXPECT_EQ(counts.vertices, 2u * 501u);
  EXPECT_EQ(counts.triangles, 1000u);
  const IndexedMesh mesh = readBack(path);
  EXPECT_EQ(mesh.stats.degenerateTriangles, 0u);
  // Border: 2 x 500 long sides and the 2 ends; every cell is (1000/500)^2 square.
  int border = 0;
  for (const auto& [edge, use] : edgeUse(mesh)) {
    ASSERT_LE(use, 2);
    border += use == 1;
  }
  EXPECT_EQ(border, 1002);
  EXPECT_NEAR(totalArea(mesh), 500 * 2.0 * 2.0, 1e-6);
  std::filesystem::remove(path);
}

TEST(Generate, ShuffledMeshesHoldTheSameTriangles) {
  GenerateOptions options;
  options.triangles = 5000;
  const auto plain = scratch("plain.ply"), shuffled = scratch("shuffled.ply");
  for (const SyntheticKind kind :
       {SyntheticKind::Grid, SyntheticKind::Sphere, SyntheticKind::Terrain, SyntheticKind::Strip}) {
    options.shuffleVertices = options.shuffleFaces = false;
    writeSyntheticMesh(kind, options, plain);
    options.shuffleVertices = options.shuffleFaces = true;
    writeSyntheticMesh(kind, options, shuffled);
    const IndexedMesh a = readBack(plain), b = readBack(shuffled);
    EXPECT_NE(a.indices, b.indices);
    EXPECT_EQ(canonicalTriangles(a), canonicalTriangles(b));
  }
  std::filesystem::remove(plain);
  std::filesystem::remove(shuffled);
}

TEST(Generate, SphereIsClosedAndManifold) {
  const auto path = scratch("sphere.ply");
  GenerateOptions options;
  options.triangles = 4000;
  const GeneratedCounts counts = writeSyntheticMesh(SyntheticKind::Sphere, options, path);
  const IndexedMesh mesh = readBack(path);
  const auto use = edgeUse(mesh);
  for (const auto& [edge, n] : use) ASSERT_EQ(n, 2);
  // Euler characteristic of a sphere.
  EXPECT_EQ(static_cast<int64_t>(counts.vertices) - static_cast<int64_t>(use.size()) +
                static_cast<int64_t>(counts.triangles),
            2);
  std::filesystem::remove(path);
}

TEST(Generate, AssemblyIsEighteenClosedBoxesWithTheirTouchingFacesStoredTwice) {
  const auto path = scratch("assembly.ply");
  GenerateOptions options;
  options.triangles = 18 * 12 * 16;  // boxes of 4 x 4 cells a side
  const GeneratedCounts counts = writeSyntheticMesh(SyntheticKind::Assembly, options, path);
  EXPECT_EQ(counts.triangles, 18u * 12 * 16);
  const IndexedMesh mesh = readBack(path);
  // Every box closed and manifold, oriented outwards (every directed edge once), a sphere each.
  const auto use = edgeUse(mesh);
  for (const auto& [edge, n] : use) ASSERT_EQ(n, 2);
  std::set<std::pair<uint32_t, uint32_t>> directed;
  for (size_t t = 0; t < mesh.indices.size() / 3; ++t)
    for (int k = 0; k < 3; ++k)
      EXPECT_TRUE(directed.insert({mesh.indices[3 * t + k], mesh.indices[3 * t + (k + 1) % 3]}).second);
  EXPECT_EQ(static_cast<int64_t>(counts.vertices) - static_cast<int64_t>(use.size()) +
                static_cast<int64_t>(counts.triangles),
            2 * 18);
  // Touching boxes store their shared faces both: in each group 10 contacts (7 in the block of 3 x
  // 2, 2 under the two on top, 1 between them) of 4 x 4 cells, 2 triangles each.
  // (The two boxes face opposite ways: the same corners in the other turn.)
  std::vector<PositionTriangle> triangles = canonicalTriangles(mesh);
  for (PositionTriangle& t : triangles) {
    std::array<std::array<float, 3>, 3> c{{{t[0], t[1], t[2]}, {t[3], t[4], t[5]}, {t[6], t[7], t[8]}}};
    std::sort(c.begin(), c.end());
    for (int k = 0; k < 9; ++k) t[k] = c[k / 3][k % 3];
  }
  std::sort(triangles.begin(), triangles.end());
  size_t twice = 0;
  for (size_t i = 0; i + 1 < triangles.size(); ++i) twice += triangles[i] == triangles[i + 1];
  EXPECT_EQ(twice, 2u * 10 * 16 * 2);
  // Two groups far apart: no triangle between x = 5 and x = 25.
  for (const glm::vec3& p : mesh.positions) EXPECT_TRUE(p.x < 5.0f || p.x > 25.0f);
  std::filesystem::remove(path);
}

TEST(Generate, TiledScanIsEightyOneTilesOfUnweldedPiecesOnTheTerrain) {
  const auto path = scratch("tiled.ply");
  GenerateOptions options;
  options.triangles = 200000;  // tiles of 35 cells: room for up to four islands
  const GeneratedCounts counts = writeSyntheticMesh(SyntheticKind::TiledScan, options, path);
  const IndexedMesh mesh = readBack(path);
  ASSERT_EQ(mesh.indices.size(), 3 * counts.triangles);
  // 81 tiles of 6 to 11 pieces, each a grid of cells: a disc (V - E + F = 1), its edges used
  // once on its border and twice inside, and no vertex shared with another piece.
  std::vector<uint32_t> label;
  const uint32_t pieces = faceComponents(mesh.view(), label);
  EXPECT_GE(pieces, 81u * 6);
  EXPECT_LE(pieces, 81u * 11);
  EXPECT_GT(pieces, 81u * 7);  // islands vary from tile to tile
  const auto use = edgeUse(mesh);
  for (const auto& [edge, n] : use) ASSERT_TRUE(n == 1 || n == 2);
  EXPECT_EQ(static_cast<int64_t>(counts.vertices) - static_cast<int64_t>(use.size()) +
                static_cast<int64_t>(counts.triangles),
            int64_t{pieces});
  std::vector<uint32_t> pieceOf(mesh.positions.size(), UINT32_MAX);
  for (size_t t = 0; t < label.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      uint32_t& p = pieceOf[mesh.indices[3 * t + k]];
      ASSERT_TRUE(p == UINT32_MAX || p == label[t]);
      p = label[t];
    }
  // The pieces meet along their seams (the same positions stored by each), except around the holes
  // and islands: fewer distinct positions than vertices, and the terrain's heights throughout.
  std::set<std::array<float, 3>> distinct;
  for (const glm::vec3& p : mesh.positions) {
    distinct.insert({p.x, p.y, p.z});
    ASSERT_TRUE(p.x >= 0 && p.x <= 1000 && p.y >= 0 && p.y <= 1000 && p.z >= 0 && p.z <= 120);
  }
  EXPECT_LT(distinct.size(), mesh.positions.size());
  // Holes: fewer triangles than the whole grid of the same side would have.
  const uint64_t side = static_cast<uint64_t>(std::llround(std::sqrt(double(mesh.positions.size()))));
  EXPECT_LT(counts.triangles, 2 * side * side);
  std::filesystem::remove(path);
}

TEST(Generate, SubdivisionKeepsTheSurfaceAndItsTopology) {
  // A tetrahedron: closed, so the subdivision must be closed too.
  const std::vector<glm::vec3> positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const std::vector<uint32_t> indices = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2};
  for (unsigned levels : {1u, 2u, 3u}) {
    const auto path = scratch("subdivided.ply");
    GenerateOptions options;
    options.shuffleFaces = levels == 3;
    const GeneratedCounts counts = writeSubdividedMesh({positions, indices}, levels, options, path);
    const uint64_t s = uint64_t{1} << levels;
    EXPECT_EQ(counts.triangles, 4 * s * s);
    EXPECT_EQ(counts.vertices, 4 + 6 * (s - 1) + 4 * (s - 1) * (s - 2) / 2);
    const IndexedMesh mesh = readBack(path);
    const auto use = edgeUse(mesh);
    for (const auto& [edge, n] : use) ASSERT_EQ(n, 2) << "levels " << levels;
    EXPECT_EQ(static_cast<int64_t>(counts.vertices) - static_cast<int64_t>(use.size()) +
                  static_cast<int64_t>(counts.triangles),
              2);
    EXPECT_NEAR(totalArea(mesh), 1.5 + std::sqrt(3.0) / 2, 1e-5);
    EXPECT_EQ(mesh.stats.degenerateTriangles, 0u);
    std::filesystem::remove(path);
  }
}

TEST(Generate, ZeroTrianglesIsRejected) {
  GenerateOptions options;
  options.triangles = 0;
  EXPECT_THROW(writeSyntheticMesh(SyntheticKind::Grid, options, scratch("none.ply")), std::invalid_argument);
  EXPECT_FALSE(std::filesystem::exists(scratch("none.ply")));
}

}  // namespace
}  // namespace facetree
