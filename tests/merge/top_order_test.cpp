// The file's first nodes (merge/top/top_order.cpp): they go first, each above every other node and
// below its parent; the open node whose expansion removes the most fit goes next, also from below
// the top; a split that adds fit goes first where the best few expansions under it remove more
// (not the next best gains one at a time), unless it puts a cluster without surface in the cut;
// the cut's boxes keep to their limit; the tree itself is unchanged.
#include <algorithm>
#include <numeric>
#include <vector>

#include <gtest/gtest.h>

#include "merge/top/top_order.h"

namespace facetree::test {
namespace {

// A hand-made tree: each cluster's "fit" is carried in its perimeter (the test's areaFit), its
// box is a cube of the given side at the given x.
struct Tree {
  std::vector<SurfaceStats> leaves;
  std::vector<ClusterMergeNode> nodes;

  static SurfaceStats stats(double fit, double area, float x, float side) {
    SurfaceStats s;
    s.perimeter = fit;
    s.area = area;
    s.faceCount = 1;
    s.boundsMin = glm::vec3(x, 0, 0);
    s.boundsMax = glm::vec3(x + side, side, side);
    return s;
  }
  uint32_t leaf(double fit, float x = 0, float side = 1) {
    leaves.push_back(stats(fit, 1, x, side));
    return kLeafChild | static_cast<uint32_t>(leaves.size() - 1);
  }
  uint32_t node(uint32_t a, uint32_t b, double fit, float cost, double area = 1, float x = 0,
                float side = 1) {
    ClusterMergeNode n{};
    n.child[0] = a;
    n.child[1] = b;
    n.cost = cost;
    n.stats = stats(fit, area, x, side);
    nodes.push_back(n);
    return static_cast<uint32_t>(nodes.size() - 1);
  }
  // The nodes in the file's order: decreasing cost, ties to the later node.
  std::vector<uint32_t> fileOrder() const {
    std::vector<uint32_t> order(nodes.size());
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](uint32_t x, uint32_t y) {
      return nodes[x].cost != nodes[y].cost ? nodes[x].cost > nodes[y].cost : x > y;
    });
    return order;
  }
};

uint32_t order(Tree& tree, uint32_t firstTop, std::span<const double> boxLimit = {},
               uint32_t orderedCuts = 64, uint32_t keptCuts = 0, float leavesCost = 0) {
  TopTree top{tree.nodes, tree.leaves, firstTop, 0.5, boxLimit, orderedCuts, keptCuts, leavesCost};
  return orderTop(top, [](const SurfaceStats& s) { return s.perimeter; });
}

void expectParentsFirst(const Tree& tree, const std::vector<uint32_t>& file) {
  std::vector<size_t> at(tree.nodes.size());
  for (size_t p = 0; p < file.size(); ++p) at[file[p]] = p;
  for (uint32_t i = 0; i < tree.nodes.size(); ++i)
    for (const uint32_t child : tree.nodes[i].child)
      if (!(child & kLeafChild)) {
        EXPECT_LT(at[i], at[child]) << "node " << i;
        EXPECT_GT(tree.nodes[i].cost, tree.nodes[child].cost) << "node " << i;
      }
}

TEST(TopOrder, TheSplitThatRemovesMostFitGoesFirstAlsoFromBelowTheTop) {
  // Below the top: node 0 (its split removes 50). The top: 1 (removes 2), 2 = 0 + a leaf
  // (removes 3), the root 3 = 1 + 2 (removes 145). Node 0 goes before the top's node 1.
  Tree t;
  const uint32_t below = t.node(t.leaf(0), t.leaf(0), 50, 5.0f);
  const uint32_t small = t.node(t.leaf(0), t.leaf(0), 2, 1.0f);
  const uint32_t above = t.node(below, t.leaf(0), 53, 2.0f);
  const uint32_t root = t.node(small, above, 200, 3.0f);
  EXPECT_EQ(order(t, 1), 4u);
  const std::vector<uint32_t> file = t.fileOrder();
  EXPECT_EQ(file, (std::vector<uint32_t>{root, above, below, small}));
  expectParentsFirst(t, file);
}

