// Branching-factor recast (Willmott 2000, sec. 5.5.1): structure, eq. 85, copied boxes, order.
#include <gtest/gtest.h>

#include <map>

#include "facetree/io.h"
#include "fch_test_util.h"

namespace facetree {
namespace {

using namespace facetree::test;

struct Recast : ::testing::TestWithParam<std::tuple<unsigned, RecastRule>> {};

TEST_P(Recast, EveryNodeIsABinaryNodeWithItsBoxAndChildrenFromItsSubtree) {
  const auto [b, rule] = GetParam();
  const TestMesh mesh = gridMesh(23, 17);
  const Hierarchy binary = medianSplitHierarchy(mesh.view());
  std::map<std::pair<uint32_t, uint32_t>, uint32_t> byRange;  // (first, count) -> binary node
  for (uint32_t i = 0; i < binary.nodes.size(); ++i)
    byRange[{binary.nodes[i].first, binary.nodes[i].count}] = i;
  FileOptions options;
  options.branching = b;
  options.rule = rule;
  BranchingStats stats;
  const ClusterFile file = makeClusterFile(mesh.view(), {}, binary, options, &stats);
  const VerifyResult result = verifyClusterFile(file);
  ASSERT_TRUE(result.ok) << result.message;
  uint32_t previousBinary = 0;
  for (size_t j = 0; j < file.nodes.size(); ++j) {
    const FchNode& node = file.nodes[j];
    const auto it = byRange.find({node.first, node.count});
    ASSERT_NE(it, byRange.end()) << "b-ary node " << j << " is not a binary node";
    const uint32_t i = it->second;
    // Boxes copied from the binary node with the same face range: exact for the b-ary node.
    EXPECT_EQ(node.box.center, binary.boxes[i].center);
    EXPECT_EQ(node.box.halfExtent, binary.boxes[i].halfExtent);
    EXPECT_EQ(node.box.orientation, binary.boxes[i].orientation);
    EXPECT_TRUE(std::equal(node.box.sideArea, node.box.sideArea + 6, binary.boxes[i].sideArea));
    EXPECT_EQ(node.area, binary.nodes[i].area);
    // Stored by binary index ascending: creation order descending.
    if (j > 0) {
      EXPECT_GT(i, previousBinary);
    }
    previousBinary = i;
    // Children: leaves of a binary subtree rooted at i, i.e. binary descendants of i.
    for (unsigned c = 0; c < node.childCount; ++c) {
      if (node.child[c] & kFaceChild) continue;
      const FchNode& child = file.nodes[node.child[c]];
      EXPECT_GT(byRange.at({child.first, child.count}), i);
    }
    EXPECT_LE(node.childCount, b);
  }
  EXPECT_EQ(stats.internalNodes, file.nodes.size());
  uint64_t histogramTotal = 0;
  for (const uint64_t count : stats.childHistogram) histogramTotal += count;
  EXPECT_EQ(histogramTotal, file.nodes.size());
  EXPECT_GE(double(stats.internalNodes), stats.eq85Nodes - 1e-9);  // eq. 85 is the lower bound
  // The shape is the same whether the file is made whole, streamed to disk, read back, or only
  // described from the hierarchy.
  EXPECT_TRUE(branchingStats(file) == stats);
  EXPECT_TRUE(branchingStats(binary, options) == stats);
  const std::filesystem::path path = scratch("shape_" + std::to_string(b) + ".fch");
  BranchingStats streamed;
  writeClusterFile(path, mesh.view(), {}, binary, options, {}, &streamed);
  EXPECT_TRUE(streamed == stats);
  EXPECT_TRUE(branchingStats(readClusterFile(path)) == stats);
  std::filesystem::remove(path);
  EXPECT_EQ(stats.balancedHeight, balancedHeight(stats.triangles, b));
}

TEST(RecastCounts, BinaryFilesSkipTheRecastTreeAndMatchIt) {
  // makeClusterFile and the streamed writer take b = 2 straight from the hierarchy; the recast
  // tree must give the same nodes: all of them, children in face order, each its own join flag.
  const TestMesh mesh = gridMesh(19, 11);
  Hierarchy binary = medianSplitHierarchy(mesh.view());
  for (size_t i = 0; i < binary.nodes.size(); ++i) {
    if (i % 3 == 1) std::swap(binary.nodes[i].child[0], binary.nodes[i].child[1]);
    if (i % 5 == 0) binary.nodes[i].flags |= kNodeJoinsDisjointSurfaces;
  }
  for (const RecastRule rule : {RecastRule::LargestArea, RecastRule::FewestNodes}) {
    FileOptions options;
    options.rule = rule;
    const ClusterFile file = makeClusterFile(mesh.view(), {}, binary, options);
    const RecastTree tree = recastHierarchy(binary, 2, rule);
    ASSERT_EQ(file.nodes.size(), tree.binaryNode.size());
    for (size_t j = 0; j < file.nodes.size(); ++j) {
      const FchNode& node = file.nodes[j];
      EXPECT_EQ(tree.binaryNode[j], j);
      ASSERT_EQ(node.childCount, tree.childCount[j]);
      EXPECT_TRUE(std::equal(node.child, node.child + 2, tree.child[j].begin())) << "node " << j;
      EXPECT_EQ((node.flags & kFchJoinsDisjointSurfaces) != 0, tree.joinFlag[j] != 0) << "node " << j;
      EXPECT_EQ((node.flags & kFchFlatFrame) != 0, (binary.nodes[j].flags & kNodeFlatFrame) != 0);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Factors, Recast,
                         ::testing::Combine(::testing::Values(2u, 3u, 4u, 8u),
                                            ::testing::Values(RecastRule::LargestArea,
                                                              RecastRule::FewestNodes)));

TEST(RecastCounts, PerfectBinaryTreesGiveEq85Exactly) {
  // 1024 = 4^5 equal-area triangles split at medians: a perfect binary tree, so the quadtree
  // recast has (n - 1) / 3 nodes, all with 4 children.
  const TestMesh mesh = gridMesh(32, 16, 0.0f);
  const Hierarchy binary = medianSplitHierarchy(mesh.view());
  ASSERT_EQ(binary.faceOrder.size(), 1024u);
  FileOptions options;
  options.branching = 4;
  BranchingStats s;
  makeClusterFile(mesh.view(), {}, binary, options, &s);
  EXPECT_EQ(s.internalNodes, 341u);
  EXPECT_DOUBLE_EQ(s.eq85Nodes, 341.0);
  EXPECT_EQ(s.childHistogram[4], 341u);
  EXPECT_EQ(s.height, 6u);  // 5 node levels + faces
  EXPECT_EQ(s.balancedHeight, 6u);
  // Binary: n - 1 nodes, heights log2.
  options.branching = 2;
  makeClusterFile(mesh.view(), {}, binary, options, &s);
  EXPECT_EQ(s.internalNodes, 1023u);
  EXPECT_EQ(s.childHistogram[2], 1023u);
  EXPECT_EQ(s.height, 11u);
  EXPECT_EQ(s.balancedHeight, 11u);
}

TEST(RecastCounts, FewestNodesNeverUsesMoreNodesThanLargestArea) {
  // 1024 = 2 * 8^3 faces: largest-area expansion ends on 512 two-face nodes; the bottom-up
  // grouping reaches far fewer.
  const TestMesh mesh = gridMesh(32, 16, 0.0f);
  const Hierarchy binary = medianSplitHierarchy(mesh.view());
  for (unsigned b : {3u, 4u, 5u, 8u}) {
    FileOptions options;
    options.branching = b;
    BranchingStats area, fewest;
    makeClusterFile(mesh.view(), {}, binary, options, &area);
    options.rule = RecastRule::FewestNodes;
    makeClusterFile(mesh.view(), {}, binary, options, &fewest);
    EXPECT_LE(fewest.internalNodes, area.internalNodes) << "b = " << b;
    // Kundu-Misra groups hold at most b - 1 binary nodes: at least ceil((n-1)/(b-1)) groups.
    EXPECT_GE(double(fewest.internalNodes), std::ceil(fewest.eq85Nodes) - 1e-9);
  }
  FileOptions options;
  options.branching = 8;
  options.rule = RecastRule::FewestNodes;
  BranchingStats s;
  makeClusterFile(mesh.view(), {}, binary, options, &s);
  EXPECT_LT(double(s.internalNodes), 1.3 * s.eq85Nodes);
}

TEST(RecastCounts, RejectsBadHierarchies) {
  const TestMesh mesh = gridMesh(4, 4);
  Hierarchy binary = medianSplitHierarchy(mesh.view());
  FileOptions options;
  options.branching = 9;
  EXPECT_THROW(makeClusterFile(mesh.view(), {}, binary, options), std::invalid_argument);
  options.branching = 4;
  binary.nodes[1].child[0] = 0;  // points back to the root
  EXPECT_THROW(makeClusterFile(mesh.view(), {}, binary, options), std::invalid_argument);
  binary = medianSplitHierarchy(mesh.view());
  binary.boxes.clear();
  EXPECT_THROW(makeClusterFile(mesh.view(), {}, binary, options), std::invalid_argument);
}

}  // namespace
}  // namespace facetree
