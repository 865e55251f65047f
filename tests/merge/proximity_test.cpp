// The top of the tree over separate pieces: proximity candidates by box gap (merge/top/proximity.cpp)
// against brute force, and the joins they give in both merge orders: far groups split at the root,
// tiles that share no vertex grouped into quadrants, touching parts joined before apart ones.
#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "merge/top/proximity.h"
#include "test_meshes.h"

namespace facetree::test {
namespace {

// The k nearest of another label by (gap^2, centre distance^2, index), by brute force.
std::vector<uint32_t> bruteNearest(const std::vector<AxisBox>& boxes, const std::vector<uint32_t>& label,
                                   uint32_t q, uint32_t k) {
  struct Entry {
    double gap, centre;
    uint32_t index;
  };
  std::vector<Entry> all;
  for (uint32_t j = 0; j < boxes.size(); ++j) {
    if (label[j] == label[q] || boxes[j].empty()) continue;
    const glm::vec3 d = boxes[j].centre() - boxes[q].centre();
    const double centre = double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z;
    all.push_back({squaredBoxGap(boxes[q], boxes[j]), centre, j});
  }
  std::sort(all.begin(), all.end(), [](const Entry& a, const Entry& b) {
    return std::tie(a.gap, a.centre, a.index) < std::tie(b.gap, b.centre, b.index);
  });
  std::vector<uint32_t> out;
  for (size_t i = 0; i < std::min<size_t>(k, all.size()); ++i) out.push_back(all[i].index);
  return out;
}

TEST(NearestPairs, AreEveryBoxsNearestOfAnotherLabelAsBruteForceFindsThem) {
  std::mt19937 random(5);
  std::uniform_real_distribution<float> size(0.0f, 4.0f);
  // Spread out, and crowded: there most boxes overlap (gap 0) and the centres' distances decide.
  for (const auto& [labels, span] : {std::pair{2u, 100.0f}, {7u, 100.0f}, {1000u, 100.0f}, {7u, 10.0f}}) {
    std::uniform_real_distribution<float> at(0.0f, span);
    std::vector<AxisBox> boxes(600);
    std::vector<uint32_t> label(boxes.size());
    for (uint32_t i = 0; i < boxes.size(); ++i) {
      const glm::vec3 lo(at(random), at(random), i % 3 == 0 ? 0.0f : at(random));  // ties in z
      boxes[i] = {lo, lo + glm::vec3(size(random), size(random), size(random))};
      label[i] = i % 5 == 0 ? 0 : random() % labels;  // one large piece and smaller ones
    }
    boxes[17] = AxisBox{};  // empty: no candidates
    const uint32_t k = 3;
    const std::vector<std::pair<uint32_t, uint32_t>> pairs = nearestPairs(boxes, label, k);
    // The proposals by brute force; a box accepts the 2k nearest proposers.
    std::vector<std::vector<std::pair<double, uint32_t>>> proposedTo(boxes.size());
    std::set<std::pair<uint32_t, uint32_t>> want;
    std::vector<std::vector<uint32_t>> nearest(boxes.size());
    for (uint32_t q = 0; q < boxes.size(); ++q) {
      if (boxes[q].empty()) continue;
      nearest[q] = bruteNearest(boxes, label, q, k);
    }
    for (uint32_t b = 0; b < boxes.size(); ++b) {
      if (boxes[b].empty()) continue;
      // b's proposers in b's own order of them.
      std::vector<uint32_t> proposers;
      for (uint32_t q = 0; q < boxes.size(); ++q)
        if (std::find(nearest[q].begin(), nearest[q].end(), b) != nearest[q].end()) proposers.push_back(q);
      const std::vector<uint32_t> order = bruteNearest(boxes, label, b, uint32_t(boxes.size()));
      uint32_t accepted = 0;
      for (const uint32_t q : order) {
        if (accepted == 2 * k) break;
        if (std::find(proposers.begin(), proposers.end(), q) == proposers.end()) continue;
        want.insert(std::minmax(b, q));
        ++accepted;
      }
    }
    const std::set<std::pair<uint32_t, uint32_t>> got(pairs.begin(), pairs.end());
    EXPECT_EQ(got, want) << labels << " labels over " << span;
    EXPECT_TRUE(std::is_sorted(pairs.begin(), pairs.end()));
    for (const auto& [a, b] : pairs) {
      EXPECT_LT(a, b);
      EXPECT_NE(label[a], label[b]);
      EXPECT_TRUE(a != 17 && b != 17);
    }
  }
}

// The faces under each child of the root, as sets of input faces.
std::vector<std::vector<uint32_t>> rootChildren(const Hierarchy& h) {
  std::vector<std::vector<uint32_t>> out;
  for (const uint32_t c : h.nodes[0].child) {
    const uint32_t first = (c & kFaceChild) ? (c & ~kFaceChild) : h.nodes[c].first;
    const uint32_t count = (c & kFaceChild) ? 1 : h.nodes[c].count;
    out.emplace_back(h.faceOrder.begin() + first, h.faceOrder.begin() + first + count);
    std::sort(out.back().begin(), out.back().end());
  }
  return out;
}

// The clusters of the cut after the first `kept` nodes (the frontier a truncated file keeps).
std::vector<std::vector<uint32_t>> cutClusters(const Hierarchy& h, uint32_t kept) {
  std::vector<std::vector<uint32_t>> out;
  for (uint32_t j = 0; j < kept; ++j) {
    for (const uint32_t c : h.nodes[j].child) {
      if (!(c & kFaceChild) && c < kept) continue;
      const uint32_t first = (c & kFaceChild) ? (c & ~kFaceChild) : h.nodes[c].first;
      const uint32_t count = (c & kFaceChild) ? 1 : h.nodes[c].count;
      out.emplace_back(h.faceOrder.begin() + first, h.faceOrder.begin() + first + count);
    }
  }
  return out;
}

// The hierarchy of `mesh` with boxes, its structure checked and its nodes flagged exactly where
// the children share no mesh edge.
Hierarchy connectedBuild(const TestMesh& mesh, const BuildOptions& options) {
  Hierarchy h = buildHierarchy(mesh.view(), options);
  const Layout layout = checkStructure(h, mesh.faceCount());
  checkConnectivity(h, mesh, layout);
  return h;
}

// The hierarchy of `mesh` in `order`, without boxes, its structure checked.
Hierarchy checkedBuild(const TestMesh& mesh, MergeOrder order) {
  BuildOptions options = noBoxes();
  options.order = order;
  Hierarchy h = buildHierarchy(mesh.view(), options);
  checkStructure(h, mesh.faceCount());
  return h;
}

// A closed box surface of 6 n^2 quads (12 n^2 triangles) over [lo, hi], its own vertices per side.
TestMesh boxSurface(glm::vec3 lo, glm::vec3 hi, uint32_t n) {
  TestMesh mesh;
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const uint32_t base = static_cast<uint32_t>(mesh.positions.size());
      for (uint32_t j = 0; j <= n; ++j) {
        for (uint32_t i = 0; i <= n; ++i) {
          glm::vec3 p;
          p[axis] = side ? hi[axis] : lo[axis];
          p[u] = lo[u] + (hi[u] - lo[u]) * float(i) / float(n);
          p[v] = lo[v] + (hi[v] - lo[v]) * float(j) / float(n);
          mesh.positions.push_back(p);
        }
      }
      for (uint32_t j = 0; j < n; ++j) {
        for (uint32_t i = 0; i < n; ++i) {
          const uint32_t a = base + j * (n + 1) + i;
          if (side) {
            mesh.add(a, a + 1, a + n + 2);
            mesh.add(a, a + n + 2, a + n + 1);
          } else {
            mesh.add(a, a + n + 2, a + 1);
            mesh.add(a, a + n + 1, a + n + 2);
          }
        }
      }
    }
  }
  return mesh;
}