TEST(TopOrder, ASplitThatAddsFitGoesFirstWhereItOpensOneThatRemovesMore) {
  // The root's children: node 1 (splitting it adds 2, then its child 0 removes 40) and node 2
  // (removes 10). Without looking ahead, node 2 would go first.
  Tree t;
  const uint32_t inner = t.node(t.leaf(0), t.leaf(0), 40, 3.0f);
  const uint32_t adds = t.node(inner, t.leaf(0), 38, 4.0f);
  const uint32_t plain = t.node(t.leaf(0), t.leaf(0), 10, 9.0f);
  const uint32_t root = t.node(adds, plain, 100, 1.0f);
  EXPECT_EQ(order(t, 1), 4u);
  EXPECT_EQ(t.fileOrder(), (std::vector<uint32_t>{root, adds, inner, plain}));
}

TEST(TopOrder, TheLookaheadFindsTheBestExpansionsNotTheNextBestGains) {
  // Node P adds 1, and so does its child N, above M, which removes 40; P's other child S heads a
  // chain of splits that remove 0.5 each. Q removes 5. Following the best gain open, 8 expansions
  // from P go down S's chain and average 0.31; the best 3 (P, N, M) average 12.7, so P goes before Q.
  Tree t;
  const uint32_t m = t.node(t.leaf(0), t.leaf(0), 40, 1.0f);
  const uint32_t n = t.node(m, t.leaf(0), 39, 1.0f);
  uint32_t chain = t.node(t.leaf(0), t.leaf(0), 0.5, 1.0f);
  for (int i = 2; i <= 8; ++i) chain = t.node(chain, t.leaf(0), 0.5 * i, 1.0f);
  const uint32_t p = t.node(chain, n, 4 + 39 - 1, 2.0f);
  const uint32_t q = t.node(t.leaf(0), t.leaf(0), 5, 2.0f);
  const uint32_t root = t.node(p, q, 100, 3.0f);
  order(t, p);
  const std::vector<uint32_t> file = t.fileOrder();
  EXPECT_EQ(std::vector<uint32_t>(file.begin(), file.begin() + 5), (std::vector<uint32_t>{root, p, n, m, q}));
  expectParentsFirst(t, file);
}

TEST(TopOrder, ASplitThatPutsASurfacelessClusterInTheCutIsNotLookedThrough) {
  // As above, but node 1 is the top's merge of node 0 with a degenerate face (no area): splitting
  // it adds nothing to the cut but a cluster without surface, so node 2 (removes 10) goes first.
  Tree t;
  const uint32_t inner = t.node(t.leaf(0), t.leaf(0), 40, 3.0f);
  t.leaves.push_back(Tree::stats(0, 0, 0, 1));
  const uint32_t peels = t.node(inner, kLeafChild | uint32_t(t.leaves.size() - 1), 40, 4.0f);
  const uint32_t plain = t.node(t.leaf(0), t.leaf(0), 10, 9.0f);
  const uint32_t root = t.node(peels, plain, 100, 1.0f);
  EXPECT_EQ(order(t, 1), 4u);
  EXPECT_EQ(t.fileOrder(), (std::vector<uint32_t>{root, plain, peels, inner}));
}

TEST(TopOrder, TheCutsBoxesKeepToTheirLimit) {
  // Node 0's split removes the most fit, but its children's boxes are its own twice over; node
  // 1's removes less and shrinks its box (6 x 10^2) to two of 6 x 1^2. The cut of 2 holds
  // 1200: node 0 first makes the cut of 3 hold 1800, node 1 first 612.
  for (const bool limited : {true, false}) {
    Tree t;
    const uint32_t spreads = t.node(t.leaf(0, 0, 10), t.leaf(0, 0, 10), 50, 5.0f, 1, 0, 10);
    const uint32_t keeps = t.node(t.leaf(0, 100, 1), t.leaf(0, 105, 1), 10, 6.0f, 1, 100, 10);
    const uint32_t root = t.node(spreads, keeps, 100, 1.0f, 1, 0, 110);
    const std::vector<double> limit{0, 0, 1e9, 1000, 1e9};
    EXPECT_EQ(order(t, 0, limited ? std::span<const double>(limit) : std::span<const double>()), 3u);
    EXPECT_EQ(t.fileOrder(), limited ? (std::vector<uint32_t>{root, keeps, spreads})
                                     : (std::vector<uint32_t>{root, spreads, keeps}));
  }
}

