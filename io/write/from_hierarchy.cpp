// The cluster file of a binary hierarchy: its nodes recast to the file's branching
// (recastHierarchy), its geometry reordered, built whole (makeClusterFile) or streamed into a
// ClusterFileWriter (writeClusterFile) without holding the file.
#include <algorithm>
#include <future>
#include <optional>
#include <stdexcept>

#include "facetree/io.h"
#include "mesh/reordered_mesh.h"
#include "shape/file_shape.h"
#include "shape/hierarchy_check.h"

namespace facetree {
namespace {

// The nodes of the cluster file of a hierarchy, one at a time in file order. For b = 2 the
// recast is the identity (every binary node kept, its two children sorted by face range, its
// join flag its own), so no tree is built: the nodes come straight from the hierarchy.
class FileNodes {
 public:
  FileNodes(const Hierarchy& hierarchy, const FileOptions& options) : hierarchy_(hierarchy) {
    if (options.branching == 2)
      checkHierarchy(hierarchy, 2);
    else
      tree_ = recastHierarchy(hierarchy, options.branching, options.rule);
  }
  size_t size() const { return tree_ ? tree_->binaryNode.size() : hierarchy_.nodes.size(); }
  // Node j's child references, in no particular order, into `child`; returns their number.
  unsigned children(size_t j, uint32_t* child) const {
    if (tree_) return std::copy_n(tree_->child[j].begin(), tree_->childCount[j], child) - child;
    std::copy_n(hierarchy_.nodes[j].child, 2, child);
    return 2;
  }
  // Nodes first ... first + out.size() - 1. For b = 2 each node looks at its first child, a random
  // read: the child of the node kAhead places on is fetched early, so that the misses overlap.
  void fill(size_t first, std::span<FchNode> out) const {
    constexpr size_t kAhead = 16;
    for (size_t i = 0; i < out.size(); ++i) {
      if (!tree_ && i + kAhead < out.size()) {
        const uint32_t c0 = hierarchy_.nodes[first + i + kAhead].child[0];
        if (!(c0 & kFaceChild)) __builtin_prefetch(&hierarchy_.nodes[c0]);
      }
      out[i] = (*this)[first + i];
    }
  }
  FchNode operator[](size_t j) const {
    const uint32_t binary = tree_ ? tree_->binaryNode[j] : static_cast<uint32_t>(j);
    const Node& b = hierarchy_.nodes[binary];
    FchNode node;
    node.first = b.first;
    node.count = b.count;
    bool joined;
    if (tree_) {
      node.childCount = tree_->childCount[j];
      std::copy_n(tree_->child[j].begin(), node.childCount, node.child);
      joined = tree_->joinFlag[j];
      for (unsigned c = 0; c < node.childCount; ++c) node.childFaces[c] = faces(node.child[c]);
    } else {
      // The two children split the node's faces: one look at the first child (a random read, the
      // cost of this loop) gives the order and both face counts.
      const uint32_t c0 = b.child[0];
      const bool face0 = (c0 & kFaceChild) != 0;
      const uint32_t start0 = face0 ? c0 & ~kFaceChild : hierarchy_.nodes[c0].first;
      const uint32_t faces0 = face0 ? 1 : hierarchy_.nodes[c0].count;
      const bool swap = start0 != b.first;
      node.childCount = 2;
      node.child[0] = b.child[swap ? 1 : 0];
      node.child[1] = b.child[swap ? 0 : 1];
      node.childFaces[swap ? 1 : 0] = faces0;
      node.childFaces[swap ? 0 : 1] = b.count - faces0;
      joined = (b.flags & kNodeJoinsDisjointSurfaces) != 0;
    }
    node.flags = static_cast<uint8_t>((b.flags & kNodeFlatFrame ? kFchFlatFrame : 0) |
                                      (joined ? kFchJoinsDisjointSurfaces : 0));
    node.cost = b.cost;
    node.area = b.area;
    node.perimeter = b.perimeter;
    node.sumNormal = b.sumNormal;
    // Same face range: the exact box of the b-ary node. The writers require boxes
    // (checkFileInputs); branchingStats of a hierarchy built without them needs none.
    if (binary < hierarchy_.boxes.size()) node.box = hierarchy_.boxes[binary];
    return node;
  }

