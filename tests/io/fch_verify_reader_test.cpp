// verifyClusterFile and verifyAgainstMesh over a ClusterFileReader give the verdicts of the checks
// in memory, on valid files and on files broken one invariant at a time (and several, where the
// lowest node must be named), with a cap so small that the nodes wait in many windows of faces and
// in the temporary file.
#include <gtest/gtest.h>

#include <functional>

#include "facetree/grid.h"
#include "fch_test_util.h"

namespace facetree {
namespace {

using namespace facetree::test;

// Windows of 85 faces, buckets in the temporary file.
ReaderOptions tinyCap() {
  ReaderOptions options;
  options.memoryBytes = 64 << 10;
  return options;
}

WriteOptions verifyFrames() {
  WriteOptions write;
  write.nodesPerFrame = 32;
  write.geometryPerFrame = 100;
  return write;
}

class StreamingVerify : public ::testing::TestWithParam<std::tuple<unsigned, BoxPrecision>> {
 protected:
  void SetUp() override {
    BuildOptions build;
    build.boxes = std::get<1>(GetParam());
    FileOptions options;
    options.branching = std::get<0>(GetParam());
    options.build = build;
    file = makeClusterFile(mesh.view(), {}, buildHierarchy(mesh.view(), build), options);
  }
  // Writes `broken` (many small frames) and returns both verdicts: in memory, streamed.
  std::pair<VerifyResult, VerifyResult> verdicts(const ClusterFile& broken) {
    writeClusterFile(path, broken, verifyFrames());
    ClusterFileReader reader(path, tinyCap());
    return {verifyClusterFile(readClusterFile(path)), verifyClusterFile(reader)};
  }
  void expectSame(const std::pair<VerifyResult, VerifyResult>& v, bool ok) {
    EXPECT_EQ(v.first.ok, ok) << v.first.message;
    EXPECT_EQ(v.second.ok, v.first.ok);
    EXPECT_EQ(v.second.message, v.first.message);
    EXPECT_EQ(v.second.nodesChecked, v.first.nodesChecked);
  }

