// The cluster file of a binary hierarchy: its nodes recast to the file's branching
// (recastHierarchy), its geometry reordered, built whole (makeClusterFile) or streamed into a
// ClusterFileWriter (writeClusterFile) without holding the file.
#include <algorithm>
#include <optional>
#include <stdexcept>

#include "facetree/io.h"
#include "file_shape.h"
#include "hierarchy_check.h"
#include "mesh_out.h"

namespace facetree {
namespace {

constexpr size_t kNodeBatch = 4096;       // file nodes handed to the writer at a time
constexpr size_t kGeometryBatch = 65536;  // vertices / triangles handed to the writer at a time

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
    } else {
      const bool swap = rangeStart(b.child[1]) < rangeStart(b.child[0]);
      node.childCount = 2;
      node.child[0] = b.child[swap ? 1 : 0];
      node.child[1] = b.child[swap ? 0 : 1];
      joined = (b.flags & kNodeJoinsDisjointSurfaces) != 0;
    }
    for (unsigned c = 0; c < node.childCount; ++c) node.childFaces[c] = faces(node.child[c]);
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
  uint32_t rangeStart(uint32_t ref) const {
    return ref & kFaceChild ? ref & ~kFaceChild : hierarchy_.nodes[ref].first;
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
  h.spatialClusters = options.build.metric == Metric::Constant ? 0 : options.build.spatialClusters;
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
  const FileNodes nodes(hierarchy, options);
  std::optional<FileShape> shape;
  if (stats) shape.emplace(options.branching, mesh.triangleCount(), nodes.size());
  const FirstUseNumbering numbering = numberByFirstUse(mesh, hierarchy.faceOrder);
  const size_t triangles = mesh.triangleCount();
  StreamFileInfo info;
  info.header = optionsHeader(options);
  info.header.nodeCount = info.header.originalNodeCount = nodes.size();
  info.header.triangleCount = triangles;
  info.header.vertexCount = numbering.vertexCount;
  if (originalFace.empty())
    info.maxOriginalFace = triangles > 0 ? triangles - 1 : 0;
  else
    info.maxOriginalFace = *std::max_element(originalFace.begin(), originalFace.end());
  ClusterFileWriter writer(path, info, writeOptions);

  // The three streams go to the writer interleaved: a batch of nodes, then the geometry of the same
  // share of the faces, so that with WriteOptions::threads the node frames (zstd-bound) compress on
  // the writer's workers while this thread walks the faces (random reads). The file's bytes do not
  // depend on the interleaving.
  std::vector<FchNode> nodeBatch;
  nodeBatch.reserve(std::min(kNodeBatch, nodes.size()));
  const std::span<const uint32_t> order = hierarchy.faceOrder;
  std::vector<glm::vec3> vertexBatch;
  vertexBatch.reserve(std::min<size_t>(kGeometryBatch, numbering.vertexCount));
  std::vector<uint32_t> indexBatch;
  std::vector<uint64_t> idBatch;
  indexBatch.reserve(3 * std::min(kGeometryBatch, triangles));
  idBatch.reserve(std::min(kGeometryBatch, triangles));
  uint32_t next = 0;  // vertices numbered so far: a walk along the faces meets each one's number in turn
  size_t node = 0, face = 0;
  const size_t steps = std::max<size_t>(1, (nodes.size() + kNodeBatch - 1) / kNodeBatch);
  for (size_t step = 1; step <= steps; ++step) {
    for (const size_t end = std::min(nodes.size(), step * kNodeBatch); node < end; ++node) {
      nodeBatch.push_back(nodes[node]);
      if (shape) shape->add(node, nodeBatch.back());
    }
    if (!nodeBatch.empty()) writer.addNodes(nodeBatch), nodeBatch.clear();
    for (const size_t end = step == steps ? triangles : triangles / steps * step; face < end; ++face) {
      const uint32_t t = order[face];
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = mesh.indices[3 * size_t{t} + k];
        const uint32_t number = numbering.remap[v];
        indexBatch.push_back(number);
        if (number != next) continue;
        vertexBatch.push_back(mesh.positions[v]);
        if (++next == numbering.vertexCount || vertexBatch.size() == kGeometryBatch)
          writer.addVertices(vertexBatch), vertexBatch.clear();
      }
      idBatch.push_back(originalFace.empty() ? t : originalFace[t]);
      if (idBatch.size() == kGeometryBatch || face + 1 == triangles)
        writer.addTriangles(indexBatch, idBatch), indexBatch.clear(), idBatch.clear();
    }
  }
  const uint64_t bytes = writer.finish();
  if (stats) *stats = shape->stats();
  return bytes;
}

BranchingStats branchingStats(const Hierarchy& hierarchy, const FileOptions& options) {
  const FileNodes nodes(hierarchy, options);
  const uint64_t triangles = hierarchy.faceOrder.size();
  FileShape shape(options.branching, triangles, nodes.size());
  for (size_t j = 0; j < nodes.size(); ++j) shape.add(j, nodes[j]);
  return shape.stats();
}

}  // namespace facetree
