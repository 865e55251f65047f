// Internal to io/: the cluster file as a source of passes, whole in memory (a ClusterFile) or read
// lazily under a cap (a ClusterFileReader), so that verify, the cut's fit and the branching
// statistics are written once and give the same figures from either.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <vector>

#include "facetree/io.h"

namespace facetree {
// The cap a reader holds: the one asked for, else the one the file was built under, else the
// build's default (read/lazy_reader.cpp).
uint64_t readerMemory(const ReaderOptions& options, const FileHeader& header);
}  // namespace facetree

namespace facetree::fch {

// Triangles [first, first + indices.size() / 3) of the face order: their corners index `vertices`
// (the piece's own, from a reader; the file's, in memory), with their original ids unless the
// pass asked for the geometry alone.
struct FacePiece {
  uint64_t first = 0;
  std::span<const glm::vec3> vertices;
  std::span<const uint32_t> indices;
  std::span<const uint64_t> originalFace;
};

class ClusterSource {
 public:
  virtual ~ClusterSource() = default;
  virtual const FileHeader& header() const = 0;
  virtual uint64_t nodeCount() const = 0;
  // Node `index` alone (a version 1 cut places its members by their own records).
  virtual FchNode node(uint64_t index) = 0;
  // As ClusterFileReader's: nodes in file order with their depths (the root's is 1) and every
  // child's face count (childFaces), until visit returns false.
  virtual uint64_t forEachNode(const std::function<bool(uint64_t, const FchNode&, uint32_t)>& visit,
                               NodeFields fields = NodeFields::All) = 0;
  virtual void forEachVertexFrame(const std::function<void(uint64_t, std::span<const glm::vec3>)>& visit) = 0;
  virtual void forEachFacePiece(const std::function<void(const FacePiece&)>& visit,
                                FaceFields fields = FaceFields::All) = 0;
  // What a pass may hold, and where it spills the rest.
  virtual uint64_t memoryBytes() const = 0;
  virtual std::filesystem::path temporaryDirectory() const = 0;
};

class ReaderSource final : public ClusterSource {
 public:
  explicit ReaderSource(ClusterFileReader& reader) : reader_(reader) {}
  const FileHeader& header() const override { return reader_.header(); }
  uint64_t nodeCount() const override { return reader_.size(); }
  FchNode node(uint64_t index) override { return reader_.node(index); }
  uint64_t forEachNode(const std::function<bool(uint64_t, const FchNode&, uint32_t)>& visit,
                       NodeFields fields) override {
    return reader_.forEachNode(visit, fields);
  }
  void forEachVertexFrame(const std::function<void(uint64_t, std::span<const glm::vec3>)>& visit) override {
    reader_.forEachVertexFrame(visit);
  }
  void forEachFacePiece(const std::function<void(const FacePiece&)>& visit, FaceFields fields) override {
    reader_.forEachFacePiece(
        [&](const FaceRangeMesh& mesh) {
          visit({mesh.first, mesh.vertices, mesh.indices, mesh.originalFace});
        },
        fields);
  }
  uint64_t memoryBytes() const override { return reader_.memoryBytes(); }
  std::filesystem::path temporaryDirectory() const override { return reader_.temporaryDirectory(); }

 private:
  ClusterFileReader& reader_;
};

// A ClusterFile as a source: its header with the counts of its arrays (a file in memory may hold
// its nodes alone), its nodes with their depths and children's face counts, its triangles in
// pieces of kPieceFaces, and the cap a reader of the file would hold (the one it
// was built under, else the default). Its face pieces are views of its arrays.
class MemorySource final : public ClusterSource {
 public:
  static constexpr uint64_t kPieceFaces = uint64_t{1} << 18;
  explicit MemorySource(const ClusterFile& file) : file_(file), header_(file.header) {
    header_.nodeCount = file.nodes.size();
    header_.triangleCount = file.indices.size() / 3;
    header_.vertexCount = file.vertices.size();
  }
  const FileHeader& header() const override { return header_; }
  FchNode node(uint64_t index) override { return file_.nodes[index]; }
  uint64_t nodeCount() const override { return file_.nodes.size(); }
  uint64_t forEachNode(const std::function<bool(uint64_t, const FchNode&, uint32_t)>& visit,
                       NodeFields fields) override;
  void forEachVertexFrame(const std::function<void(uint64_t, std::span<const glm::vec3>)>& visit) override {
    visit(0, file_.vertices);
  }
  void forEachFacePiece(const std::function<void(const FacePiece&)>& visit, FaceFields fields) override;
  uint64_t memoryBytes() const override;
  std::filesystem::path temporaryDirectory() const override { return {}; }

 private:
  const ClusterFile& file_;
  FileHeader header_;
};

// The cuts of ClusterFileReader (cut, cutByCost, cutByDepth) over any source: the frontier of the
// shortest node prefix with at least `clusters` members, of the nodes whose effective cost exceeds
// `maxCost`, of the nodes of depth below `depth`.
std::vector<CutCluster> prefixCut(ClusterSource& source, uint64_t clusters);
std::vector<CutCluster> costCut(ClusterSource& source, double maxCost);
std::vector<CutCluster> depthCut(ClusterSource& source, uint32_t depth);

}  // namespace facetree::fch
