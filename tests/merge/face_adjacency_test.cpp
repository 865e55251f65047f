// FaceAdjacency (merge.h): the matching built once for a mesh stands in for the dual graph of any
// piece of it. Every hierarchy must be bit for bit the call on the piece's own mesh, also where the
// adjacency's factors are not the piece's (non-manifold edges cut by the piece, chains, repeated
// indices) and where the piece's origin rounds positions differently from the whole mesh's; a piece's
// statistics are its own but for the perimeter, which is the piece's as a cluster of the whole mesh.
#include <algorithm>
#include <cstring>
#include <numeric>
#include <random>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "merge/cost/face_geometry.h"
#include "merge/engine/dual_graph.h"
#include "test_meshes.h"

namespace facetree::test {
namespace {

// The faces of `mesh` in the given order as a mesh of their own (vertices renumbered by first use).
TestMesh piece(const TestMesh& mesh, const std::vector<uint32_t>& faces) {
  TestMesh out;
  std::vector<uint32_t> remap(mesh.positions.size(), ~0u);
  for (const uint32_t f : faces) {
    uint32_t v[3];
    for (int k = 0; k < 3; ++k) {
      uint32_t& id = remap[mesh.indices[3 * f + k]];
      if (id == ~0u) {
        id = uint32_t(out.positions.size());
        out.positions.push_back(mesh.positions[mesh.indices[3 * f + k]]);
      }
      v[k] = id;
    }
    out.add(v[0], v[1], v[2]);
  }
  return out;
}

// A bumpy grid far from the origin with coordinates of very different magnitudes (so that p - origin
// rounds differently for different origins), non-manifold fins on edges (3: pairwise, 20: a chain),
// faces with repeated indices, a triangle pair sharing all three edges, and a loose tetrahedron.
TestMesh awkwardMesh() {
  TestMesh mesh = grid(12, 1.0f / 12.0f);
  std::mt19937 random(5);
  std::uniform_real_distribution<float> bump(-0.05f, 0.05f);
  for (glm::vec3& p : mesh.positions) p = glm::vec3(1000.0f + p.x, p.y * 3e-7f + 1e-12f * p.x, bump(random));
  const auto fins = [&](uint32_t a, uint32_t b, uint32_t count) {
    for (uint32_t i = 0; i < count; ++i) {
      mesh.positions.push_back(mesh.positions[a] +
                               glm::vec3(0.01f * float(i), 0.02f, 0.03f + 0.001f * float(i)));
      mesh.add(a, b, uint32_t(mesh.positions.size() - 1));
    }
  };
  fins(14, 15, 2);   // 4 faces on an interior edge: pairwise
  fins(40, 41, 19);  // 21 faces: a chain
  mesh.add(50, 51, 51);
  mesh.add(60, 61, 60);
  mesh.add(70, 71, 83);
  mesh.add(70, 83, 71);
  mesh.append(tetrahedron(), glm::vec3(1003.0f, 0.0f, 0.0f));
  // Two slivers near 0, far from the rest: their edges (1e-20) vanish in p - origin about the whole
  // mesh's centre, not about their own.
  const uint32_t v = uint32_t(mesh.positions.size());
  mesh.positions.insert(mesh.positions.end(),
                        {{1e-20f, 0, 0}, {3e-20f, 1e-20f, 0}, {2e-20f, 3e-20f, 0}, {0, 2e-20f, 0}});
  mesh.add(v, v + 1, v + 2);
  mesh.add(v, v + 2, v + 3);
  return mesh;
}

// Shuffles the faces (so pieces and components interleave in face order).
TestMesh shuffled(const TestMesh& mesh, uint32_t seed) {
  std::vector<uint32_t> order(mesh.faceCount());
  std::iota(order.begin(), order.end(), 0u);
  std::shuffle(order.begin(), order.end(), std::mt19937(seed));
  return piece(mesh, order);
}

template <class T>
bool sameBytes(const T& a, const T& b) {
  return std::memcmp(&a, &b, sizeof(T)) == 0;
}

bool sameStats(const SurfaceStats& a, const SurfaceStats& b) {
  return sameBytes(a.area, b.area) && sameBytes(a.perimeter, b.perimeter) &&
         sameBytes(a.sumNormal, b.sumNormal) && sameBytes(a.firstMoment, b.firstMoment) &&
         std::memcmp(a.secondMoment, b.secondMoment, 48) == 0 && a.faceCount == b.faceCount &&
         a.height == b.height;
}

void expectSameHierarchy(const Hierarchy& a, const Hierarchy& b) {
  ASSERT_EQ(a.nodes.size(), b.nodes.size());
  ASSERT_EQ(a.boxes.size(), b.boxes.size());
  EXPECT_EQ(a.faceOrder, b.faceOrder);
  for (size_t i = 0; i < a.nodes.size(); ++i) EXPECT_TRUE(sameBytes(a.nodes[i], b.nodes[i])) << "node " << i;
  for (size_t i = 0; i < a.boxes.size(); ++i) EXPECT_TRUE(sameBytes(a.boxes[i], b.boxes[i])) << "box " << i;
  EXPECT_EQ(a.stats.height, b.stats.height);
  EXPECT_EQ(a.stats.components, b.stats.components);
}

TEST(FaceAdjacency, WholeMeshGivesTheDualGraphBitForBit) {
  for (const uint32_t seed : {0u, 1u, 2u}) {
    const TestMesh mesh = seed == 0 ? awkwardMesh() : shuffled(awkwardMesh(), seed);
    FaceAdjacency adjacency = buildFaceAdjacency(mesh.view());
    const FaceGeometry geometry(mesh.view());
    const DualGraph expected = buildDualGraph(geometry);
    std::vector<uint32_t> all(mesh.faceCount());
    std::iota(all.begin(), all.end(), 0u);
    const std::optional<DualGraph> graph = pieceDualGraph(geometry, adjacency, all);
    ASSERT_TRUE(graph.has_value());
    ASSERT_EQ(graph->edges.size(), expected.edges.size());
    EXPECT_EQ(graph->head, expected.head);
    for (size_t e = 0; e < expected.edges.size(); ++e)
      EXPECT_TRUE(sameBytes(graph->edges[e], expected.edges[e]));
    // Each dual edge is one link from each end, lists ascending.
    uint64_t links = 0;
    for (uint32_t f = 0; f < adjacency.faceCount(); ++f) {
      const std::span<const FaceAdjacency::Link> l = adjacency.links(f);
      links += l.size();
      EXPECT_TRUE(std::is_sorted(l.begin(), l.end(), [](auto& a, auto& b) { return a.face < b.face; }));
    }
    EXPECT_EQ(links, 2 * expected.edges.size());
    EXPECT_EQ(adjacency.edgeCount(), expected.edges.size());
  }
}

TEST(FaceAdjacency, ComponentsAreFaceComponents) {
  for (const uint32_t seed : {0u, 3u}) {
    const TestMesh mesh = seed == 0 ? awkwardMesh() : shuffled(awkwardMesh(), seed);
    const FaceAdjacency adjacency = buildFaceAdjacency(mesh.view());
    std::vector<uint32_t> expected, label;
    const uint32_t count = faceComponents(mesh.view(), expected);
    EXPECT_EQ(faceComponents(adjacency, label), count);
    EXPECT_EQ(label, expected);
    EXPECT_GE(count, 2u);
  }
}

// Groups of components in increasing face order (what the out-of-core cells build): the hierarchy
// and the statistics are the piece's own, bit for bit.
TEST(FaceAdjacency, ComponentGroupsBuildThePiecesOwnHierarchy) {
  TestMesh mesh = awkwardMesh();
  mesh.append(icosphere(1), glm::vec3(1000.0f, 5.0f, 0.0f));
  mesh.append(strip(9), glm::vec3(1000.0f, -5.0f, 0.0f));
  mesh = shuffled(mesh, 7);
  FaceAdjacency adjacency = buildFaceAdjacency(mesh.view());
  std::vector<uint32_t> label;
  const uint32_t count = faceComponents(adjacency, label);
  ASSERT_GE(count, 4u);
  // Each component alone, then all but component 0 together.
  for (uint32_t group = 0; group <= count; ++group) {
    std::vector<uint32_t> faces;
    for (uint32_t f = 0; f < mesh.faceCount(); ++f)
      if (group < count ? label[f] == group : label[f] != 0) faces.push_back(f);
    const TestMesh part = piece(mesh, faces);
    expectSameHierarchy(buildHierarchy(part.view(), adjacency, faces), buildHierarchy(part.view()));
    const glm::dvec3 origin(1000.25, 0.5, 0.0);
    EXPECT_TRUE(
        sameStats(surfaceStats(part.view(), adjacency, faces, origin), surfaceStats(part.view(), origin)));
  }
}

// The adjacency's shares among `faces` (both ends in the set), summed in double.
double sharedWithin(const TestMesh& mesh, const FaceAdjacency& adjacency, const std::vector<uint8_t>& in) {
  double shared = 0;
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) {
    if (!in[f]) continue;
    for (const FaceAdjacency::Link& link : adjacency.links(f)) {
      if (link.face < f || !in[link.face]) continue;
      for (const FaceAdjacency::Share& share : adjacency.shares(link.edge)) {
        const glm::dvec3 a(mesh.positions[mesh.indices[3 * f + share.corner]]);
        const glm::dvec3 b(mesh.positions[mesh.indices[3 * f + (share.corner + 1) % 3]]);
        shared += share.of(glm::length(b - a));
      }
    }
  }
  return shared;
}

double trianglePerimeters(const TestMesh& mesh, const std::vector<uint32_t>& faces) {
  double sum = 0;
  for (const uint32_t f : faces)
    for (int k = 0; k < 3; ++k)
      sum += glm::length(glm::dvec3(mesh.positions[mesh.indices[3 * f + k]]) -
                         glm::dvec3(mesh.positions[mesh.indices[3 * f + (k + 1) % 3]]));
  return sum;
}

// Any piece, in any order (leaf clusters come in hierarchy order): the sums are the piece's own, bit
// for bit, and the perimeter is the piece's as a cluster of the whole mesh: its triangles' perimeters
// minus twice the adjacency's shares among them, also where it cuts non-manifold edges and chains.
TEST(FaceAdjacency, AnyPieceIsAClusterOfTheWholeMesh) {
  const TestMesh mesh = shuffled(awkwardMesh(), 9);
  FaceAdjacency adjacency = buildFaceAdjacency(mesh.view());
  std::mt19937 random(13);
  const glm::dvec3 origin(1000.5, 0.25, 0.0);
  int differsFromOwn = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const uint32_t want = 1 + random() % mesh.faceCount();
    // Half the trials: a spatially coherent piece (faces near a random face), else scattered.
    std::vector<uint32_t> order(mesh.faceCount());
    std::iota(order.begin(), order.end(), 0u);
    if (trial % 2 == 0) {
      const glm::vec3 seed = mesh.positions[mesh.indices[3 * (random() % mesh.faceCount())]];
      const auto distance = [&](uint32_t f) {
        return glm::length(mesh.positions[mesh.indices[3 * f]] - seed);
      };
      std::stable_sort(order.begin(), order.end(),
                       [&](uint32_t a, uint32_t b) { return distance(a) < distance(b); });
      order.resize(want);
      std::shuffle(order.begin(), order.end(), random);
    } else {
      std::shuffle(order.begin(), order.end(), random);
      order.resize(want);
    }
    const std::vector<uint32_t>& faces = order;
    const TestMesh part = piece(mesh, faces);
    SurfaceStats got = surfaceStats(part.view(), adjacency, faces, origin);
    const SurfaceStats own = surfaceStats(part.view(), origin);
    std::vector<uint8_t> in(mesh.faceCount(), 0);
    for (const uint32_t f : faces) in[f] = 1;
    const double expected =
        std::max(0.0, trianglePerimeters(mesh, faces) - 2.0 * sharedWithin(mesh, adjacency, in));
    // The shares are the engine's floats, per pair of faces.
    EXPECT_NEAR(got.perimeter, expected, 1e-6 * trianglePerimeters(mesh, faces)) << "trial " << trial;
    differsFromOwn += got.perimeter != own.perimeter;
    got.perimeter = own.perimeter;
    EXPECT_TRUE(sameStats(got, own)) << "trial " << trial;
    if (trial % 20 == 0)
      expectSameHierarchy(buildHierarchy(part.view(), adjacency, faces), buildHierarchy(part.view()));
  }
  EXPECT_GT(differsFromOwn, 0);  // some pieces cut a non-manifold edge: the case this is for
}

