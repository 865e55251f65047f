// ClusterFileReader: the lazy reader gives what readClusterFile gives, node by node, cut by cut and
// face range by face range, in any order of access, with a cache far smaller than the file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>

#include <fcntl.h>
#include <unistd.h>

#include "facetree/error.h"
#include "facetree/picture.h"
#include "fch_test_util.h"

namespace facetree {
namespace {

using namespace facetree::test;

bool identical(const FchNode& a, const FchNode& b) {
  return a.first == b.first && a.count == b.count && a.childCount == b.childCount && a.flags == b.flags &&
         std::equal(a.child, a.child + a.childCount, b.child) &&
         std::equal(a.childFaces, a.childFaces + a.childCount, b.childFaces) && a.cost == b.cost &&
         a.area == b.area && a.perimeter == b.perimeter && a.sumNormal == b.sumNormal &&
         a.box.center == b.box.center && a.box.orientation == b.box.orientation &&
         a.box.halfExtent == b.box.halfExtent &&
         std::equal(a.box.sideArea, a.box.sideArea + 6, b.box.sideArea);
}

// clusterCut's numbering of the faces as (first, count) runs, against the reader's clusters.
void expectSameRuns(const std::vector<uint32_t>& label, const std::vector<CutCluster>& cut) {
  std::vector<std::pair<uint64_t, uint64_t>> runs;
  for (uint64_t p = 0; p < label.size(); ++p)
    if (p == 0 || label[p] != label[p - 1])
      runs.emplace_back(p, 1);
    else
      ++runs.back().second;
  ASSERT_EQ(cut.size(), runs.size());
  for (size_t i = 0; i < runs.size(); ++i) {
    EXPECT_EQ(cut[i].first, runs[i].first) << i;
    EXPECT_EQ(cut[i].count, runs[i].second) << i;
  }
}

class Reader : public ::testing::TestWithParam<std::tuple<unsigned, BoxPrecision>> {
 protected:
  void SetUp() override {
    const TestMesh mesh = gridMesh(31, 23, 0.3f);
    BuildOptions build;
    build.boxes = std::get<1>(GetParam());
    FileOptions options;
    options.branching = std::get<0>(GetParam());
    options.build = build;
    const ClusterFile file = makeClusterFile(mesh.view(), {}, buildHierarchy(mesh.view(), build), options);
    WriteOptions write;
    write.nodesPerFrame = 32;  // many frames, parents and children in different ones
    write.geometryPerFrame = 100;
    writeClusterFile(path, file, write);
  }
  Cleanup cleanup;
  std::filesystem::path path = cleanup.add(scratch("reader.fch"));
  std::filesystem::path truncated = cleanup.add(scratch("reader_cut.fch"));
};

TEST_P(Reader, NodesInAnyOrderEqualTheWholeFilesWithACacheOfAFewFrames) {
  for (const auto& file : {path, truncated}) {
    if (file == truncated) truncateClusterFile(path, truncated, 101);
    SCOPED_TRACE(file.string());
    const ClusterFile whole = readClusterFile(file);
    ClusterFileReader reader(file, ReaderOptions{32 << 10, {}});
    ASSERT_EQ(reader.size(), whole.nodes.size());
    std::vector<uint64_t> order(whole.nodes.size());
    for (uint64_t i = 0; i < order.size(); ++i) order[i] = i;
    std::shuffle(order.begin(), order.end(), std::mt19937(7));
    for (const uint64_t i : order) ASSERT_TRUE(identical(reader.node(i), whole.nodes[i])) << i;
    // The cache, the frame in use and the pass's announced children: far less than the nodes.
    EXPECT_LE(reader.heldBytes(), (8u << 10) + 3 * 32 * sizeof(FchNode) + 64 * 1024);
    // The pass: every node once, in order, with its depth from the root.
    std::vector<uint32_t> depth(whole.nodes.size(), 1);
    uint64_t next = 0;
    reader.forEachNode([&](uint64_t index, const FchNode& node, uint32_t d) {
      EXPECT_EQ(index, next++);
      EXPECT_TRUE(identical(node, whole.nodes[index])) << index;
      EXPECT_EQ(d, depth[index]) << index;
      for (unsigned c = 0; c < node.childCount; ++c)
        if (!(node.child[c] & kFaceChild) && node.child[c] < depth.size()) depth[node.child[c]] = d + 1;
      return true;
    });
    EXPECT_EQ(next, whole.nodes.size());
    EXPECT_EQ(branchingStats(reader), branchingStats(whole));
    // 8 KiB of announced children (and, with compact boxes, of their parents' boxes) hold a few
    // hundred: the rest went to the temporary file and back.
    if (file == path && std::get<0>(GetParam()) == 2) {
      EXPECT_GT(reader.spilledBytes(), 0u);
    }
    EXPECT_LE(reader.peakHeldBytes(), uint64_t{96} << 10);
    // The whole file read through a reader under that cap: the same arrays.
    ClusterFileReader small(file, ReaderOptions{32 << 10, {}});
    const ClusterFile again = readClusterFile(small);
    ASSERT_EQ(again.nodes.size(), whole.nodes.size());
    for (size_t i = 0; i < again.nodes.size(); ++i)
      ASSERT_TRUE(identical(again.nodes[i], whole.nodes[i])) << i;
    EXPECT_EQ(again.vertices, whole.vertices);
    EXPECT_EQ(again.indices, whole.indices);
    EXPECT_EQ(again.originalFace, whole.originalFace);
    EXPECT_LE(small.peakHeldBytes(), uint64_t{96} << 10);
    ClusterFileReader roomy(file);
    EXPECT_EQ(branchingStats(roomy), branchingStats(whole));
    EXPECT_EQ(roomy.spilledBytes(), 0u);
  }
}

TEST_P(Reader, CutsAreClusterCutsAndDepthCuts) {
  for (const auto& file : {path, truncated}) {
    if (file == truncated) truncateClusterFile(path, truncated, 57);
    SCOPED_TRACE(file.string());
    const ClusterFile whole = readClusterFile(file);
    ClusterFileReader reader(file, ReaderOptions{32 << 10, {}});
    for (uint64_t clusters : {1, 2, 3, 10, 64, 300, 5000}) {
      SCOPED_TRACE(clusters);
      const std::vector<CutCluster> cut = reader.cut(clusters);
      expectSameRuns(clusterCut(whole, clusters), cut);
      for (const CutCluster& c : cut)
        if (c.node != kNoNode) {
          EXPECT_EQ(whole.nodes[c.node].first, c.first);
          EXPECT_EQ(whole.nodes[c.node].count, c.count);
        }
    }
    for (uint32_t depth : {0u, 1u, 2u, 5u, 9u, 100u}) {
      SCOPED_TRACE(depth);
      expectSameRuns(clusterDepthCut(whole, depth), reader.cutByDepth(depth));
    }
    // A cost cut keeps the nodes whose subtree holds a cost above the bound: a prefix of the file.
    std::vector<float> effective(whole.nodes.size());
    for (size_t j = whole.nodes.size(); j-- > 0;)
      effective[j] = std::max(whole.nodes[j].cost, j + 1 < effective.size() ? effective[j + 1] : 0.0f);
    for (size_t j : {size_t{0}, size_t{3}, whole.nodes.size() / 2}) {
      const double bound = effective[j];
      uint64_t prefix = 0, frontier = 1;
      while (prefix < whole.nodes.size() && effective[prefix] > bound)
        frontier += whole.nodes[prefix++].childCount - 1u;
      expectSameRuns(clusterCut(whole, frontier), reader.cutByCost(bound));
    }
  }
}

// info --fit-cuts under the cap: every figure to the bit, with the Morton order sorted in runs of
// the temporary file (a cap of 64 KiB sorts 200 faces a run).
TEST_P(Reader, CutFitsUnderTheCapAreTheFileInMemorysToTheBit) {
  for (const auto& file : {path, truncated}) {
    if (file == truncated) truncateClusterFile(path, truncated, 57);
    const std::vector<uint64_t> counts = {1, 12, 100, 401, 5000};
    const std::vector<CutFit> whole = cutFits(readClusterFile(file), counts);
    ReaderOptions options;
    options.memoryBytes = 64 << 10;
    ClusterFileReader reader(file, options);
    const std::vector<CutFit> read = cutFits(reader, counts);
    ASSERT_EQ(read.size(), whole.size());
    for (size_t i = 0; i < whole.size(); ++i) {
      EXPECT_EQ(read[i].clusters, whole[i].clusters) << i;
      EXPECT_EQ(read[i].sumFit, whole[i].sumFit) << i;
      EXPECT_EQ(read[i].sumAreaFit, whole[i].sumAreaFit) << i;
      EXPECT_EQ(read[i].sumBoxArea, whole[i].sumBoxArea) << i;
      EXPECT_EQ(read[i].mortonBoxArea, whole[i].mortonBoxArea) << i;
      EXPECT_EQ(read[i].smallClusters, whole[i].smallClusters) << i;
      EXPECT_GT(whole[i].mortonBoxArea, 0.0) << i;
    }
    EXPECT_GT(whole[1].sumAreaFit, 0.0);
  }
}

// A descriptor handed over: the reader reads through its own duplicate, so the caller may close
// its descriptor at once; a pipe is refused by name.
TEST_P(Reader, AnOpenDescriptorReadsAsThePath) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  ASSERT_GE(fd, 0);
  ClusterFileReader byDescriptor(fd, "handed-over.fch");
  ::close(fd);
  ClusterFileReader byPath(path);
  ASSERT_EQ(byDescriptor.size(), byPath.size());
  for (const uint64_t i : {uint64_t{0}, byPath.size() / 2, byPath.size() - 1})
    EXPECT_TRUE(identical(byDescriptor.node(i), byPath.node(i))) << i;
  EXPECT_EQ(byDescriptor.cut(40).size(), byPath.cut(40).size());
  EXPECT_EQ(byDescriptor.faces(10, 50).originalFace, byPath.faces(10, 50).originalFace);
  int pipe[2];
  ASSERT_EQ(::pipe(pipe), 0);
  try {
    ClusterFileReader fromPipe(pipe[0], "a pipe");
    ADD_FAILURE() << "a pipe was read";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "a pipe: descriptor " + std::to_string(pipe[0]) +
                                         " is not a regular file (a cluster file is read at offsets)");
  }
  ::close(pipe[0]), ::close(pipe[1]);
}