TEST(Proximity, TwoGroupsOfPartsFarApartAreTheRootsChildren) {
  TestMesh mesh;
  std::vector<uint8_t> group;
  const auto add = [&](const TestMesh& part, glm::vec3 at, uint8_t g) {
    mesh.append(part, at);
    group.resize(mesh.faceCount(), g);
  };
  for (const uint8_t g : {0, 1}) {
    const glm::vec3 origin = g ? glm::vec3(200, 30, 0) : glm::vec3(0);
    add(icosphere(2), origin, g);
    add(grid(6, 0.5f), origin + glm::vec3(2, -1, -1), g);
    add(boxSurface(glm::vec3(0), glm::vec3(1, 2, 1), 3), origin + glm::vec3(-3, 0, 0), g);
    add(tetrahedron(), origin + glm::vec3(0, 3, 0), g);
  }
  for (const MergeOrder order : {MergeOrder::Rounds, MergeOrder::Exact}) {
    SCOPED_TRACE(int(order));
    const Hierarchy h = checkedBuild(mesh, order);
    EXPECT_EQ(h.stats.components, 18u);  // a box's six sides have their own vertices
    for (const std::vector<uint32_t>& faces : rootChildren(h)) {
      ASSERT_FALSE(faces.empty());
      for (const uint32_t f : faces) EXPECT_EQ(group[f], group[faces[0]]);
      EXPECT_EQ(faces.size(), mesh.faceCount() / 2);
    }
  }
}

