// The merge in rounds of reciprocal cheapest pairs (merge/engine/merge_rounds.cpp): a round on a hand-made
// mesh whose merges are known, the greedy's hand-over, and the same bytes for every thread count.
#include <cstring>
#include <vector>

#include <gtest/gtest.h>

#include "facetree/merge.h"
#include "test_meshes.h"

namespace facetree::test {
namespace {

BuildOptions rounds(Metric metric = Metric::Willmott) {
  BuildOptions options = noBoxes(metric);
  options.order = MergeOrder::Rounds;
  return options;
}

BuildOptions exactOrder(Metric metric = Metric::Willmott) {
  BuildOptions options = noBoxes(metric);
  options.order = MergeOrder::Exact;
  return options;
}

// The faces below a child reference, as input face ids.
std::vector<uint32_t> facesOf(const Hierarchy& h, uint32_t child) {
  if (child & kFaceChild) return {h.faceOrder[child & ~kFaceChild]};
  const Node& node = h.nodes[child];
  std::vector<uint32_t> faces(h.faceOrder.begin() + node.first,
                              h.faceOrder.begin() + node.first + node.count);
  std::sort(faces.begin(), faces.end());
  return faces;
}

void expectSameNodes(const Hierarchy& a, const Hierarchy& b) {
  ASSERT_EQ(a.nodes.size(), b.nodes.size());
  EXPECT_EQ(a.faceOrder, b.faceOrder);
  for (size_t i = 0; i < a.nodes.size(); ++i) {
    EXPECT_EQ(a.nodes[i].child[0], b.nodes[i].child[0]) << "node " << i;
    EXPECT_EQ(a.nodes[i].child[1], b.nodes[i].child[1]) << "node " << i;
    EXPECT_EQ(a.nodes[i].count, b.nodes[i].count) << "node " << i;
    EXPECT_EQ(a.nodes[i].flags, b.nodes[i].flags) << "node " << i;
  }
}

// Two unit squares side by side, two triangles each: A = faces 0, 1 and B = faces 2, 3. The dual
// graph is the path 1 - 0 - 3 - 2. Flat clusters cost k perim^2 (eq. 84 with eFit = 0): a square
// 16k, the parallelogram of faces 0 and 3 (4 + 2 sqrt 2)^2 k = 23.3k. So faces 0 and 1 are each
// other's cheapest edge, and so are 3 and 2: both squares merge in the first round, and the
// rectangle in the second.
TEST(MergeRounds, ReciprocalPairsOfARoundMergeTogether) {
  TestMesh mesh;
  for (float y : {0.0f, 1.0f})
    for (float x : {0.0f, 1.0f, 2.0f}) mesh.positions.emplace_back(x, y, 0.0f);
  mesh.add(0, 1, 4);  // A
  mesh.add(0, 4, 3);
  mesh.add(1, 2, 5);  // B
  mesh.add(1, 5, 4);
  const Hierarchy h = buildHierarchy(mesh.view(), rounds());
  checkStructure(h, 4);
  checkEffectiveCostOrder(h);
  EXPECT_EQ(h.stats.rounds, 2u);  // both pairs at once, then the two clusters
  EXPECT_EQ(h.stats.components, 1u);
  ASSERT_EQ(h.nodes.size(), 3u);
  const Node& root = h.nodes[0];
  EXPECT_EQ(root.flags, 0u);
  std::vector<std::vector<uint32_t>> children = {facesOf(h, root.child[0]), facesOf(h, root.child[1])};
  std::sort(children.begin(), children.end());
  EXPECT_EQ(children, (std::vector<std::vector<uint32_t>>{{0, 1}, {2, 3}}));
  const double k = BuildOptions{}.k;
  for (int c = 0; c < 2; ++c) EXPECT_NEAR(h.nodes[root.child[c]].cost, 16 * k, 1e-9);
  EXPECT_NEAR(root.cost, 36 * k, 1e-9);  // the 2 x 1 rectangle: perimeter 6
  EXPECT_NEAR(root.perimeter, 6.0f, 1e-6);
}

// Disjoint pieces: each square merges in round one, then the greedy joins the two.
TEST(MergeRounds, ComponentsLeftWhenTheEdgesRunOutAreJoined) {
  TestMesh mesh = grid(1);
  mesh.append(grid(1), glm::vec3(5, 0, 0));
  const Hierarchy h = buildHierarchy(mesh.view(), rounds());
  checkStructure(h, 4);
  EXPECT_EQ(h.stats.rounds, 1u);
  EXPECT_EQ(h.stats.components, 2u);
  ASSERT_EQ(h.nodes.size(), 3u);
  EXPECT_EQ(h.nodes[0].flags, uint32_t{kNodeJoinsDisjointSurfaces});
  EXPECT_EQ(h.nodes[1].count, 2u);
  EXPECT_EQ(h.nodes[2].count, 2u);
}

// With every merge costing the same, ties go to the lower ids: along a chain only the first two
// clusters are each other's cheapest, one pair a round, which is the greedy's own order (a
// reducible cost: the rounds give exactly the greedy's tree).
TEST(MergeRounds, ConstantCostChainIsTheGreedyChain) {
  const TestMesh mesh = strip(24);
  const Hierarchy h = buildHierarchy(mesh.view(), rounds(Metric::Constant));
  checkStructure(h, 24);
  EXPECT_EQ(h.stats.rounds, 18u);  // down to 24 / 4 clusters, then the greedy
  expectSameNodes(h, buildHierarchy(mesh.view(), exactOrder(Metric::Constant)));
}

// A chain of thousands merges one pair a round: the rounds stall at once and the exact greedy
// does the whole merge.
TEST(MergeRounds, StalledRoundsHandTheMergeToTheGreedy) {
  const TestMesh mesh = strip(4000);
  const Hierarchy h = buildHierarchy(mesh.view(), rounds(Metric::Constant));
  checkStructure(h, 4000);
  EXPECT_EQ(h.stats.rounds, 0u);
  expectSameNodes(h, buildHierarchy(mesh.view(), exactOrder(Metric::Constant)));
}

// A flat fan of 96 triangles, each with a steep ear on its outer edge: the fan merges first, into
// clusters bordering dozens of ears, whose lists fold parallel edges past the short-list scan.
// The balance guard then blocks the last ears: the pieces it leaves are joined with the shared
// length of the edges between them, and are not flagged as disjoint. Every node's area,
// perimeter and S against brute force, both orders.
TEST(MergeRounds, LongListsFoldAndGuardBlockedPiecesJoinAlongTheirEdges) {
  TestMesh mesh;
  constexpr uint32_t kSpokes = 96;
  mesh.positions.emplace_back(0.0f, 0.0f, 0.0f);
  for (uint32_t i = 0; i < kSpokes; ++i) {
    const float angle = 6.2831853f * float(i) / kSpokes;
    mesh.positions.emplace_back(std::cos(angle), std::sin(angle), 0.0f);
  }
  for (uint32_t i = 0; i < kSpokes; ++i) {
    const float angle = 6.2831853f * (float(i) + 0.5f) / kSpokes;
    mesh.positions.emplace_back(1.05f * std::cos(angle), 1.05f * std::sin(angle), 0.8f);
  }
  for (uint32_t i = 0; i < kSpokes; ++i) mesh.add(0, 1 + i, 1 + (i + 1) % kSpokes);
  for (uint32_t i = 0; i < kSpokes; ++i) mesh.add(1 + (i + 1) % kSpokes, 1 + i, 1 + kSpokes + i);
  for (const MergeOrder order : {MergeOrder::Rounds, MergeOrder::Exact}) {
    SCOPED_TRACE(int(order));
    BuildOptions options = rounds();
    options.order = order;
    const Hierarchy h = buildHierarchy(mesh.view(), options);
    const Layout layout = checkStructure(h, mesh.faceCount());
    checkConnectivity(h, mesh, layout);  // a node is flagged a join exactly where its children share no edge
    checkStats(h, mesh, 1e-5);
    EXPECT_EQ(h.stats.components, 1u);  // the pieces the guard blocks are of one connected mesh
    if (order == MergeOrder::Rounds) {
      EXPECT_GE(h.stats.maxDegree, 32u);  // twice the lists the contraction scans
    }
  }
}

// Several blocks of clusters (4096 each) and every metric: the same nodes, faces and boxes,
// bit for bit, whatever the number of threads.
TEST(MergeRounds, SameBytesForEveryThreadCount) {
  TestMesh mesh = icosphere(5);                      // 20480 faces
  mesh.append(grid(64, 0.05f), glm::vec3(0, 0, 2));  // 8192 more, a second component
  for (const Metric metric : {Metric::Willmott, Metric::Garland, Metric::Constant}) {
    SCOPED_TRACE(int(metric));
    BuildOptions options = rounds(metric);
    options.computeBoxes = true;
    options.threads = 1;
    const Hierarchy one = buildHierarchy(mesh.view(), options);
    EXPECT_GT(one.stats.rounds, 0u);
    for (const unsigned threads : {2u, 3u}) {
      options.threads = threads;
      const Hierarchy many = buildHierarchy(mesh.view(), options);
      ASSERT_EQ(many.nodes.size(), one.nodes.size());
      ASSERT_EQ(many.boxes.size(), one.boxes.size());
      EXPECT_EQ(many.faceOrder, one.faceOrder);
      EXPECT_EQ(std::memcmp(many.nodes.data(), one.nodes.data(), one.nodes.size() * sizeof(Node)), 0);
      EXPECT_EQ(std::memcmp(many.boxes.data(), one.boxes.data(), one.boxes.size() * sizeof(NodeBox)), 0);
      EXPECT_EQ(many.stats.rounds, one.stats.rounds);
    }
  }
}

}  // namespace
}  // namespace facetree::test