TEST_P(Reader, FaceRangesGiveTheFilesTrianglesAndIdsWithLocalVertices) {
  const ClusterFile whole = readClusterFile(path);
  ClusterFileReader reader(path, ReaderOptions{16 << 10, {}});
  const uint64_t faces = whole.indices.size() / 3;
  for (auto [first, count] :
       {std::pair<uint64_t, uint64_t>{0, 1}, {0, faces}, {99, 2}, {250, 333}, {faces - 1, 1}, {17, 0}}) {
    SCOPED_TRACE(std::to_string(first) + "+" + std::to_string(count));
    const FaceRangeMesh mesh = reader.faces(first, count);
    ASSERT_EQ(mesh.indices.size(), 3 * count);
    ASSERT_EQ(mesh.vertexIds.size(), mesh.vertices.size());
    EXPECT_TRUE(std::is_sorted(mesh.vertexIds.begin(), mesh.vertexIds.end()));
    for (uint64_t t = 0; t < count; ++t) {
      EXPECT_EQ(mesh.originalFace[t], whole.originalFace[first + t]);
      for (int c = 0; c < 3; ++c) {
        const uint32_t local = mesh.indices[3 * t + c];
        ASSERT_LT(local, mesh.vertices.size());
        EXPECT_EQ(mesh.vertexIds[local], whole.indices[3 * (first + t) + c]);
        EXPECT_EQ(mesh.vertices[local], whole.vertices[whole.indices[3 * (first + t) + c]]);
      }
    }
  }
  EXPECT_THROW(reader.faces(faces, 1), std::out_of_range);
  // A pass over a cut's clusters covers every face once, in order.
  uint64_t next = 0;
  const std::vector<CutCluster> cut = reader.cut(40);
  reader.forEachCluster(cut, [&](const CutCluster& c, const FaceRangeMesh& mesh) {
    EXPECT_EQ(c.first, next);
    EXPECT_EQ(mesh.originalFace.size(), c.count);
    next += c.count;
  });
  EXPECT_EQ(next, faces);
}