 private:
  // Faces under a child reference of the file (a face, or a file node index).
  uint32_t faces(uint32_t ref) const {
    if (ref & kFaceChild) return 1;
    return hierarchy_.nodes[tree_ ? tree_->binaryNode[ref] : ref].count;
  }
  const Hierarchy& hierarchy_;
  std::optional<RecastTree> tree_;
};

void checkFileInputs(const MeshView& mesh, std::span<const uint64_t> originalFace, const Hierarchy& hierarchy,
                     const char* caller) {
  const size_t triangles = mesh.triangleCount();
  if (hierarchy.faceOrder.size() != triangles)
    throw std::invalid_argument(std::string(caller) + ": the hierarchy's face order does not match the mesh");
  if (!originalFace.empty() && originalFace.size() != triangles)
    throw std::invalid_argument(std::string(caller) + ": one original face id per triangle expected");
  if (hierarchy.boxes.size() != hierarchy.nodes.size())
    throw std::invalid_argument(std::string(caller) +
                                ": the hierarchy has no boxes (BuildOptions::computeBoxes)");
}

}  // namespace

FileHeader optionsHeader(const FileOptions& options) {
  FileHeader h;
  h.branching = options.branching;
  h.metric = options.build.metric;
  h.k = options.build.k;
  h.flatThreshold = options.build.flatThreshold;
  h.garlandWeights[0] = options.build.garlandFitWeight;
  h.garlandWeights[1] = options.build.garlandDirWeight;
  h.garlandWeights[2] = options.build.garlandShapeWeight;
  h.memoryCapBytes = options.memoryCapBytes;
  h.boxes = options.build.boxes;
  h.topClusters = options.build.metric == Metric::Constant ? 0 : options.build.topClusters;
  return h;
}

ClusterFile makeClusterFile(const MeshView& mesh, std::span<const uint64_t> originalFace,
                            const Hierarchy& hierarchy, const FileOptions& options, BranchingStats* stats) {
  checkFileInputs(mesh, originalFace, hierarchy, "makeClusterFile");
  const FileNodes nodes(hierarchy, options);
  ClusterFile file;
  file.header = optionsHeader(options);
  file.nodes.resize(nodes.size());
  for (size_t j = 0; j < nodes.size(); ++j) file.nodes[j] = nodes[j];
  ReorderedGeometry geometry = reorderGeometry(mesh, hierarchy.faceOrder);
  file.vertices = std::move(geometry.vertices);
  file.indices = std::move(geometry.indices);
  const size_t triangles = mesh.triangleCount();
  file.originalFace.resize(triangles);
  for (size_t i = 0; i < triangles; ++i) {
    const uint32_t t = hierarchy.faceOrder[i];
    file.originalFace[i] = originalFace.empty() ? t : originalFace[t];
  }
  FileHeader& h = file.header;
  h.nodeCount = h.originalNodeCount = file.nodes.size();
  h.triangleCount = triangles;
  h.vertexCount = file.vertices.size();
  if (stats) *stats = branchingStats(file);
  return file;
}

uint64_t writeClusterFile(const std::filesystem::path& path, const MeshView& mesh,
                          std::span<const uint64_t> originalFace, const Hierarchy& hierarchy,
                          const FileOptions& options, const WriteOptions& writeOptions,
                          BranchingStats* stats) {
  checkFileInputs(mesh, originalFace, hierarchy, "writeClusterFile");
  const size_t triangles = mesh.triangleCount();
  const std::span<const uint32_t> order = hierarchy.faceOrder;
  // The numbering by first use along the face order (random reads), which only the vertex and
  // triangle frames need, and the file's shape are made beside the node frames (on this thread
  // when the write has one); the numbering starts first, beside the hierarchy's check. The header
  // declares the vertex count: the vertices some face uses, counted in memory order.
  const std::launch beside = writeOptions.threads == 1 ? std::launch::deferred : std::launch::async;
  struct Numbered {
    FirstUseNumbering numbering;
    std::vector<uint32_t> vertexOf;  // the input vertex of each number: any run of vertices made alone
  };
  auto numbered = std::async(beside, [&] {
    Numbered out{numberByFirstUse(mesh, order), {}};
    out.vertexOf.resize(out.numbering.vertexCount);
    for (size_t v = 0; v < out.numbering.remap.size(); ++v)
      if (out.numbering.remap[v] != kUnusedVertex)
        out.vertexOf[out.numbering.remap[v]] = static_cast<uint32_t>(v);
    return out;
  });
  const FileNodes nodes(hierarchy, options);
  const uint32_t vertexCount = usedVertexCount(mesh);
  std::future<BranchingStats> shaped;
  if (stats)
    shaped = std::async(beside, [&] {
      FileShape shape(options.branching, triangles, nodes.size());
      constexpr size_t kAhead = 16;
      uint32_t child[kMaxBranching];
      for (size_t j = 0; j < nodes.size(); ++j) {
        if (j + kAhead < nodes.size()) shape.prefetch(nodes.children(j + kAhead, child), child);
        shape.add(j, nodes.children(j, child), child);
      }
      return shape.stats();
    });
  Numbered numbering;  // before the writer: its workers read it until the writer goes
  StreamFileInfo info;
  info.header = optionsHeader(options);
  info.header.nodeCount = info.header.originalNodeCount = nodes.size();
  info.header.triangleCount = triangles;
  info.header.vertexCount = vertexCount;
  if (originalFace.empty())
    info.maxOriginalFace = triangles > 0 ? triangles - 1 : 0;
  else
    info.maxOriginalFace = *std::max_element(originalFace.begin(), originalFace.end());
  ClusterFileWriter writer(path, info, writeOptions);

  // Every frame is made from the hierarchy and the mesh alone, so the writer's workers make them
  // (node records, gathered geometry) as well as compress them; this thread only places them.
  writer.addNodes(nodes.size(), [&nodes](uint64_t first, std::span<FchNode> out) { nodes.fill(first, out); });
  numbering = numbered.get();
  if (numbering.numbering.vertexCount != vertexCount)
    throw std::invalid_argument("writeClusterFile: the face order does not hold every face once");
  const std::span<const uint32_t> remap = numbering.numbering.remap, vertexOf = numbering.vertexOf;
  writer.addVertices(vertexCount, [&mesh, vertexOf](uint64_t first, std::span<glm::vec3> out) {
    for (size_t i = 0; i < out.size(); ++i) out[i] = mesh.positions[vertexOf[first + i]];
  });
  writer.addTriangles(
      triangles,
      [&mesh, order, remap](uint64_t first, std::span<uint32_t> out) {
        for (size_t i = 0; i < out.size() / 3; ++i) {
          const size_t t = order[first + i];
          for (size_t k = 0; k < 3; ++k) out[3 * i + k] = remap[mesh.indices[3 * t + k]];
        }
      },
      [order, originalFace](uint64_t first, std::span<uint64_t> out) {
        for (size_t i = 0; i < out.size(); ++i) {
          const uint32_t t = order[first + i];
          out[i] = originalFace.empty() ? t : originalFace[t];
        }
      });
  if (stats) *stats = shaped.get();
  return writer.finish();
}

BranchingStats branchingStats(const Hierarchy& hierarchy, const FileOptions& options) {
  const FileNodes nodes(hierarchy, options);
  const uint64_t triangles = hierarchy.faceOrder.size();
  FileShape shape(options.branching, triangles, nodes.size());
  for (size_t j = 0; j < nodes.size(); ++j) shape.add(j, nodes[j]);
  return shape.stats();
}

}  // namespace facetree
