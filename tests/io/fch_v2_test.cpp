// Version 2 of the cluster file: records within their stated bounds, compact boxes that always
// hold their faces within one step of the parent's grid, the same bytes for any writer threads,
// and version 1 files (written by the version 1 writer) read, verify and truncate.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/stream.h"
#include "fch_test_util.h"
#include "io/format/node_code.h"

namespace facetree {
namespace {

using namespace facetree::test;

const std::filesystem::path kVersion1 = std::filesystem::path(FACETREE_TEST_DATA) / "fch_v1";

// Every node's child face counts add up to its own, and a kept node child's is that child's count.
void expectChildFacesConsistent(const ClusterFile& file) {
  for (size_t j = 0; j < file.nodes.size(); ++j) {
    const FchNode& node = file.nodes[j];
    uint64_t sum = 0;
    for (unsigned c = 0; c < node.childCount; ++c) {
      sum += node.childFaces[c];
      const uint32_t ref = node.child[c];
      if (ref & kFaceChild) {
        EXPECT_EQ(node.childFaces[c], 1u) << "node " << j;
      } else if (!file.isCutOff(ref)) {
        EXPECT_EQ(node.childFaces[c], file.nodes[ref].count) << "node " << j;
      }
    }
    EXPECT_EQ(sum, node.count) << "node " << j;
  }
}

struct Version1Case {
  const char* file;
  const char* mesh;
  uint64_t nodes;
  bool truncated;
};

TEST(FchVersion1, FilesOfTheVersion1WriterReadVerifyAndTruncate) {
  Cleanup cleanup;
  for (const Version1Case& c : {Version1Case{"terrain_b2.fch", "terrain.ply.zst", 967, false},
                                Version1Case{"assembly_b4.fch", "assembly.ply.zst", 687, false},
                                Version1Case{"terrain_b8_truncated.fch", "terrain.ply.zst", 40, true},
                                Version1Case{"terrain_cells.fch", "terrain.ply.zst", 967, false}}) {
    SCOPED_TRACE(c.file);
    const std::filesystem::path path = kVersion1 / c.file;
    const ClusterFile file = readClusterFile(path);
    EXPECT_EQ(file.header.version, 1u);
    EXPECT_EQ(file.header.boxes, BoxPrecision::Exact);
    ASSERT_EQ(file.nodes.size(), c.nodes);
    const VerifyResult verified = verifyClusterFile(file);
    EXPECT_TRUE(verified.ok) << verified.message;
    const IndexedMesh mesh = load(kVersion1 / c.mesh);
    const VerifyResult same = verifyAgainstMesh(file, mesh.view(), mesh.originalFace);
    EXPECT_TRUE(same.ok) << same.message;
    expectChildFacesConsistent(file);
    bool anyTruncated = false;
    for (const FchNode& node : file.nodes) anyTruncated |= (node.flags & kFchTruncated) != 0;
    EXPECT_EQ(anyTruncated, c.truncated);
    // Truncation keeps the version and the kept records.
    const auto cut = cleanup.add(scratch("v1_cut.fch"));
    const TruncateResult kept = truncateClusterFile(path, cut, c.nodes / 2);
    const ClusterFile back = readClusterFile(cut);
    EXPECT_EQ(back.header.version, 1u);
    ASSERT_EQ(back.nodes.size(), kept.nodes);
    for (size_t j = 0; j < back.nodes.size(); ++j) {
      EXPECT_EQ(back.nodes[j].cost, file.nodes[j].cost);
      EXPECT_EQ(back.nodes[j].box.orientation, file.nodes[j].box.orientation);
      EXPECT_EQ(back.nodes[j].sumNormal, file.nodes[j].sumNormal);
    }
    EXPECT_TRUE(verifyClusterFile(back).ok) << verifyClusterFile(back).message;
    expectChildFacesConsistent(back);
  }
}

// A bumpy, folded surface whose clusters take tilted frames.
TestMesh foldedGrid() {
  TestMesh mesh = gridMesh(40, 30, 0.4f);
  for (glm::vec3& p : mesh.positions) p.z += 0.05f * std::sin(7 * p.x) * std::cos(5 * p.y) + 3.0f;
  return mesh;
}

ClusterFile buildFile(const TestMesh& mesh, BoxPrecision boxes, unsigned branching) {
  BuildOptions build;
  build.boxes = boxes;
  const Hierarchy hierarchy = buildHierarchy(mesh.view(), build);
  FileOptions options;
  options.branching = branching;
  options.build = build;
  return makeClusterFile(mesh.view(), {}, hierarchy, options);
}

TEST(FchVersion2, CompactBoxesHoldTheExactOnesWithinOneStepOfTheParentsGrid) {
  Cleanup cleanup;
  const TestMesh mesh = foldedGrid();
  for (unsigned branching : {2u, 4u, 8u}) {
    SCOPED_TRACE(branching);
    const ClusterFile file = buildFile(mesh, BoxPrecision::Compact, branching);
    const auto path = cleanup.add(scratch("compact.fch"));
    writeClusterFile(path, file);
    const ClusterFile back = readClusterFile(path);
    EXPECT_EQ(back.header.boxes, BoxPrecision::Compact);
    ASSERT_EQ(back.nodes.size(), file.nodes.size());
    const VerifyResult verified = verifyClusterFile(back);
    ASSERT_TRUE(verified.ok) << verified.message;
    std::vector<uint32_t> parent(back.nodes.size(), 0);
    for (uint32_t j = 0; j < back.nodes.size(); ++j)
      for (unsigned c = 0; c < back.nodes[j].childCount; ++c)
        if (!(back.nodes[j].child[c] & kFaceChild)) parent[back.nodes[j].child[c]] = j;
    double looser = 0;
    for (size_t j = 0; j < back.nodes.size(); ++j) {
      const NodeBox &exact = file.nodes[j].box, &compact = back.nodes[j].box;
      ASSERT_TRUE(compact.orientation == exact.orientation);
      const glm::mat3 axes = glm::mat3_cast(exact.orientation);
      double step[3] = {0, 0, 0};
      if (j > 0) fch::compactStep(back.nodes[parent[j]].box, compact.orientation, step);
      for (int a = 0; a < 3; ++a) {
        const glm::dvec3 axis(axes[a]);
        const double e = glm::dot(glm::dvec3(exact.center), axis),
                     q = glm::dot(glm::dvec3(compact.center), axis);
        const double tolerance = 1e-6 * (std::abs(e) + exact.halfExtent[a]);
        // Holds the exact box, each face at most a step (and rounding) beyond it.
        EXPECT_LE(q - compact.halfExtent[a], e - exact.halfExtent[a] + tolerance) << j;
        EXPECT_GE(q + compact.halfExtent[a], e + exact.halfExtent[a] - tolerance) << j;
        EXPECT_LE(e - exact.halfExtent[a] - (q - compact.halfExtent[a]), step[a] + tolerance) << j;
        EXPECT_LE(q + compact.halfExtent[a] - (e + exact.halfExtent[a]), step[a] + tolerance) << j;
        looser = std::max(looser, double(compact.halfExtent[a]) - exact.halfExtent[a]);
      }
    }
    EXPECT_GT(looser, 0.0);  // quantised, not copied
  }
}

TEST(FchVersion2, ExactBoxesStillTouchTheirFacesAndCompactFilesAreSmaller) {
  Cleanup cleanup;
  const TestMesh mesh = foldedGrid();
  const auto exactPath = cleanup.add(scratch("exact.fch")), compactPath = cleanup.add(scratch("compact.fch"));
  writeClusterFile(exactPath, buildFile(mesh, BoxPrecision::Exact, 2));
  writeClusterFile(compactPath, buildFile(mesh, BoxPrecision::Compact, 2));
  const ClusterFile exact = readClusterFile(exactPath);
  EXPECT_EQ(exact.header.version, kFchVersion);
  const VerifyResult verified = verifyClusterFile(exact);  // containment and tightness
  EXPECT_TRUE(verified.ok) << verified.message;
  uint64_t exactNodes = 0, compactNodes = 0;
  for (const FchFrame& f : readClusterFileLayout(exactPath).frames)
    if (f.section == FchSection::Nodes) exactNodes += f.compressedBytes;
  for (const FchFrame& f : readClusterFileLayout(compactPath).frames)
    if (f.section == FchSection::Nodes) compactNodes += f.compressedBytes;
  EXPECT_LT(compactNodes, exactNodes * 0.8);
}

TEST(FchVersion2, AnOrientationOffTheLatticeIsRefusedNamingTheNode) {
  Cleanup cleanup;
  ClusterFile file = buildFile(foldedGrid(), BoxPrecision::Exact, 2);
  file.nodes[3].box.orientation = glm::normalize(glm::quat(0.9f, 0.1f, 0.2f, 0.3f));
  try {
    writeClusterFile(cleanup.add(scratch("off.fch")), file);
    FAIL() << "written";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("node 3: box orientation off the stored lattice"), std::string::npos)
        << e.what();
  }
  // Exact lattice orientations in a compact file: the 8-bit lattice does not hold them.
  file = buildFile(foldedGrid(), BoxPrecision::Exact, 2);
  file.header.boxes = BoxPrecision::Compact;
  EXPECT_THROW(writeClusterFile(cleanup.add(scratch("mixed.fch")), file), std::invalid_argument);
}

TEST(FchVersion2, TheSameBytesForAnyWriterThreadsAndFrameBatching) {
  Cleanup cleanup;
  for (BoxPrecision boxes : {BoxPrecision::Exact, BoxPrecision::Compact}) {
    const ClusterFile file = buildFile(foldedGrid(), boxes, 4);
    std::string first;
    for (unsigned threads : {1u, 2u, 5u}) {
      WriteOptions options;
      options.threads = threads;
      options.nodesPerFrame = 64;
      const auto path = cleanup.add(scratch("threads.fch"));
      writeClusterFile(path, file, options);
      const std::string bytes = slurp(path);
      if (first.empty()) first = bytes;
      EXPECT_EQ(bytes, first) << threads << " threads";
    }
  }
}

// The header of a writer of `file`'s counts.
StreamFileInfo infoOf(const ClusterFile& file) {
  StreamFileInfo info;
  info.header = file.header;
  info.header.nodeCount = file.nodes.size();
  info.header.triangleCount = file.originalFace.size();
  info.header.vertexCount = file.vertices.size();
  info.maxOriginalFace = *std::max_element(file.originalFace.begin(), file.originalFace.end());
  return info;
}

// `file` written as runs of 1 to 37 nodes, every third one added as nodes instead.
void writeAsRuns(const std::filesystem::path& path, const ClusterFile& file, WriteOptions options,
                 unsigned seed) {
  const std::span<const FchNode> nodes = file.nodes;
  const BoxPrecision lattice = file.header.boxes;
  ClusterFileWriter writer(path, infoOf(file), options);
  std::mt19937 rng(seed);
  for (size_t first = 0, k = 0; first < nodes.size(); ++k) {
    const size_t n = std::min<size_t>(nodes.size() - first, 1 + rng() % 37);
    if (k % 3 == 2)
      writer.addNodes(nodes.subspan(first, n));
    else
      writer.addNodeRun(encodeNodeRun(nodes.subspan(first, n), first, lattice), n, first,
                        [](uint64_t i) { return static_cast<uint32_t>(i); });
    first += n;
  }
  writer.addVertices(file.vertices);
  writer.addTriangles(file.indices, file.originalFace);
  writer.finish();
}

TEST(FchVersion2, NodeRunsReadBackAsTheirNodesWithinTheFilesBounds) {
  Cleanup cleanup;
  for (BoxPrecision boxes : {BoxPrecision::Exact, BoxPrecision::Compact})
    for (unsigned branching : {2u, 8u}) {
      SCOPED_TRACE(std::to_string(branching) + (boxes == BoxPrecision::Exact ? " exact" : " compact"));
      const ClusterFile file = buildFile(foldedGrid(), boxes, branching);
      const auto path = cleanup.add(scratch("as_runs.fch"));
      WriteOptions options;
      options.nodesPerFrame = 16;
      writeAsRuns(path, file, options, branching);
      const ClusterFile back = readClusterFile(path);
      const VerifyResult verified = verifyClusterFile(back);
      EXPECT_TRUE(verified.ok) << verified.message;
      ASSERT_EQ(back.nodes.size(), file.nodes.size());
      for (size_t i = 0; i < file.nodes.size(); ++i) {
        FchNode node = back.nodes[i];
        if (boxes == BoxPrecision::Compact) {
          // A compact box is judged by verify (it holds the faces, each face of it within a step of
          // the exact box's); the rest as exact boxes.
          node.box.center = file.nodes[i].box.center;
          node.box.halfExtent = file.nodes[i].box.halfExtent;
        }
        ASSERT_TRUE(sameNode(node, file.nodes[i])) << i;
      }
    }
}

// Compact boxes quantised ahead of the write (compactNodeRun, a tree's runs in order against the
// decoded boxes of their parents) give the bytes of the same runs quantised by the writer as they
// arrive, and a compact record for the root, whose box goes in the header, is refused.
TEST(FchVersion2, CompactRunsMadeAheadGiveTheBytesTheWriterMakes) {
  Cleanup cleanup;
  for (unsigned branching : {2u, 8u}) {
    const ClusterFile file = buildFile(foldedGrid(), BoxPrecision::Compact, branching);
    const auto byWriter = cleanup.add(scratch("compact_by_writer.fch")),
               ahead = cleanup.add(scratch("compact_ahead.fch"));
    WriteOptions options;
    options.nodesPerFrame = 16;
    const std::span<const FchNode> nodes = file.nodes;
    const auto identity = [](uint64_t i) { return static_cast<uint32_t>(i); };
    // The root as a node, the rest in runs of 1 to 37 nodes: exact records that the writer quantises
    // as they arrive, or compact records made ahead.
    for (const bool madeAhead : {false, true}) {
      ClusterFileWriter writer(madeAhead ? ahead : byWriter, infoOf(file), options);
      writer.addNodes(nodes.first(1));
      std::vector<NodeBox> parentBox(nodes.size());
      const NodeBox root = compactDecodedBox(nodes[0].box, nullptr);
      for (unsigned c = 0; c < nodes[0].childCount; ++c)
        if (!(nodes[0].child[c] & kFaceChild)) parentBox[nodes[0].child[c]] = root;
      std::mt19937 rng(branching);
      for (size_t first = 1; first < nodes.size();) {
        const size_t n = std::min<size_t>(nodes.size() - first, 1 + rng() % 37);
        const std::string run = encodeNodeRun(nodes.subspan(first, n), first, BoxPrecision::Compact);
        if (madeAhead)
          writer.addNodeRun(compactNodeRun(run, n, first, parentBox), n, first, identity,
                            BoxPrecision::Compact);
        else
          writer.addNodeRun(run, n, first, identity);
        first += n;
      }
      writer.addVertices(file.vertices);
      writer.addTriangles(file.indices, file.originalFace);
      writer.finish();
    }
    EXPECT_TRUE(slurp(ahead) == slurp(byWriter)) << branching;
    const VerifyResult verified = verifyClusterFile(readClusterFile(ahead));
    EXPECT_TRUE(verified.ok) << verified.message;
    // The root as a compact record: refused.
    std::vector<NodeBox> parentBox(nodes.size());
    parentBox[0] = compactDecodedBox(nodes[0].box, nullptr);  // a box that holds the root's
    const std::string top =
        compactNodeRun(encodeNodeRun(nodes.first(1), 0, BoxPrecision::Compact), 1, 0, parentBox);
    try {
      ClusterFileWriter writer(cleanup.add(scratch("compact_root.fch")), infoOf(file), options);
      writer.addNodeRun(top, 1, 0, identity, BoxPrecision::Compact);
      ADD_FAILURE() << "added";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("node 0: the root's box goes in the header"), std::string::npos)
          << e.what();
    }
  }
}

