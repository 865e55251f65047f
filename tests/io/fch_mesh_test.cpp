// Real hierarchies (buildHierarchy) through the cluster file, and the reordered mesh as PLY and
// Draco, decoded and checked against the hierarchy's face order.
#include <draco/compression/decode.h>
#include <gtest/gtest.h>

#include <cstdio>

#include "facetree/generate.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/picture.h"
#include "facetree/stream.h"
#include "fch_test_util.h"

namespace facetree {
namespace {

using namespace facetree::test;

std::filesystem::path shared(const std::string& name) {
  return std::filesystem::path(FACETREE_SHARED_DATA) / name;
}

// Triangle i of `decoded` has the corners of triangle faceOrder[i] of `mesh`, in order.
void expectHierarchyOrder(const std::vector<glm::vec3>& vertices, const std::vector<uint32_t>& indices,
                          const MeshView& mesh, const std::vector<uint32_t>& faceOrder, float tolerance) {
  ASSERT_EQ(indices.size(), 3 * faceOrder.size());
  for (size_t i = 0; i < faceOrder.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const glm::vec3 got = vertices[indices[3 * i + k]];
      const glm::vec3 want = mesh.positions[mesh.indices[3 * size_t{faceOrder[i]} + k]];
      ASSERT_LE(glm::length(got - want), tolerance) << "triangle " << i << " corner " << k;
    }
}

struct Decoded {
  std::vector<glm::vec3> vertices;
  std::vector<uint32_t> indices;
};

Decoded decodeDraco(const std::filesystem::path& path) {
  const std::string bytes = slurp(path);
  draco::DecoderBuffer buffer;
  buffer.Init(bytes.data(), bytes.size());
  draco::Decoder decoder;
  auto result = decoder.DecodeMeshFromBuffer(&buffer);
  EXPECT_TRUE(result.ok()) << result.status().error_msg_string();
  Decoded out;
  if (!result.ok()) return out;
  const draco::Mesh& mesh = *result.value();
  const draco::PointAttribute* position = mesh.GetNamedAttribute(draco::GeometryAttribute::POSITION);
  for (uint32_t p = 0; p < mesh.num_points(); ++p) {
    glm::vec3 v;
    position->GetValue(position->mapped_index(draco::PointIndex(p)), &v.x);
    out.vertices.push_back(v);
  }
  for (uint32_t f = 0; f < mesh.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) out.indices.push_back(mesh.face(draco::FaceIndex(f))[k].value());
  return out;
}

TEST(ReorderedMesh, PlyAndDracoKeepTheHierarchyFaceOrder) {
  Cleanup cleanup;
  const TestMesh mesh = gridMesh(30, 20);
  const Hierarchy hierarchy = medianSplitHierarchy(mesh.view());
  const ClusterFile file = makeClusterFile(mesh.view(), {}, hierarchy, {});

  const auto ply = cleanup.add(scratch("reordered.ply"));
  writeReorderedMesh(mesh.view(), hierarchy, ply);
  const IndexedMesh fromPly = load(ply);
  expectHierarchyOrder(fromPly.positions, fromPly.indices, mesh.view(), hierarchy.faceOrder, 0.0f);
  EXPECT_EQ(fromPly.positions, file.vertices);
  EXPECT_EQ(fromPly.indices, file.indices);

  const auto drc = cleanup.add(scratch("reordered.drc"));
  writeReorderedMesh(mesh.view(), hierarchy, drc);
  const Decoded lossless = decodeDraco(drc);
  expectHierarchyOrder(lossless.vertices, lossless.indices, mesh.view(), hierarchy.faceOrder, 0.0f);
  EXPECT_EQ(lossless.indices, file.indices);  // point ids preserved

  MeshOutOptions quantized;
  quantized.dracoPositionBits = 14;
  writeReorderedMesh(file, drc, quantized);
  const Decoded lossy = decodeDraco(drc);
  expectHierarchyOrder(lossy.vertices, lossy.indices, mesh.view(), hierarchy.faceOrder, 40.0f / (1 << 13));
  EXPECT_EQ(lossy.indices, file.indices);

  EXPECT_THROW(writeReorderedMesh(file, cleanup.add(scratch("reordered.obj"))), std::invalid_argument);
}

// The real merge: build -> file -> read -> verify (boxes and side areas from computeBoxes),
// geometry against the mesh, every prefix valid, per-node sizes printed.
class RealMesh : public ::testing::TestWithParam<std::string> {};

TEST_P(RealMesh, BuildWriteReadVerify) {
  const auto path = shared(GetParam() + ".ply.zst");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " not present";
  Cleanup cleanup;
  const IndexedMesh mesh = load(path);
  const Hierarchy hierarchy = buildHierarchy(mesh.view());
  for (const RecastRule rule : {RecastRule::LargestArea, RecastRule::FewestNodes})
    for (const unsigned b : {2u, 4u, 8u}) {
      if (b == 2 && rule == RecastRule::FewestNodes) continue;
      SCOPED_TRACE("b = " + std::to_string(b));
      FileOptions options;
      options.branching = b;
      options.rule = rule;
      BranchingStats stats;
      const ClusterFile file = makeClusterFile(mesh.view(), mesh.originalFace, hierarchy, options, &stats);
      const auto fch = cleanup.add(scratch(GetParam() + ".fch"));
      writeClusterFile(fch, file);
      const ClusterFile back = readClusterFile(fch);
      ASSERT_EQ(back.nodes.size(), file.nodes.size());
      for (size_t j = 0; j < file.nodes.size(); ++j) ASSERT_TRUE(sameNode(back.nodes[j], file.nodes[j])) << j;
      const VerifyResult verified = verifyClusterFile(back);
      EXPECT_TRUE(verified.ok) << verified.message;
      const VerifyResult matches = verifyAgainstMesh(back, mesh.view(), mesh.originalFace);
      EXPECT_TRUE(matches.ok) << matches.message;
      const FchLayout layout = readClusterFileLayout(fch);
      uint64_t nodeBytes = 0, geometryBytes = 0;
      for (const FchFrame& f : layout.frames)
        (f.section == FchSection::Nodes ? nodeBytes : geometryBytes) += f.compressedBytes;
      std::printf(
          "%-18s b=%u %-11s tris %7zu nodes %7zu (eq85 %8.0f, %+5.1f%%) height %3u/%2u  node bytes %8llu "
          "(%.1f/node, raw 98+4b)  geometry %8llu (%.2f/tri)  file %llu\n",
          GetParam().c_str(), b, rule == RecastRule::LargestArea ? "largest" : "fewest",
          mesh.indices.size() / 3, file.nodes.size(), stats.eq85Nodes,
          100.0 * (double(stats.internalNodes) / stats.eq85Nodes - 1), stats.height, stats.balancedHeight,
          static_cast<unsigned long long>(nodeBytes), double(nodeBytes) / file.nodes.size(),
          static_cast<unsigned long long>(geometryBytes), double(geometryBytes) / (mesh.indices.size() / 3),
          static_cast<unsigned long long>(layout.fileBytes));
      // Prefixes, including 1.
      const auto cut = cleanup.add(scratch(GetParam() + "_cut.fch"));
      for (const uint64_t k : {uint64_t{1}, uint64_t{5000}, uint64_t{file.nodes.size() / 2}}) {
        truncateClusterFile(fch, cut, k);
        const VerifyResult prefix = verifyClusterFile(readClusterFile(cut));
        EXPECT_TRUE(prefix.ok) << "K = " << k << ": " << prefix.message;
      }
    }
}

INSTANTIATE_TEST_SUITE_P(Shared, RealMesh,
                         ::testing::Values("bunny_npm_lowres", "fandisk", "gears_cad", "rocker_arm"));

TEST(RealMesh, GeneratedTerrainWithShuffledFaces) {
  Cleanup cleanup;
  const auto ply = cleanup.add(scratch("terrain.ply"));
  GenerateOptions generate;
  generate.triangles = 20000;
  generate.shuffleFaces = generate.shuffleVertices = true;
  writeSyntheticMesh(SyntheticKind::Terrain, generate, ply);
  const IndexedMesh mesh = load(ply);
  const Hierarchy hierarchy = buildHierarchy(mesh.view());
  FileOptions options;
  options.branching = 4;
  const ClusterFile file = makeClusterFile(mesh.view(), mesh.originalFace, hierarchy, options);
  const auto fch = cleanup.add(scratch("terrain.fch"));
  writeClusterFile(fch, file);
  const ClusterFile back = readClusterFile(fch);
  const VerifyResult verified = verifyClusterFile(back);
  EXPECT_TRUE(verified.ok) << verified.message;
  EXPECT_TRUE(verifyAgainstMesh(back, mesh.view(), mesh.originalFace).ok);
  // The reordered mesh from the hierarchy and from the file are the same bytes.
  const auto a = cleanup.add(scratch("a.drc")), b = cleanup.add(scratch("b.drc"));
  writeReorderedMesh(mesh.view(), hierarchy, a);
  writeReorderedMesh(back, b);
  EXPECT_EQ(slurp(a), slurp(b));
}

}  // namespace
}  // namespace facetree
