// The file's node order for both merge orders: every invariant verify checks (ranges, parents,
// boxes containment and tightness, areas and side areas) on the whole file and on truncated
// prefixes, nodes by decreasing effective cost, and the rounds' cuts against the exact greedy's.
#include <gtest/gtest.h>

#include <vector>

#include "facetree/grid.h"
#include "facetree/stream.h"
#include "fch_test_util.h"
#include "sanitizers.h"

namespace facetree {
namespace {

using namespace facetree::test;

ClusterFile fileOf(const TestMesh& mesh, MergeOrder order, Metric metric = Metric::Willmott) {
  BuildOptions options;
  options.order = order;
  options.metric = metric;
  return makeClusterFile(mesh.view(), {}, buildHierarchy(mesh.view(), options), FileOptions{});
}

// A terrain patch: a 2:1 grid over a few octaves of bumps, its faces in scan order.
TestMesh terrain(int w, int h) {
  TestMesh m = gridMesh(w, h, 0.0f);
  for (glm::vec3& p : m.positions)
    p.z = 2.0f * std::sin(0.21f * p.x) * std::cos(0.17f * p.y) + 0.5f * std::sin(0.9f * p.x + 0.4f * p.y) +
          0.1f * std::cos(2.3f * p.y);
  return m;
}

TestMesh disjointPieces() {
  TestMesh m = terrain(40, 20);
  m.append(icosphere(3), glm::vec3(20, 10, 6));
  m.append(gridMesh(10, 10, 0.5f), glm::vec3(50, 0, 0));
  return m;
}

std::vector<float> effectiveCosts(const ClusterFile& file) {
  std::vector<float> effective(file.nodes.size());
  for (size_t i = file.nodes.size(); i-- > 0;) {
    const FchNode& node = file.nodes[i];
    float e = node.cost;
    for (uint32_t k = 0; k < node.childCount; ++k)
      if (!(node.child[k] & kFaceChild) && !file.isCutOff(node.child[k]))
        e = std::max(e, effective[node.child[k]]);
    effective[i] = e;
  }
  return effective;
}

TEST(NodeOrder, BothOrdersGiveVerifiedFilesAndPrefixesByDecreasingEffectiveCost) {
  for (const TestMesh& mesh : {terrain(60, 40), icosphere(4), disjointPieces()}) {
    for (const MergeOrder order : {MergeOrder::Rounds, MergeOrder::Exact}) {
      for (const Metric metric : {Metric::Willmott, Metric::Garland}) {
        SCOPED_TRACE(::testing::Message()
                     << mesh.faceCount() << " faces, order " << int(order) << ", metric " << int(metric));
        const ClusterFile file = fileOf(mesh, order, metric);
        const VerifyResult whole = verifyClusterFile(file);
        EXPECT_TRUE(whole.ok) << whole.message;
        EXPECT_EQ(whole.nodesChecked, file.nodes.size());
        const std::vector<float> effective = effectiveCosts(file);
        for (size_t i = 1; i < effective.size(); ++i)
          ASSERT_LE(effective[i], effective[i - 1]) << "node " << i;
        for (const uint64_t keep : {uint64_t{1}, uint64_t{7}, uint64_t{file.nodes.size() / 3}}) {
          ClusterFile prefix = file;
          truncateInMemory(prefix, keep);
          const VerifyResult cut = verifyClusterFile(prefix);
          EXPECT_TRUE(cut.ok) << keep << " nodes: " << cut.message;
        }
      }
    }
  }
}

// The rounds approximate the greedy order (eq. 84 is not reducible): the fit of their cuts stays
// within 5% of the exact greedy's, or better.
TEST(NodeOrder, RoundsCutsFitLikeTheExactGreedys) {
  for (const TestMesh& mesh : {terrain(160, 80), icosphere(5), disjointPieces()}) {
    const ClusterFile rounds = fileOf(mesh, MergeOrder::Rounds);
    const ClusterFile exact = fileOf(mesh, MergeOrder::Exact);
    for (const uint64_t clusters : {uint64_t{mesh.faceCount() / 100}, uint64_t{mesh.faceCount() / 10}}) {
      const CutFit r = cutFit(rounds, clusters), e = cutFit(exact, clusters);
      SCOPED_TRACE(::testing::Message() << mesh.faceCount() << " faces, cut of " << clusters << ": rounds "
                                        << r.sumAreaFit << ", exact " << e.sumAreaFit);
      EXPECT_EQ(r.clusters, e.clusters);
      EXPECT_LE(r.sumAreaFit, 1.05 * e.sumAreaFit);
    }
  }
}

// The same on shared meshes (scans and CAD, dirty as published), at cuts of 1,000 clusters.
TEST(NodeOrder, RoundsCutsFitLikeTheExactGreedysOnSharedMeshes) {
  SKIP_SHARED_MESH_QUALITY_UNDER_SANITIZERS();
  for (const char* name : {"fandisk", "gears_cad", "bunny_zipper", "horse_97k"}) {
    auto reader = openMesh(std::filesystem::path(FACETREE_SHARED_DATA) / (std::string(name) + ".ply.zst"));
    const IndexedMesh mesh = loadMesh(*reader);
    const MeshView view = mesh.view();
    BuildOptions options;
    const ClusterFile rounds = makeClusterFile(view, {}, buildHierarchy(view, options), FileOptions{});
    options.order = MergeOrder::Exact;
    const ClusterFile exact = makeClusterFile(view, {}, buildHierarchy(view, options), FileOptions{});
    const CutFit r = cutFit(rounds, 1000), e = cutFit(exact, 1000);
    SCOPED_TRACE(::testing::Message() << name << ": rounds " << r.sumAreaFit << ", exact " << e.sumAreaFit);
    EXPECT_LE(r.sumAreaFit, 1.05 * e.sumAreaFit);
  }
}

}  // namespace
}  // namespace facetree
