// Branching-factor recast (Willmott 2000, sec. 5.5.1) and the cluster file of a hierarchy.
#include "facetree/io.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>

#include "mesh_out.h"

namespace facetree {
namespace {
constexpr uint32_t kUnassigned = 0xFFFFFFFFu;

constexpr size_t kNodeBatch = 4096;       // file nodes handed to the writer at a time
constexpr size_t kGeometryBatch = 65536;  // vertices / triangles handed to the writer at a time

void checkHierarchy(const Hierarchy& hierarchy, unsigned branching) {
  if (branching < 2 || branching > kMaxBranching)
    throw std::invalid_argument("branching factor must be 2 ... 8");
  const std::vector<Node>& nodes = hierarchy.nodes;
  const size_t n = nodes.size();
  const uint64_t faces = hierarchy.faceOrder.size();
  for (size_t i = 0; i < n; ++i)
    for (const uint32_t ref : nodes[i].child) {
      if (ref & kFaceChild ? (ref & ~kFaceChild) >= faces : ref >= n || ref <= i)
        throw std::invalid_argument("hierarchy: node " + std::to_string(i) + " has a bad child reference");
    }
}

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
    node.flags = static_cast<uint8_t>((b.flags & kNodeFlatFrame ? kFchFlatFrame : 0) |
                                      (joined ? kFchJoinsDisjointSurfaces : 0));
    node.cost = b.cost;
    node.area = b.area;
    node.perimeter = b.perimeter;
    node.sumNormal = b.sumNormal;
    node.box = hierarchy_.boxes[binary];  // same face range: the exact box of the b-ary node
    return node;
  }

 private:
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
  return h;
}

