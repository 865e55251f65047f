// Truncation (Willmott 2000, sec. 5.5.3): every prefix is a valid hierarchy, by file and in memory.
#include <gtest/gtest.h>

#include "facetree/error.h"
#include "fch_test_util.h"

namespace facetree {
namespace {

constexpr uint32_t kNoOwner = 0xFFFFFFFFu;  // a face no kept node holds

// Calls visit(first, end, ref) with the face range [first, end) of each child of `node` that has a
// record, in order: a face child is one position, a node child its range. Children cut off by
// truncation have none and are skipped, unless `cutOff` and their parent gives their face count
// (version 2 records do); the ranges visited partition the node's in order, with gaps where
// skipped children lie.
template <class Visit>
void forEachChildRange(const ClusterFile& file, const FchNode& node, Visit&& visit, bool cutOff = false) {
  uint64_t cursor = node.first;
  bool known = true;  // cursor is the start of child c
  for (unsigned c = 0; c < node.childCount; ++c) {
    const uint32_t ref = node.child[c];
    if (ref & kFaceChild) {
      const uint64_t position = ref & ~kFaceChild;
      visit(position, position + 1, ref);
      cursor = position + 1, known = true;
    } else if (ref < file.nodes.size()) {
      const FchNode& child = file.nodes[ref];
      visit(uint64_t{child.first}, uint64_t{child.first} + child.count, ref);
      cursor = uint64_t{child.first} + child.count, known = true;
    } else if (known && node.childFaces[c] > 0) {
      if (cutOff) visit(cursor, cursor + node.childFaces[c], ref);
      cursor += node.childFaces[c];
    } else {
      known = false;
    }
  }
}

uint64_t rangeEnd(const FchNode& node) {
  return uint64_t{node.first} + node.count;
}

// For every face position, the deepest node with kept[node] != 0 containing it (kNoOwner if none):
// each face is assigned once, by the node that owns it directly.
std::vector<uint32_t> deepestKeptNode(const ClusterFile& file, const std::vector<uint8_t>& kept) {
  const size_t faces = file.indices.size() / 3;
  std::vector<uint32_t> owner(faces, kNoOwner);
  auto paint = [&](uint64_t begin, uint64_t end, uint32_t node) {
    for (uint64_t p = begin; p < std::min<uint64_t>(end, faces); ++p) owner[p] = node;
  };
  for (size_t j = 0; j < file.nodes.size(); ++j) {
    if (!kept[j]) continue;
    const FchNode& node = file.nodes[j];
    // Children partition the range in order: paint the gaps between kept node children.
    uint64_t cursor = node.first;
    forEachChildRange(file, node, [&](uint64_t first, uint64_t end, uint32_t ref) {
      if ((ref & kFaceChild) || !kept[ref]) return;
      paint(cursor, first, static_cast<uint32_t>(j));
      cursor = end;
    });
    paint(cursor, rangeEnd(node), static_cast<uint32_t>(j));
  }
  return owner;
}

using namespace facetree::test;

class Truncate : public ::testing::TestWithParam<unsigned> {
 protected:
  void SetUp() override {
    const TestMesh mesh = gridMesh(25, 19);
    FileOptions options;
    options.branching = GetParam();
    file = makeClusterFile(mesh.view(), {}, medianSplitHierarchy(mesh.view()), options);
    write.nodesPerFrame = 32;
    write.geometryPerFrame = 200;
    writeClusterFile(full, file, write);
  }
  Cleanup cleanup;
  std::filesystem::path full = cleanup.add(scratch("full.fch"));
  std::filesystem::path cut = cleanup.add(scratch("cut.fch"));
  std::filesystem::path reference = cleanup.add(scratch("reference.fch"));
  ClusterFile file;
  WriteOptions write;
};

TEST_P(Truncate, EveryPrefixIsAValidHierarchyReachingEveryFaceOnce) {
  const uint64_t n = file.nodes.size();
  for (uint64_t k : {uint64_t{1}, uint64_t{2}, uint64_t{3}, uint64_t{31}, uint64_t{32}, uint64_t{33}, n / 3,
                     n / 2, n - 1, n, n + 5}) {
    SCOPED_TRACE("K = " + std::to_string(k));
    const TruncateResult result = truncateClusterFile(full, cut, k);
    EXPECT_EQ(result.nodes, std::min(k, n));
    EXPECT_EQ(result.bytes, std::filesystem::file_size(cut));
    const ClusterFile back = readClusterFile(cut);
    ASSERT_EQ(back.nodes.size(), std::min(k, n));
    EXPECT_EQ(back.header.originalNodeCount, n);
    const VerifyResult verified = verifyClusterFile(back);
    ASSERT_TRUE(verified.ok) << verified.message;
    EXPECT_EQ(back.indices, file.indices);
    EXPECT_EQ(back.originalFace, file.originalFace);
    // Same as truncating in memory, field by field and byte by byte.
    ClusterFile memory = file;
    truncateInMemory(memory, k);
    ASSERT_EQ(memory.nodes.size(), back.nodes.size());
    for (size_t j = 0; j < back.nodes.size(); ++j)
      ASSERT_TRUE(sameNode(back.nodes[j], memory.nodes[j])) << "node " << j;
    writeClusterFile(reference, memory, write);
    EXPECT_EQ(slurp(reference), slurp(cut));
    // Every face has exactly one owner, the deepest kept node; owners are leaves of the cut tree
    // or truncated nodes, and each owner's faces are its range minus its kept children.
    const std::vector<uint8_t> kept(back.nodes.size(), 1);
    const std::vector<uint32_t> owner = deepestKeptNode(back, kept);
    std::vector<uint64_t> owned(back.nodes.size(), 0);
    for (const uint32_t o : owner) {
      ASSERT_NE(o, kNoOwner);
      ++owned[o];
    }
    for (size_t j = 0; j < back.nodes.size(); ++j) {
      uint64_t covered = 0;
      for (unsigned c = 0; c < back.nodes[j].childCount; ++c) {
        const uint32_t ref = back.nodes[j].child[c];
        if (!(ref & kFaceChild) && !back.isCutOff(ref)) covered += back.nodes[ref].count;
      }
      EXPECT_EQ(owned[j], back.nodes[j].count - covered);
    }
  }
}

TEST_P(Truncate, TruncatingATruncatedFile) {
  const auto twice = cleanup.add(scratch("twice.fch"));
  truncateClusterFile(full, cut, file.nodes.size() / 2);
  truncateClusterFile(cut, twice, 40);
  truncateClusterFile(full, reference, 40);
  EXPECT_EQ(slurp(twice), slurp(reference));
}

// The frames are copied from the input as the output is written: a corrupt geometry frame found
// then fails the truncation by its checksum and leaves no output behind.
TEST_P(Truncate, ACorruptFrameFoundWhileCopyingLeavesNoOutput) {
  std::string bytes = slurp(full);
  bytes[bytes.size() - 3] ^= 0x10;  // the last frame: original ids
  const auto corrupt = cleanup.add(scratch("corrupt.fch"));
  spit(corrupt, bytes);
  for (const bool byBytes : {false, true}) {
    try {
      if (byBytes)
        truncateClusterFileToBytes(corrupt, cut, bytes.size() - 100);
      else
        truncateClusterFile(corrupt, cut, 40);
      ADD_FAILURE() << "a corrupt frame was copied";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("checksum mismatch"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(std::filesystem::exists(cut));
  }
}

TEST_P(Truncate, MaxBytesKeepsTheLargestPrefixThatFits) {
  const uint64_t fullBytes = std::filesystem::file_size(full);
  const uint64_t minimal = truncateClusterFile(full, reference, 1).bytes;
  for (const uint64_t budget :
       {fullBytes, fullBytes + 100, fullBytes - 1, (fullBytes + minimal) / 2, minimal + 300, minimal}) {
    SCOPED_TRACE("budget " + std::to_string(budget));
    const TruncateResult result = truncateClusterFileToBytes(full, cut, budget);
    EXPECT_LE(result.bytes, budget);
    EXPECT_EQ(result.bytes, std::filesystem::file_size(cut));
    EXPECT_TRUE(verifyClusterFile(readClusterFile(cut)).ok);
    if (result.nodes < file.nodes.size()) {
      // A few nodes more would not fit (zstd noise within the last frame aside).
      EXPECT_GT(truncateClusterFile(full, reference, result.nodes + 3).bytes, budget);
    } else {
      EXPECT_EQ(result.bytes, fullBytes);
    }
  }
  EXPECT_THROW(truncateClusterFileToBytes(full, cut, minimal - 30), std::invalid_argument);
  EXPECT_THROW(truncateClusterFile(full, cut, 0), std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(Branching, Truncate, ::testing::Values(2u, 4u, 8u));

TEST(Cut, ClusterCutsNumberContiguousClusters) {
  const TestMesh mesh = gridMesh(16, 16);
  const ClusterFile file = makeClusterFile(mesh.view(), {}, medianSplitHierarchy(mesh.view()), {});
  const size_t faces = file.originalFace.size();
  EXPECT_EQ(clusterCut(file, 1), std::vector<uint32_t>(faces, 0));
  EXPECT_EQ(clusterDepthCut(file, 0), std::vector<uint32_t>(faces, 0));
  for (uint64_t n : {uint64_t{2}, uint64_t{7}, uint64_t{100}, uint64_t{1000000}}) {
    const std::vector<uint32_t> cut = clusterCut(file, n);
    ASSERT_EQ(cut.size(), faces);
    // Clusters are runs along the face order, numbered 0, 1, 2, ...
    uint32_t next = 0;
    for (size_t p = 0; p < faces; ++p) {
      if (p > 0 && cut[p] == cut[p - 1]) continue;
      EXPECT_EQ(cut[p], next++) << "face " << p;
    }
    // A binary tree cut after k nodes has k + 1 clusters: exactly n, up to one per face.
    EXPECT_EQ(next, std::min<uint64_t>(n, faces));
  }
  // Depth d of a median-split (balanced) tree: 2^d clusters.
  const std::vector<uint32_t> depth3 = clusterDepthCut(file, 3);
  EXPECT_EQ(*std::max_element(depth3.begin(), depth3.end()), 7u);
}

}  // namespace
}  // namespace facetree
