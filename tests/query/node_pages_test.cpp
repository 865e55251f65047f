// A reader's query pages (query/node_pages.h): every node is found from its parent's reference,
// with the fields the file holds, through small pages and top chunks, on whole and truncated files
// of b = 2, 4 and 8; the cache stays within its budget; a reader's queries through one index give
// the hits of the file in memory batch after batch.
#include <gtest/gtest.h>

#include <random>

#include "facetree/grid.h"
#include "facetree/query.h"
#include "merge/test_meshes.h"
#include "query/node_pages.h"
#include "query_test_util.h"

namespace facetree {
namespace {

// Walks the file's tree from the root through the pages, every node reached from its parent's
// reference, and compares each with the file in memory. Returns the nodes reached.
size_t expectEveryNodeFound(query::NodePages& pages, const ClusterFile& file) {
  std::vector<query::NodeRef> todo = {pages.root()};
  size_t reached = 0;
  while (!todo.empty()) {
    const query::NodeRef ref = todo.back();
    todo.pop_back();
    const query::NodePages::Page page = pages.page(pages.pageOf(ref));
    const FchNode got = pages.find(*page, ref);
    const FchNode& want = file.nodes[ref.index];
    EXPECT_EQ(got.first, want.first) << ref.index;
    EXPECT_EQ(got.count, want.count) << ref.index;
    EXPECT_EQ(ref.first, want.first) << ref.index;
    EXPECT_EQ(ref.count, want.count) << ref.index;
    EXPECT_EQ(got.flags, want.flags) << ref.index;
    EXPECT_EQ(got.box.center, want.box.center) << ref.index;
    EXPECT_EQ(got.box.halfExtent, want.box.halfExtent) << ref.index;
    EXPECT_EQ(got.box.orientation, want.box.orientation) << ref.index;
    EXPECT_EQ(got.childCount, want.childCount) << ref.index;
    uint32_t cursor = want.first;
    for (unsigned c = 0; c < want.childCount; ++c) {
      EXPECT_EQ(got.child[c], want.child[c]) << ref.index;
      EXPECT_EQ(got.childFaces[c], want.childFaces[c]) << ref.index;
      if (!(want.child[c] & kFaceChild) && !file.isCutOff(want.child[c]))
        todo.push_back({want.child[c], cursor, want.childFaces[c]});
      cursor += want.childFaces[c];
    }
    ++reached;
  }
  return reached;
}

TEST(NodePages, EveryNodeIsFoundFromItsParentThroughSmallPagesOnWholeAndTruncatedFiles) {
  const IndexedMesh mesh = test::loadShared("fandisk.ply.zst");
  for (const unsigned branching : {2u, 4u, 8u}) {
    const BoxPrecision boxes = branching == 4 ? BoxPrecision::Compact : BoxPrecision::Exact;
    const ClusterFile file = test::fileOf(mesh.view(), branching, boxes);
    test::TemporaryFiles files;
    const auto path = files.add("pages.fch"), cut = files.add("pages.cut.fch");
    WriteOptions write;
    write.nodesPerFrame = 64;
    writeClusterFile(path, file, write);
    truncateClusterFile(path, cut, file.nodes.size() / 7);
    for (const auto& onDisk : {path, cut}) {
      SCOPED_TRACE(onDisk.string() + ", b = " + std::to_string(branching));
      const ClusterFile whole = readClusterFile(onDisk);
      ClusterFileReader reader(onDisk, ReaderOptions{256 << 10, {}});
      constexpr uint64_t kBudget = 64 << 10;
      // Pages of at most 16 faces and top chunks of 8 records: hundreds of each.
      query::NodePages pages(reader, kBudget, 16, 8);
      EXPECT_EQ(pages.nodeCount(), whole.nodes.size());
      EXPECT_EQ(expectEveryNodeFound(pages, whole), whole.nodes.size());
      // Every triangle's corners and original id, block by block.
      const uint64_t faces = whole.indices.size() / 3;
      ASSERT_EQ(pages.faceCount(), faces);
      for (uint64_t p = 0; p < faces; ++p) {
        const query::NodePages::Page block = pages.block(p / query::NodePages::kBlockTriangles);
        glm::vec3 corner[3];
        query::NodePages::corners(*block, p, corner);
        for (int c = 0; c < 3; ++c) ASSERT_EQ(corner[c], whole.vertices[whole.indices[3 * p + c]]) << p;
        ASSERT_EQ(query::NodePages::originalFace(*block, p), whole.originalFace[p]) << p;
      }
      EXPECT_THROW(pages.block(faces / query::NodePages::kBlockTriangles + 1), Error);
      // Written: records of 56 + 8 b bytes, 44 bytes a triangle.
      EXPECT_EQ(pages.temporaryBytes(), whole.nodes.size() * (56 + 8 * branching) + faces * 44);
      // The cache within its budget but for the entry that came last (a block of 44 KiB).
      EXPECT_GT(pages.peakBytes(), 0u);
      EXPECT_LE(pages.peakBytes(), kBudget + query::NodePages::kBlockTriangles * 44 + 4096);
      // The default pages: the same nodes.
      query::NodePages defaults(reader, kBudget);
      EXPECT_EQ(expectEveryNodeFound(defaults, whole), whole.nodes.size());
    }
  }
}

TEST(NodePages, OneIndexServesManyBatchesWithTheHitsOfTheFileInMemory) {
  const IndexedMesh mesh = test::loadShared("bunny_npm_lowres.ply.zst");
  test::TemporaryFiles files;
  const auto path = files.add("index.fch");
  writeClusterFile(path, test::fileOf(mesh.view(), 2, BoxPrecision::Exact), {});
  const ClusterFile file = readClusterFile(path);  // the boxes as stored
  ClusterFileReader reader(path, ReaderOptions{1 << 20, {}});
  ReaderQueryIndex index(reader);
  EXPECT_EQ(&index.reader(), &reader);
  EXPECT_GT(index.temporaryBytes(), 0u);
  const auto [lo, hi] = test::vertexBounds(file);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (int batch = 0; batch < 3; ++batch) {
    std::vector<Ray> rays(500);
    for (Ray& r : rays) {
      r.origin = lo - (hi - lo) + 3.0f * (hi - lo) * glm::vec3(unit(rng), unit(rng), unit(rng));
      r.direction = lo + (hi - lo) * glm::vec3(unit(rng), unit(rng), unit(rng)) - r.origin;
    }
    QueryStats viaIndex, inMemory;
    const std::vector<RayHit> a = intersect(index, rays, {2}, &viaIndex);
    const std::vector<RayHit> b = intersect(file, rays, {1}, &inMemory);
    size_t met = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      ASSERT_EQ(a[i].face, b[i].face) << i;
      EXPECT_EQ(a[i].t, b[i].t) << i;
      met += a[i].face != kNoHit;
    }
    EXPECT_GT(met, rays.size() / 4);
    EXPECT_EQ(viaIndex.boxTests, inMemory.boxTests);
    EXPECT_EQ(viaIndex.triangleTests, inMemory.triangleTests);
  }
  EXPECT_GT(index.peakPageBytes(), 0u);
  EXPECT_LE(index.peakPageBytes(), reader.memoryBytes() / 8 + 2048 * 72 + 64);
}

}  // namespace
}  // namespace facetree