TEST_P(Reader, PicturesAndMeshesOfACutReadInFramesAreTheWholeFilesBytes) {
  const auto png = cleanup.add(scratch("reader_a.png")), pngWhole = cleanup.add(scratch("reader_b.png"));
  const auto ply = cleanup.add(scratch("reader_a.ply")), plyWhole = cleanup.add(scratch("reader_b.ply"));
  truncateClusterFile(path, truncated, 77);
  for (const auto& file : {path, truncated}) {
    SCOPED_TRACE(file.string());
    const ClusterFile whole = readClusterFile(file);
    ClusterFileReader reader(file, ReaderOptions{16 << 10, {}});
    RenderOptions options;
    options.width = 96, options.height = 64;
    for (uint64_t clusters : {1, 12, 200}) {
      SCOPED_TRACE(clusters);
      const std::vector<CutCluster> cut = reader.cut(clusters);
      renderClustersPng(reader, cut, options, png);
      renderClustersPng(whole.mesh(), clusterCut(whole, clusters), options, pngWhole);
      EXPECT_EQ(slurp(png), slurp(pngWhole));
      writeClusterColouredPly(reader, cut, ply);
      writeClusterColouredPly(whole.mesh(), clusterCut(whole, clusters), plyWhole);
      EXPECT_EQ(slurp(ply), slurp(plyWhole));
    }
  }
}

INSTANTIATE_TEST_SUITE_P(BranchingAndBoxes, Reader,
                         ::testing::Combine(::testing::Values(2u, 4u, 8u),
                                            ::testing::Values(BoxPrecision::Exact, BoxPrecision::Compact)));

TEST(ReaderErrors, ACorruptNodeFrameIsNamedWhenReachedAndTheOpenChecksOnlyTheIndex) {
  Cleanup cleanup;
  const auto path = cleanup.add(scratch("reader_bad.fch"));
  const TestMesh mesh = gridMesh(20, 20);
  const ClusterFile file = makeClusterFile(mesh.view(), {}, medianSplitHierarchy(mesh.view()), FileOptions{});
  WriteOptions write;
  write.nodesPerFrame = 64;
  writeClusterFile(path, file, write);
  const FchLayout layout = readClusterFileLayout(path);
  const FchFrame& third = layout.frames[2];
  ASSERT_EQ(third.section, FchSection::Nodes);
  std::string bytes = slurp(path);
  bytes[third.offset + third.compressedBytes / 2] ^= 0x5A;
  spit(path, bytes);
  ClusterFileReader reader(path);
  EXPECT_TRUE(sameNode(reader.node(5), file.nodes[5]));  // the frames before the bad one decode
  try {
    reader.node(2 * 64 + 1);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), path.string() + ": node frame 2 (nodes 128-191): checksum mismatch");
  }
}

}  // namespace
}  // namespace facetree
