// The cluster file format: checksums, round trips, determinism and corrupt files.
#include <gtest/gtest.h>

#include <cstring>

#include "facetree/io.h"
#include "fch_test_util.h"
#include "io/format/fch_format.h"
#include "io/mesh/reordered_mesh.h"

namespace facetree {
namespace {

using namespace facetree::test;

ClusterFile sampleFile(unsigned branching, int w = 20, int h = 13) {
  const TestMesh mesh = gridMesh(w, h);
  const Hierarchy hierarchy = medianSplitHierarchy(mesh.view());
  std::vector<uint64_t> ids(mesh.indices.size() / 3);
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = 1000 + i / 2;  // two triangles per quad face
  FileOptions options;
  options.branching = branching;
  options.build.k = 2e-4;
  options.memoryCapBytes = 123456789;
  return makeClusterFile(mesh.view(), ids, hierarchy, options);
}

std::string errorOf(const std::filesystem::path& path) {
  try {
    readClusterFile(path);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(FchHash, MatchesTheReferenceXxh64) {
  // Values from libxxhash 0.8.1 (XXH64, seed 0).
  EXPECT_EQ(fch::xxh64("", 0), 0xef46db3751d8e999ull);
  EXPECT_EQ(fch::xxh64("a", 1), 0xd24ec4f1a98c6e5bull);
  EXPECT_EQ(fch::xxh64("abc", 3), 0x44bc2cf5ad770999ull);
  EXPECT_EQ(fch::xxh64("facetree cluster file", 21), 0x12f817cb6d6fe1e9ull);
  std::string bytes;
  for (int r = 0; r < 3; ++r)
    for (int i = 0; i < 256; ++i) bytes += static_cast<char>(i);
  EXPECT_EQ(fch::xxh64(bytes.data(), bytes.size()), 0x8e03c838c596036full);
}

class FchRoundTrip : public ::testing::TestWithParam<unsigned> {};

TEST_P(FchRoundTrip, WriteReadGivesIdenticalNodesAndGeometry) {
  Cleanup cleanup;
  const ClusterFile file = sampleFile(GetParam());
  ASSERT_TRUE(verifyClusterFile(file).ok) << verifyClusterFile(file).message;
  WriteOptions small;
  small.nodesPerFrame = 7;  // many frames
  small.geometryPerFrame = 50;
  for (const WriteOptions& options : {WriteOptions{}, small}) {
    const auto path = cleanup.add(scratch("roundtrip.fch"));
    writeClusterFile(path, file, options);
    const ClusterFile back = readClusterFile(path);
    ASSERT_EQ(back.nodes.size(), file.nodes.size());
    for (size_t j = 0; j < file.nodes.size(); ++j)
      EXPECT_TRUE(sameNode(back.nodes[j], file.nodes[j])) << "node " << j;
    EXPECT_EQ(back.vertices, file.vertices);
    EXPECT_EQ(back.indices, file.indices);
    EXPECT_EQ(back.originalFace, file.originalFace);
    EXPECT_EQ(back.header.branching, GetParam());
    EXPECT_EQ(back.header.k, 2e-4);
    EXPECT_EQ(back.header.memoryCapBytes, 123456789u);
    EXPECT_EQ(back.header.nodeCount, file.nodes.size());
    EXPECT_EQ(back.header.originalNodeCount, file.nodes.size());
    const VerifyResult result = verifyClusterFile(back);
    EXPECT_TRUE(result.ok) << result.message;
    const ClusterFile nodesOnly = readClusterFile(path, false);
    EXPECT_EQ(nodesOnly.nodes.size(), file.nodes.size());
    EXPECT_TRUE(nodesOnly.indices.empty());
  }
}

INSTANTIATE_TEST_SUITE_P(Branching, FchRoundTrip, ::testing::Values(2u, 4u, 8u));

TEST(FchFormat, WritingTwiceGivesIdenticalBytes) {
  Cleanup cleanup;
  const ClusterFile file = sampleFile(4);
  const auto a = cleanup.add(scratch("a.fch")), b = cleanup.add(scratch("b.fch"));
  writeClusterFile(a, file);
  writeClusterFile(b, sampleFile(4));
  EXPECT_EQ(slurp(a), slurp(b));
}

TEST(FchFormat, WideOriginalIdsRoundTrip) {
  Cleanup cleanup;
  ClusterFile file = sampleFile(2, 4, 3);
  file.originalFace[0] = uint64_t{1} << 40;
  file.originalFace[1] = 3;
  const auto path = cleanup.add(scratch("wide.fch"));
  writeClusterFile(path, file);
  EXPECT_EQ(readClusterFileLayout(path).originalIdBytes, 8u);
  EXPECT_EQ(readClusterFile(path).originalFace, file.originalFace);
}

TEST(FchFormat, TinyMeshes) {
  Cleanup cleanup;
  for (int triangles : {0, 1, 2}) {
    TestMesh mesh = gridMesh(1, 1);
    mesh.indices.resize(3 * triangles);
    const Hierarchy hierarchy = medianSplitHierarchy(mesh.view());
    const ClusterFile file = makeClusterFile(mesh.view(), {}, hierarchy, {});
    const auto path = cleanup.add(scratch("tiny.fch"));
    writeClusterFile(path, file);
    const ClusterFile back = readClusterFile(path);
    EXPECT_EQ(back.nodes.size(), triangles == 2 ? 1u : 0u);
    EXPECT_EQ(back.indices, file.indices);
    EXPECT_TRUE(verifyClusterFile(back).ok) << verifyClusterFile(back).message;
    EXPECT_EQ(clusterCut(back, 5).size(), size_t(triangles));
  }
}

TEST(FchFormat, ReorderedGeometryKeepsTrianglesAndNumbersVerticesByFirstUse) {
  const TestMesh mesh = gridMesh(6, 5);
  const Hierarchy hierarchy = medianSplitHierarchy(mesh.view());
  const ClusterFile file = makeClusterFile(mesh.view(), {}, hierarchy, {});
  uint32_t next = 0;
  for (const uint32_t v : file.indices) {
    ASSERT_LE(v, next);
    if (v == next) ++next;
  }
  EXPECT_EQ(next, file.vertices.size());
  for (size_t i = 0; i < file.originalFace.size(); ++i) {
    EXPECT_EQ(file.originalFace[i], hierarchy.faceOrder[i]);
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(file.vertices[file.indices[3 * i + k]],
                mesh.positions[mesh.indices[3 * hierarchy.faceOrder[i] + k]]);
  }
  EXPECT_TRUE(verifyAgainstMesh(file, mesh.view(), {}).ok);
}

// ---------------------------------------------------------------------------------------------
// Corrupt files: the exact messages, never a crash.

struct Corruption : ::testing::Test {
  Cleanup cleanup;
  std::filesystem::path good = cleanup.add(scratch("good.fch"));
  std::filesystem::path bad = cleanup.add(scratch("bad.fch"));
  std::string bytes;
  void SetUp() override {
    WriteOptions options;
    options.nodesPerFrame = 16;
    writeClusterFile(good, sampleFile(2, 12, 8), options);
    bytes = slurp(good);
  }
};

TEST_F(Corruption, BadMagic) {
  std::string b = bytes;
  b[1] = 'X';
  spit(bad, b);
  EXPECT_EQ(errorOf(bad), bad.string() + ": not a facetree cluster file (bad magic)");
  spit(bad, "ply\nformat ascii 1.0\n");
  EXPECT_EQ(errorOf(bad), bad.string() + ": not a facetree cluster file (bad magic)");
  spit(bad, "");
  EXPECT_EQ(errorOf(bad), bad.string() + ": not a facetree cluster file (bad magic)");
}

TEST_F(Corruption, UnsupportedVersion) {
  std::string b = bytes;
  b[8] = 7;
  spit(bad, b);
  EXPECT_EQ(errorOf(bad), bad.string() + ": unsupported version 7");
}

TEST_F(Corruption, FlippedByteInANodeFrame) {
  const FchLayout layout = readClusterFileLayout(good);
  const FchFrame& frame = layout.frames[3];
  ASSERT_EQ(frame.section, FchSection::Nodes);
  std::string b = bytes;
  b[frame.offset + frame.compressedBytes / 2] ^= 0x10;
  spit(bad, b);
  EXPECT_EQ(errorOf(bad), bad.string() + ": node frame 3 (nodes 48-63): checksum mismatch");
}

TEST_F(Corruption, FlippedHeaderByte) {
  std::string b = bytes;
  b[44] ^= 1;  // triangle count
  spit(bad, b);
  EXPECT_EQ(errorOf(bad), bad.string() + ": header checksum mismatch");
}

TEST_F(Corruption, TruncatedFile) {
  spit(bad, bytes.substr(0, bytes.size() - 10));
  EXPECT_EQ(errorOf(bad), bad.string() + ": truncated at byte " + std::to_string(bytes.size() - 10) +
                              " (header declares " + std::to_string(bytes.size()) + " bytes)");
  spit(bad, bytes.substr(0, 100));
  EXPECT_EQ(errorOf(bad), bad.string() + ": truncated at byte 100");
  spit(bad, bytes + "xyz");
  EXPECT_EQ(errorOf(bad), bad.string() + ": 3 unexpected bytes after byte " + std::to_string(bytes.size()));
}

TEST_F(Corruption, EveryFlippedByteIsDetected) {
  // Every byte is covered by a checksum, a magic or a consistency check.
  // Header and index byte by byte, frames at a stride (each read costs a few milliseconds).
  const size_t frames = fch::kHeaderBytes + fch::kIndexEntryBytes * readClusterFileLayout(good).frames.size();
  for (size_t i = 0; i < bytes.size(); i += i < frames ? 1 : 5) {
    std::string b = bytes;
    b[i] ^= static_cast<char>(1u << (i % 8));
    spit(bad, b);
    EXPECT_NE(errorOf(bad), "") << "byte " << i;
  }
}

TEST_F(Corruption, EveryTruncationIsDetected) {
  for (size_t n = 0; n < bytes.size(); n += 7) {
    spit(bad, bytes.substr(0, n));
    EXPECT_NE(errorOf(bad), "") << n << " bytes";
  }
}

TEST_F(Corruption, HugeCountsWithValidChecksumsAllocateNothing) {
  // A forged header claiming 2^30 triangles, re-checksummed: rejected from the index, before
  // anything is allocated for the claimed counts.
  std::string b = bytes;
  const uint64_t claimed = uint64_t{1} << 30;
  std::memcpy(b.data() + 40, &claimed, 8);
  const uint64_t sum = fch::xxh64(b.data(), fch::kHeaderChecksumOffset);
  std::memcpy(b.data() + fch::kHeaderChecksumOffset, &sum, 8);
  spit(bad, b);
  const std::string error = errorOf(bad);
  EXPECT_NE(error.find(": frame index entry "), std::string::npos) << error;
}

}  // namespace
}  // namespace facetree