// Pieces that partition the mesh, with the adjacency's shares between them, add up to the whole
// mesh's perimeter, however they cut its non-manifold edges: what the merge above out-of-core leaf
// clusters starts from.
TEST(FaceAdjacency, PiecesAndTheirSharesAddUpToTheWholePerimeter) {
  const TestMesh mesh = shuffled(awkwardMesh(), 4);
  FaceAdjacency adjacency = buildFaceAdjacency(mesh.view());
  const glm::dvec3 origin(1000.5, 0.25, 0.0);
  const double whole = surfaceStats(mesh.view(), origin).perimeter;
  std::mt19937 random(21);
  for (const uint32_t pieces : {2u, 5u, 17u, 60u}) {
    std::vector<uint32_t> label(mesh.faceCount());
    for (uint32_t& l : label) l = random() % pieces;
    double sum = 0, sharedInside = 0;
    for (uint32_t p = 0; p < pieces; ++p) {
      std::vector<uint32_t> faces;
      std::vector<uint8_t> in(mesh.faceCount(), 0);
      for (uint32_t f = 0; f < mesh.faceCount(); ++f)
        if (label[f] == p) faces.push_back(f), in[f] = 1;
      sum += surfaceStats(piece(mesh, faces).view(), adjacency, faces, origin).perimeter;
      sharedInside += sharedWithin(mesh, adjacency, in);
    }
    const std::vector<uint8_t> all(mesh.faceCount(), 1);
    const double between = sharedWithin(mesh, adjacency, all) - sharedInside;
    EXPECT_NEAR(sum - 2.0 * between, whole, 1e-6 * whole) << pieces << " pieces";
  }
}