RecastTree recastHierarchy(const Hierarchy& hierarchy, unsigned branching, RecastRule rule) {
  checkHierarchy(hierarchy, branching);
  const std::vector<Node>& nodes = hierarchy.nodes;
  const size_t n = nodes.size();
  auto rangeStart = [&](uint32_t ref) { return ref & kFaceChild ? ref & ~kFaceChild : nodes[ref].first; };

  std::vector<uint8_t> kept(n, 0), join(n, 0);
  std::vector<std::array<uint32_t, kMaxBranching>> frontierOf(n);
  std::vector<uint8_t> sizeOf(n, 0);
  if (rule == RecastRule::FewestNodes) {
    // Bottom up (children follow parents): group[v] = binary nodes in v's open group.
    std::vector<uint32_t> group(n, 0);
    for (size_t v = n; v-- > 0;) {
      uint32_t total = 1;
      for (const uint32_t ref : nodes[v].child)
        if (!(ref & kFaceChild)) total += group[ref];
      while (total > branching - 1) {
        int heaviest = -1;
        for (int c = 0; c < 2; ++c) {
          const uint32_t ref = nodes[v].child[c];
          if (!(ref & kFaceChild) && !kept[ref] &&
              (heaviest < 0 || group[ref] > group[nodes[v].child[heaviest]]))
            heaviest = c;
        }
        kept[nodes[v].child[heaviest]] = 1;
        total -= group[nodes[v].child[heaviest]];
      }
      group[v] = total;
    }
  }
  if (n > 0) kept[0] = 1;
  // Parents precede children, so one ascending pass grows every kept node's frontier before
  // its frontier nodes are visited.
  for (size_t i = 0; i < n; ++i) {
    if (!kept[i]) continue;
    std::array<uint32_t, kMaxBranching> frontier{nodes[i].child[0], nodes[i].child[1]};
    unsigned size = 2;
    uint8_t joined = nodes[i].flags & kNodeJoinsDisjointSurfaces ? 1 : 0;
    while (size < branching) {
      int best = -1;
      for (unsigned f = 0; f < size; ++f) {
        const uint32_t ref = frontier[f];
        if (ref & kFaceChild) continue;
        if (rule == RecastRule::FewestNodes) {
          if (!kept[ref]) best = static_cast<int>(f);  // open group: expand it all
          continue;
        }
        if (best < 0 || nodes[ref].area > nodes[frontier[best]].area ||
            (nodes[ref].area == nodes[frontier[best]].area && ref < frontier[best]))
          best = static_cast<int>(f);
      }
      if (best < 0) break;
      const Node& expanded = nodes[frontier[best]];
      if (expanded.flags & kNodeJoinsDisjointSurfaces) joined = 1;
      frontier[best] = expanded.child[0];
      frontier[size++] = expanded.child[1];
    }
    // In face order (the starts are distinct: the ranges are disjoint and never empty). At most
    // kMaxBranching entries: an insertion sort, which also keeps GCC's -Warray-bounds quiet where
    // std::sort's inlined bounds did not (sanitizer builds).
    for (unsigned f = 1; f < size; ++f) {
      const uint32_t ref = frontier[f];
      const auto start = rangeStart(ref);
      unsigned g = f;
      for (; g > 0 && rangeStart(frontier[g - 1]) > start; --g) frontier[g] = frontier[g - 1];
      frontier[g] = ref;
    }
    for (unsigned f = 0; f < size; ++f)
      if (!(frontier[f] & kFaceChild)) kept[frontier[f]] = 1;
    frontierOf[i] = frontier;
    sizeOf[i] = static_cast<uint8_t>(size);
    join[i] = joined;
  }

  RecastTree tree;
  std::vector<uint32_t> newIndex(n, kUnassigned);
  for (size_t i = 0; i < n; ++i)
    if (kept[i])
      newIndex[i] = static_cast<uint32_t>(tree.binaryNode.size()),
      tree.binaryNode.push_back(static_cast<uint32_t>(i));
  const size_t m = tree.binaryNode.size();
  tree.child.resize(m);
  tree.childCount.resize(m);
  tree.joinFlag.resize(m);
  for (size_t j = 0; j < m; ++j) {
    const uint32_t i = tree.binaryNode[j];
    tree.childCount[j] = sizeOf[i];
    tree.joinFlag[j] = join[i];
    for (unsigned f = 0; f < sizeOf[i]; ++f) {
      const uint32_t ref = frontierOf[i][f];
      tree.child[j][f] = ref & kFaceChild ? ref : newIndex[ref];
    }
  }
  return tree;
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
                          const FileOptions& options, const WriteOptions& writeOptions) {
  checkFileInputs(mesh, originalFace, hierarchy, "writeClusterFile");
  const FileNodes nodes(hierarchy, options);
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
    for (const size_t end = std::min(nodes.size(), step * kNodeBatch); node < end; ++node)
      nodeBatch.push_back(nodes[node]);
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
  return writer.finish();
}

BranchingStats branchingStats(const ClusterFile& file) {
  BranchingStats s;
  s.branching = file.header.branching;
  s.triangles = file.indices.size() / 3;
  s.internalNodes = file.nodes.size();
  s.eq85Nodes = s.triangles > 0 ? double(s.triangles - 1) / double(s.branching - 1) : 0.0;
  // Depth in nodes of every node (root 1); a face below node j is at depth[j] + 1.
  std::vector<uint32_t> depth(file.nodes.size(), 1);
  s.height = s.triangles > 0 ? 1 : 0;
  for (size_t j = 0; j < file.nodes.size(); ++j) {
    const FchNode& node = file.nodes[j];
    ++s.childHistogram[std::min<unsigned>(node.childCount, kMaxBranching)];
    uint32_t kept = 0;
    for (unsigned c = 0; c < node.childCount; ++c) {
      const uint32_t ref = node.child[c];
      if (!(ref & kFaceChild) && ref < file.nodes.size()) {
        depth[ref] = depth[j] + 1;
        kept += file.nodes[ref].count;
      }
    }
    if (kept < node.count) s.height = std::max(s.height, depth[j] + 1);  // faces directly below
  }
  uint32_t balanced = 1;
  for (double reach = 1; reach < double(s.triangles); reach *= s.branching) ++balanced;  // eq. 86
  s.balancedHeight = s.triangles > 0 ? balanced : 0;
  return s;
}

}  // namespace facetree