  TestMesh mesh = gridMesh(31, 23, 0.3f);
  ClusterFile file;
  Cleanup cleanup;
  std::filesystem::path path = cleanup.add(scratch("verify_stream.fch"));
};

TEST_P(StreamingVerify, AValidFileAndItsTruncationsPass) {
  expectSame(verdicts(file), true);
  for (const uint64_t keep : {uint64_t{1}, uint64_t{7}, uint64_t{100}}) {
    ClusterFile cut = file;
    truncateInMemory(cut, keep);
    expectSame(verdicts(cut), true);
  }
}

TEST_P(StreamingVerify, EachBrokenInvariantGetsTheSameVerdict) {
  const uint64_t n = file.nodes.size();
  const std::vector<std::pair<const char*, std::function<void(FchNode&)>>> breaks = {
      {"box containment", [](FchNode& node) { node.box.halfExtent.y *= 0.5f; }},
      {"box tightness", [](FchNode& node) { node.box.halfExtent.z = node.box.halfExtent.z * 2.0f + 1.0f; }},
      {"area", [](FchNode& node) { node.area *= 1.5f; }},
      {"sum normal", [](FchNode& node) { node.sumNormal.x += node.area; }},
      {"side area", [](FchNode& node) { node.box.sideArea[3] += node.area; }},
  };
  int checked = 0, refused = 0;
  for (const auto& [check, edit] : breaks) {
    for (const uint64_t at : {uint64_t{0}, uint64_t{1}, n / 2, n - 1}) {
      ClusterFile broken = file;
      edit(broken.nodes[at]);
      std::pair<VerifyResult, VerifyResult> v;
      try {
        v = verdicts(broken);
      } catch (const std::exception& e) {
        // Compact boxes are quantised against the parent's: the writer refuses a box that leaves it.
        if (std::get<1>(GetParam()) != BoxPrecision::Compact) throw;
        EXPECT_NE(std::string(e.what()).find("outside its parent's"), std::string::npos) << e.what();
        ++refused;
        continue;
      }
      ++checked;
      expectSame(v, false);
      // The writer's rounding (S and side areas are fractions of the area) can move which check
      // breaks first; the node is always the one broken.
      EXPECT_EQ(v.second.message.rfind("node " + std::to_string(at) + ": ", 0), 0u)
          << check << ": " << v.second.message;
    }
  }
  EXPECT_GE(checked, 12) << refused << " refused";
  // Two nodes broken far apart in face order: the lowest index is the verdict, as in memory.
  ClusterFile broken = file;
  broken.nodes[n - 2].box.sideArea[0] += broken.nodes[n - 2].area;
  broken.nodes[n / 3].area *= 2.0f;
  const auto v = verdicts(broken);
  expectSame(v, false);
  EXPECT_EQ(v.second.message.rfind("node " + std::to_string(n / 3) + ": area", 0), 0u) << v.second.message;
}

TEST_P(StreamingVerify, TheMeshComparisonGetsTheSameVerdict) {
  writeClusterFile(path, file, verifyFrames());
  const ClusterFile back = readClusterFile(path);
  // The mesh as the build had it: the original ids are positions in `mesh`. Its triangles come in
  // order (compared as they come) and backwards (bucketed by id like the file's).
  const auto compareIn = [&](bool backwards, const TestMesh& other, const std::vector<uint64_t>& ids) {
    ClusterFileReader reader(path, tinyCap());
    const MeshTriangleSource source = [&](const std::function<void(std::span<const MeshTriangle>)>& visit) {
      std::vector<MeshTriangle> batch;
      for (uint64_t t = 0; t < other.faceCount(); ++t) {  // in batches of 50
        const uint64_t s = backwards ? other.faceCount() - 1 - t : t;
        batch.push_back({ids.empty() ? s : ids[s],
                         s,
                         {other.positions[other.indices[3 * s]], other.positions[other.indices[3 * s + 1]],
                          other.positions[other.indices[3 * s + 2]]}});
        if (batch.size() == 50) visit(batch), batch.clear();
      }
      visit(batch);
    };
    const VerifyResult streamed = verifyAgainstMesh(reader, source);
    const VerifyResult inMemory = verifyAgainstMesh(back, other.view(), ids);
    EXPECT_EQ(streamed.ok, inMemory.ok) << backwards;
    EXPECT_EQ(streamed.message, inMemory.message) << backwards;
    return streamed;
  };
  const auto compare = [&](const TestMesh& other, const std::vector<uint64_t>& ids) {
    compareIn(false, other, ids);
    return compareIn(true, other, ids);
  };
  EXPECT_TRUE(compare(mesh, {}).ok);
  TestMesh moved = mesh;
  moved.positions[moved.indices[3 * 700 + 1]].z += 0.5f;
  EXPECT_FALSE(compare(moved, {}).ok);
  std::vector<uint64_t> swapped(mesh.faceCount());
  for (uint64_t t = 0; t < swapped.size(); ++t) swapped[t] = t;
  std::swap(swapped[10], swapped[1200]);
  const VerifyResult v = compare(mesh, swapped);
  EXPECT_FALSE(v.ok);
  EXPECT_NE(v.message.find("original face 10"), std::string::npos) << v.message;
  TestMesh fewer = mesh;
  fewer.indices.resize(fewer.indices.size() - 3);
  EXPECT_EQ(compare(fewer, {}).message, "mesh: 1425 triangles, the file has 1426");
}

INSTANTIATE_TEST_SUITE_P(Files, StreamingVerify,
                         ::testing::Combine(::testing::Values(2u, 4u, 8u),
                                            ::testing::Values(BoxPrecision::Exact, BoxPrecision::Compact)));

}  // namespace
}  // namespace facetree