// Two faces on the same three vertices share three manifold edges; the piece's graph sums their
// lengths in the order of its lower face's corners, which need not be the adjacency's: the hierarchy
// is still the piece's own, and the perimeter the same but for that rounding.
TEST(FaceAdjacency, TrianglePairsSumInThePiecesOrder) {
  // A triangle whose edge lengths (as the dual graph rounds them) sum differently in float in the
  // two corner orders.
  std::mt19937 random(3);
  std::uniform_real_distribution<float> coordinate(0.0f, 1.0f);
  // A third triangle spans the box [0, 1]^3: the pair's origin is the same in every piece.
  TestMesh mesh;
  mesh.indices = {0, 1, 2, 0, 2, 1, 3, 4, 5};
  for (;;) {
    mesh.positions.clear();
    for (int i = 0; i < 3; ++i)
      mesh.positions.push_back({coordinate(random), coordinate(random), coordinate(random)});
    mesh.positions.insert(mesh.positions.end(), {{0, 0, 0}, {1, 1, 1}, {1, 0, 0}});
    const FaceGeometry geometry(mesh.view());
    const auto length = [&](int a, int b) {
      return float(glm::length(geometry.position(a) - geometry.position(b)));
    };
    const float l0 = length(0, 1), l1 = length(1, 2), l2 = length(2, 0);
    if (0.0f + l0 + l1 + l2 != 0.0f + l2 + l1 + l0) break;
  }
  FaceAdjacency adjacency = buildFaceAdjacency(mesh.view());
  const glm::dvec3 origin(0.5);
  for (const std::vector<uint32_t>& faces :
       {std::vector<uint32_t>{0, 1, 2}, std::vector<uint32_t>{1, 0, 2}}) {
    const TestMesh part = piece(mesh, faces);
    expectSameHierarchy(buildHierarchy(part.view(), adjacency, faces), buildHierarchy(part.view()));
    SurfaceStats got = surfaceStats(part.view(), adjacency, faces, origin);
    const SurfaceStats own = surfaceStats(part.view(), origin);
    EXPECT_NEAR(got.perimeter, own.perimeter, 1e-6 * (1.0 + own.perimeter));
    got.perimeter = own.perimeter;
    EXPECT_TRUE(sameStats(got, own));
  }
}