TEST(FchVersion2, NodeRunsAddedAsRecordsGiveTheBytesOfTheirNodes) {
  Cleanup cleanup;
  const ClusterFile file = buildFile(foldedGrid(), BoxPrecision::Exact, 4);
  const auto whole = cleanup.add(scratch("whole_runs.fch")), runs = cleanup.add(scratch("runs.fch"));
  WriteOptions options;
  options.nodesPerFrame = 16;
  writeClusterFile(whole, file, options);
  for (const unsigned threads : {1u, 3u}) {
    options.threads = threads;
    writeAsRuns(runs, file, options, threads);
    EXPECT_EQ(slurp(runs), slurp(whole)) << threads << " threads";
  }
  // A child placed before its parent, a run cut short and a run of fewer records than said are refused.
  const std::span<const FchNode> nodes = file.nodes;
  const std::string run = encodeNodeRun(nodes.first(3), 0, BoxPrecision::Exact);
  const auto identity = [](uint64_t i) { return static_cast<uint32_t>(i); };
  const auto refused = [&](BoxPrecision boxes, std::string_view bytes, size_t n,
                           const std::function<uint32_t(uint64_t)>& place, const std::string& expected) {
    StreamFileInfo bad = infoOf(file);
    bad.header.boxes = boxes;
    try {
      ClusterFileWriter writer(cleanup.add(scratch("bad_runs.fch")), bad);
      writer.addNodeRun(bytes, n, 0, place);
      ADD_FAILURE() << "added";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  };
  for (const BoxPrecision boxes : {BoxPrecision::Exact, BoxPrecision::Compact}) {
    refused(
        boxes, run, 3, [](uint64_t) { return 0u; }, "node 0: child 0 not after it");
    refused(boxes, std::string_view(run).substr(0, run.size() - 1), 3, identity, "node run: ");
    refused(boxes, run, 4, identity, "node run: ");
  }
}

// A file made in pieces by independent writers (the geometry in one, the nodes in pieces of three
// frames, node runs cut at the pieces' borders, a compact file's parents in other pieces given by
// addParentBox) and assembled in any order: the bytes of one writer given the same runs and nodes.
// Pieces that leave a gap are refused naming the piece.
TEST(FchVersion2, PiecesAssembleToTheBytesOfOneWriter) {
  Cleanup cleanup;
  for (BoxPrecision boxes : {BoxPrecision::Exact, BoxPrecision::Compact})
    for (unsigned branching : {2u, 8u}) {
      SCOPED_TRACE(std::to_string(branching) + (boxes == BoxPrecision::Exact ? " exact" : " compact"));
      const ClusterFile file = buildFile(foldedGrid(), boxes, branching);
      const std::span<const FchNode> nodes = file.nodes;
      WriteOptions options;
      options.nodesPerFrame = 16;
      options.geometryPerFrame = 64;
      const auto identity = [](uint64_t i) { return static_cast<uint32_t>(i); };
      // The nodes as segments of 1 to 37: added as nodes (the root, every third) or as a run.
      struct Segment {
        size_t first, n;
        bool run;
      };
      std::vector<Segment> segments;
      std::mt19937 rng(branching);
      for (size_t first = 0, k = 0; first < nodes.size(); ++k) {
        const size_t n = std::min<size_t>(nodes.size() - first, 1 + rng() % 37);
        segments.push_back({first, n, first > 0 && k % 3 != 2});
        first += n;
      }
      // Compact: the decoded box of every node's parent as the writer meets them (a run's from its
      // records, as compactNodeRun makes them ahead).
      std::vector<NodeBox> parentBox(nodes.size());
      std::vector<std::string> records(segments.size());
      for (size_t k = 0; k < segments.size(); ++k) {
        const Segment& g = segments[k];
        if (g.run) {
          records[k] = encodeNodeRun(nodes.subspan(g.first, g.n), g.first, boxes);
          if (boxes == BoxPrecision::Compact)
            records[k] = compactNodeRun(records[k], g.n, g.first, parentBox);
          continue;
        }
        if (boxes != BoxPrecision::Compact) continue;
        for (size_t i = g.first; i < g.first + g.n; ++i) {
          const NodeBox decoded = compactDecodedBox(nodes[i].box, i == 0 ? nullptr : &parentBox[i]);
          for (unsigned c = 0; c < nodes[i].childCount; ++c)
            if (!(nodes[i].child[c] & kFaceChild)) parentBox[nodes[i].child[c]] = decoded;
        }
      }
      // Nodes [first, end) into `writer`, the segments cut to them.
      const auto addNodes = [&](ClusterFileWriter& writer, size_t first, size_t end) {
        for (size_t k = 0; k < segments.size(); ++k) {
          const Segment& g = segments[k];
          const size_t from = std::max(first, g.first), to = std::min(end, g.first + g.n);
          if (from >= to) continue;
          if (!g.run)
            writer.addNodes(nodes.subspan(from, to - from));
          else
            writer.addNodeRun(records[k], g.n, g.first, identity, boxes, from - g.first, to - from);
        }
      };
      const auto whole = cleanup.add(scratch("pieces_whole.fch"));
      {
        ClusterFileWriter writer(whole, infoOf(file), options);
        // Compact: the boxes of parents that came as compact records, which the writer does not decode.
        if (boxes == BoxPrecision::Compact)
          for (size_t i = 1; i < nodes.size(); ++i) writer.addParentBox(i, parentBox[i]);
        addNodes(writer, 0, nodes.size());
        writer.addVertices(file.vertices);
        writer.addTriangles(file.indices, file.originalFace);
        writer.finish();
      }
      std::vector<std::filesystem::path> pieces;
      {
        PieceRange geometry;
        geometry.endVertex = file.vertices.size();
        geometry.endTriangle = file.originalFace.size();
        WriteOptions o = options;
        o.piece = geometry;
        pieces.push_back(cleanup.add(scratch("piece_geometry")));
        ClusterFileWriter writer(pieces.back(), infoOf(file), o);
        writer.addVertices(file.vertices);
        writer.addTriangles(file.indices, file.originalFace);
        writer.finish();
      }
      const size_t per = 3 * options.nodesPerFrame;
      for (size_t first = 0; first < nodes.size(); first += per) {
        const size_t end = std::min(nodes.size(), first + per);
        PieceRange range;
        range.firstNode = first;
        range.endNode = end;
        WriteOptions o = options;
        o.piece = range;
        pieces.push_back(cleanup.add(scratch("piece_nodes_" + std::to_string(first))));
        ClusterFileWriter writer(pieces.back(), infoOf(file), o);
        if (boxes == BoxPrecision::Compact)  // and those in other pieces
          for (size_t i = std::max<size_t>(first, 1); i < end; ++i) writer.addParentBox(i, parentBox[i]);
        addNodes(writer, first, end);
        writer.finish();
      }
      std::shuffle(pieces.begin(), pieces.end(), rng);
      const auto assembled = cleanup.add(scratch("pieces_assembled.fch"));
      EXPECT_EQ(assembleClusterFile(assembled, infoOf(file), options, pieces),
                std::filesystem::file_size(whole));
      EXPECT_TRUE(slurp(assembled) == slurp(whole));
      const VerifyResult verified = verifyClusterFile(readClusterFile(assembled));
      EXPECT_TRUE(verified.ok) << verified.message;

      const std::filesystem::path gone = pieces.back();
      pieces.pop_back();
      try {
        assembleClusterFile(assembled, infoOf(file), options, pieces);
        ADD_FAILURE() << "assembled without " << gone;
      } catch (const Error& e) {
        EXPECT_EQ(e.category(), ErrorCategory::Input);
        const std::string what = e.what();
        EXPECT_TRUE(what.find("leave a gap") != std::string::npos ||
                    what.find("the pieces hold") != std::string::npos)
            << what;
      }
    }
}

}  // namespace
}  // namespace facetree