TEST(Proximity, TilesSharingNoVertexGroupIntoQuadrants) {
  // A flat terrain in 4 x 4 tiles of 8 x 8 cells, each tile its own vertices.
  constexpr uint32_t kTiles = 4, kCells = 8;
  TestMesh mesh;
  std::vector<uint8_t> quadrant;
  for (uint32_t ty = 0; ty < kTiles; ++ty) {
    for (uint32_t tx = 0; tx < kTiles; ++tx) {
      TestMesh tile = grid(kCells);
      for (glm::vec3& p : tile.positions) {
        p += glm::vec3(float(tx * kCells), float(ty * kCells), 0.0f);
      }
      mesh.append(tile);
      quadrant.resize(mesh.faceCount(), uint8_t((ty / 2) * 2 + tx / 2));
    }
  }
  for (const MergeOrder order : {MergeOrder::Rounds, MergeOrder::Exact}) {
    SCOPED_TRACE(int(order));
    const Hierarchy h = checkedBuild(mesh, order);
    EXPECT_EQ(h.stats.components, kTiles * kTiles);
    const std::vector<std::vector<uint32_t>> cut = cutClusters(h, 3);
    ASSERT_EQ(cut.size(), 4u);
    std::set<uint8_t> seen;
    for (const std::vector<uint32_t>& faces : cut) {
      EXPECT_EQ(faces.size(), mesh.faceCount() / 4);
      for (const uint32_t f : faces) EXPECT_EQ(quadrant[f], quadrant[faces[0]]);
      seen.insert(quadrant[faces[0]]);
    }
    EXPECT_EQ(seen.size(), 4u);
  }
}

TEST(Proximity, PartsThatTouchJoinBeforePartsThatDoNot) {
  // Three boxes in a row: the first two touch along x = 1, where both store the face (as CAD
  // assemblies do); the third stands 3 units off. A fourth lies on top of the third.
  TestMesh mesh;
  std::vector<uint8_t> part;
  const auto add = [&](glm::vec3 lo, glm::vec3 hi, uint8_t p) {
    mesh.append(boxSurface(lo, hi, 4));
    part.resize(mesh.faceCount(), p);
  };
  add(glm::vec3(0, 0, 0), glm::vec3(1, 1, 1), 0);
  add(glm::vec3(1, 0, 0), glm::vec3(2, 1, 1), 1);
  add(glm::vec3(5, 0, 0), glm::vec3(6, 1, 1), 2);
  add(glm::vec3(5, 0, 1), glm::vec3(6, 1, 2), 3);
  for (const MergeOrder order : {MergeOrder::Rounds, MergeOrder::Exact}) {
    SCOPED_TRACE(int(order));
    BuildOptions options;
    options.order = order;
    const Hierarchy h = connectedBuild(mesh, options);
    checkStats(h, mesh, 1e-5);
    ASSERT_EQ(h.boxes.size(), h.nodes.size());
    // The root joins the touching pairs {0, 1} and {2, 3}.
    for (const std::vector<uint32_t>& faces : rootChildren(h)) {
      ASSERT_EQ(faces.size(), mesh.faceCount() / 2);
      for (const uint32_t f : faces) EXPECT_EQ(part[f] / 2, part[faces[0]] / 2);
    }
  }
}

TEST(Top, TilesJoinTheCoplanarTilesThatAddNoFitErrorRatherThanTheirNeighbours) {
  // 2 x 2 flat tiles of 16 x 16 cells, 1 apart, their own vertices; the diagonal pairs share a
  // plane, the neighbours stand 2 apart in height. Eq. 84 joins the coplanar diagonal pairs, and so
  // does the top: their union adds nothing to the sum of area x eFit, a neighbour's a step.
  constexpr uint32_t kCells = 16;
  TestMesh mesh;
  std::vector<uint8_t> tile;
  for (uint32_t ty = 0; ty < 2; ++ty) {
    for (uint32_t tx = 0; tx < 2; ++tx) {
      mesh.append(grid(kCells),
                  glm::vec3(float(tx * (kCells + 1)), float(ty * (kCells + 1)), 2.0f * float((tx + ty) % 2)));
      tile.resize(mesh.faceCount(), uint8_t(ty * 2 + tx));
    }
  }
  const auto rootPairs = [&](const Hierarchy& h) {
    std::set<std::set<uint8_t>> pairs;
    for (const std::vector<uint32_t>& faces : rootChildren(h)) {
      std::set<uint8_t> tiles;
      for (const uint32_t f : faces) tiles.insert(tile[f]);
      pairs.insert(tiles);
    }
    return pairs;
  };
  const std::set<std::set<uint8_t>> diagonal = {{0, 3}, {1, 2}};
  for (const MergeOrder order : {MergeOrder::Rounds, MergeOrder::Exact}) {
    SCOPED_TRACE(int(order));
    BuildOptions options;
    options.order = order;
    ASSERT_GE(std::min<uint64_t>(options.topClusters, mesh.faceCount() / kTopFaces), 4u);
    EXPECT_EQ(rootPairs(connectedBuild(mesh, options)), diagonal);
    options.topClusters = 0;
    EXPECT_EQ(rootPairs(buildHierarchy(mesh.view(), options)), diagonal);
  }
}

}  // namespace
}  // namespace facetree::test