TEST(FaceAdjacency, RejectsFacesThatAreNotThePiecesAndStaysUsable) {
  const TestMesh mesh = awkwardMesh();
  FaceAdjacency adjacency = buildFaceAdjacency(mesh.view());
  const TestMesh part = piece(mesh, {0, 1, 2});
  const glm::dvec3 origin(0.0);
  const std::vector<uint32_t> repeated = {0, 1, 0}, outside = {0, 1, mesh.faceCount()}, short_ = {0, 1};
  for (const auto* faces : {&repeated, &outside, &short_}) {
    EXPECT_THROW(surfaceStats(part.view(), adjacency, *faces, origin), std::invalid_argument);
    EXPECT_THROW(buildHierarchy(part.view(), adjacency, *faces), std::invalid_argument);
  }
  EXPECT_THROW(surfaceStats(TestMesh{}.view(), adjacency, short_, origin), std::invalid_argument);
  // The failed calls left no face marked: the right faces still give the piece's own results.
  const std::vector<uint32_t> faces = {0, 1, 2};
  EXPECT_TRUE(
      sameStats(surfaceStats(part.view(), adjacency, faces, origin), surfaceStats(part.view(), origin)));
  expectSameHierarchy(buildHierarchy(part.view(), adjacency, faces), buildHierarchy(part.view()));
  EXPECT_TRUE(sameStats(surfaceStats(TestMesh{}.view(), adjacency, {}, origin), SurfaceStats{}));
  // An empty mesh has an empty adjacency; invalid indices are refused as buildHierarchy refuses them.
  EXPECT_EQ(buildFaceAdjacency(TestMesh{}.view()).faceCount(), 0u);
  TestMesh bad = grid(1);
  bad.indices[4] = 99;
  EXPECT_THROW(buildFaceAdjacency(bad.view()), std::invalid_argument);
}

}  // namespace
}  // namespace facetree::test