TEST(TopOrder, PlacedNodesGoAboveEveryOtherAndTheTreeIsUnchanged) {
  // A chain below the top with costs above the top's own: the top and the nodes placed with it
  // still open the file, and only costs change.
  Tree t;
  uint32_t below = t.node(t.leaf(0), t.leaf(0), 1, 900.0f);
  for (int i = 0; i < 6; ++i) below = t.node(below, t.leaf(0), 2.0 + i, 1000.0f + float(i));
  const uint32_t firstTop = static_cast<uint32_t>(t.nodes.size());
  uint32_t top = t.node(below, t.leaf(0), 20, 1.0f);
  top = t.node(top, t.leaf(0), 30, 2.0f);
  const std::vector<ClusterMergeNode> before = t.nodes;
  const uint32_t placed = order(t, firstTop, {}, 3);
  EXPECT_GE(placed, 2u);
  const std::vector<uint32_t> file = t.fileOrder();
  EXPECT_EQ(file[0], top);
  EXPECT_EQ(file[1], top - 1);
  expectParentsFirst(t, file);
  float others = 0;
  for (size_t p = placed; p < file.size(); ++p) others = std::max(others, t.nodes[file[p]].cost);
  for (size_t p = 0; p < placed; ++p) EXPECT_GT(t.nodes[file[p]].cost, others);
  for (size_t i = 0; i < before.size(); ++i) {
    EXPECT_EQ(t.nodes[i].child[0], before[i].child[0]);
    EXPECT_EQ(t.nodes[i].child[1], before[i].child[1]);
    EXPECT_EQ(t.nodes[i].stats.perimeter, before[i].stats.perimeter);
    if (std::find(file.begin(), file.begin() + placed, uint32_t(i)) == file.begin() + placed) {
      EXPECT_EQ(t.nodes[i].cost, before[i].cost) << "node " << i << " is not placed";
    }
  }
}

TEST(TopOrder, PastTheOrderedCutsTheTopKeepsItsOwnOrder) {
  // Node 1 (removes 1, then node 0 below it 100) scores above node 2 (removes 30): ordered, the
  // file opens root, 1, 0, 2. With one ordered cut, the top's nodes left follow in reverse merge
  // order (2, then 1) and node 0 keeps its own cost.
  for (const uint32_t orderedCuts : {64u, 1u}) {
    Tree t;
    const uint32_t below = t.node(t.leaf(0), t.leaf(0), 100, 5.0f);
    const uint32_t first = t.node(below, t.leaf(0), 101, 1.0f);
    const uint32_t second = t.node(t.leaf(0), t.leaf(0), 30, 2.0f);
    const uint32_t root = t.node(first, second, 200, 3.0f);
    if (orderedCuts > 1) {
      EXPECT_EQ(order(t, 1, {}, orderedCuts), 4u);
      EXPECT_EQ(t.fileOrder(), (std::vector<uint32_t>{root, first, below, second}));
    } else {
      EXPECT_EQ(order(t, 1, {}, orderedCuts), 3u);
      EXPECT_EQ(t.fileOrder(), (std::vector<uint32_t>{root, second, first, below}));
      EXPECT_EQ(t.nodes[below].cost, 5.0f);
      EXPECT_EQ(t.nodes[second].cost, t.nodes[first].cost);
    }
    expectParentsFirst(t, t.fileOrder());
  }
}

TEST(TopOrder, PlacedNodesGoAboveTheLeavesOwnNodes) {
  // The leaves' own hierarchies (the rounds' records, a cell's nodes) hold costs up to 5000: the
  // placed nodes go above them too, so that no leaf's subtree lifts one of them out of order.
  Tree t;
  const uint32_t a = t.node(t.leaf(0), t.leaf(0), 10, 3.0f);
  const uint32_t b = t.node(t.leaf(0), t.leaf(0), 20, 4.0f);
  const uint32_t root = t.node(a, b, 100, 1.0f);
  EXPECT_EQ(order(t, 0, {}, 64, 0, 5000.0f), 3u);
  EXPECT_EQ(t.fileOrder(), (std::vector<uint32_t>{root, b, a}));
  for (const ClusterMergeNode& node : t.nodes) EXPECT_GT(node.cost, 5000.0f);
}

TEST(TopOrder, NothingWithoutATop) {
  Tree t;
  const uint32_t a = t.node(t.leaf(0), t.leaf(0), 1, 3.0f);
  t.node(a, t.leaf(0), 2, 4.0f);
  const std::vector<ClusterMergeNode> before = t.nodes;
  EXPECT_EQ(order(t, 2), 0u);
  for (size_t i = 0; i < before.size(); ++i) EXPECT_EQ(t.nodes[i].cost, before[i].cost);
  Tree empty;
  EXPECT_EQ(order(empty, 0), 0u);
}

}  // namespace
}  // namespace facetree::test
