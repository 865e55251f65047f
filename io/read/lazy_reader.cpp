// ClusterFileReader: a cluster file read lazily under a memory bound (facetree/io.h). Opening reads
// the header and the frame index; node frames decode in file order, since version 2 takes a node's
// face range, depth and compact box from its parent's record (NodeDecoder); geometry frames are
// independent and decode by the face and vertex ranges asked. Decoded frames wait in one cache
// bounded in bytes, the least recently used leaving first; the frame in use always stays.
#include <algorithm>
#include <atomic>
#include <cstring>
#include <map>
#include <optional>
#include <unordered_map>

#include <unistd.h>

#include "facetree/storage.h"
#include "format/fch_format.h"
#include "format/node_code.h"
#include "read/cluster_source.h"
#include "shape/file_shape.h"

namespace facetree {

namespace {

// A decoded frame of any section, with what it costs to hold.
struct CachedFrame {
  std::vector<FchNode> nodes;
  std::vector<glm::vec3> vertices;
  std::vector<uint32_t> indices;
  std::vector<uint64_t> ids;
  uint64_t bytes = 0, lastUse = 0;
};

uint64_t frameBytes(const CachedFrame& f) {
  return f.nodes.capacity() * sizeof(FchNode) + f.vertices.capacity() * sizeof(glm::vec3) +
         f.indices.capacity() * sizeof(uint32_t) + f.ids.capacity() * sizeof(uint64_t) + 64;
}

}  // namespace

uint64_t readerMemory(const ReaderOptions& options, const FileHeader& header) {
  if (options.memoryBytes) return options.memoryBytes;
  return header.memoryCapBytes ? header.memoryCapBytes : defaultMemoryCap();
}

uint64_t defaultMemoryCap() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), pageSize = ::sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || pageSize <= 0) return uint64_t{4} << 30;
  return static_cast<uint64_t>(pages) * static_cast<uint64_t>(pageSize) / 2;
}

// A node frame of a version 2 file read, checked, decompressed and split into codes: a helper
// thread makes them one frame ahead of the decoder (HelperRing), the two halves of a pass costing
// about the same.
struct FrameCodes {
  size_t index = 0;  // the frame asked for, in the section
  std::string raw, compressed;
  std::vector<fch::NodeCode> codes;
  // The buffers' bytes as the helper last filled them: the decoder's thread reads this, never the
  // buffers of a slot the helper may be filling.
  std::atomic<uint64_t> held{0};
  void countHeld() {
    held = raw.capacity() + compressed.capacity() + codes.capacity() * sizeof(fch::NodeCode);
  }
};

struct ClusterFileReader::State {
  template <class... Source>
  explicit State(const ReaderOptions& options, Source&&... from)
      : source(std::forward<Source>(from)...),
        memoryBytes(readerMemory(options, source.layout().header)),
        cacheBytes(memoryBytes / 4),
        frontierBytes(cacheBytes),
        tmp(options.tmp) {
    const FchLayout& layout = source.layout();
    for (size_t i = 0; i < layout.frames.size(); ++i)
      sections[static_cast<uint32_t>(layout.frames[i].section) - 1].push_back(i);
  }

  fch::SourceFile source;
  uint64_t memoryBytes, cacheBytes, frontierBytes;
  std::filesystem::path tmp;
  uint64_t peakHeld = 0, spilled = 0;
  std::vector<size_t> sections[4];  // layout frame indices of each section, in element order
  std::map<size_t, CachedFrame> cache;
  uint64_t cachedBytes = 0, clock = 0;
  // The pass that fills the node cache: node frames decoded so far and their decoder's state.
  std::unique_ptr<fch::NodeDecoder> decoder;
  size_t nextNodeFrame = 0;
  // The face range and parent of every node of the frames the node() pass has decoded, and with
  // compact boxes its decoded box, in a temporary file (12 or 52 bytes a node), so that a frame
  // behind the pass decodes on its own.
  struct IndexedRange {
    uint32_t first, count, parent;
    float center[3], half[3], orientation[4];  // compact boxes only
  };
  std::unique_ptr<TemporaryFile> rangeFile;
  std::vector<char> rangeBytes;

  // Buffers of one node frame, their capacity kept from frame to frame.
  std::string raw, compressed;
  std::vector<fch::NodeCode> codes;

  const FchLayout& layout() const { return source.layout(); }
  bool version1() const { return layout().header.version == 1; }

  void evict(size_t keep) {
    while (cachedBytes > cacheBytes && cache.size() > 1) {
      auto oldest = cache.end();
      for (auto it = cache.begin(); it != cache.end(); ++it)
        if (it->first != keep && (oldest == cache.end() || it->second.lastUse < oldest->second.lastUse))
          oldest = it;
      if (oldest == cache.end()) return;
      cachedBytes -= oldest->second.bytes;
      cache.erase(oldest);
    }
  }

  CachedFrame& insert(size_t frame, CachedFrame&& decoded) {
    decoded.bytes = frameBytes(decoded);
    decoded.lastUse = ++clock;
    cachedBytes += decoded.bytes;
    CachedFrame& slot = cache[frame] = std::move(decoded);
    evict(frame);
    return slot;
  }

  CachedFrame* cached(size_t frame) {
    const auto it = cache.find(frame);
    if (it == cache.end()) return nullptr;
    it->second.lastUse = ++clock;
    return &it->second;
  }

  // Reads, checks and decompresses node frame `k` (k-th of the section) of a version 2 file into
  // its codes; touches only `source` (whose reads are serialised by the caller) and the buffers.
  void readCodes(size_t k, bool structure, std::string& rawBuffer, std::string& compressedBuffer,
                 std::vector<fch::NodeCode>& out) const {
    const size_t i = sections[0][k];
    source.rawFrame(i, rawBuffer, compressedBuffer);
    out.clear();
    decodeNodeCodes(source, i, rawBuffer, out, structure);
  }

  // The nodes of frame `k` from its codes, in turn through `nodeDecoder`; depths optional.
  void decodeCodes(size_t k, const std::vector<fch::NodeCode>& frameCodes, fch::NodeDecoder& nodeDecoder,
                   std::vector<FchNode>& out, std::vector<uint32_t>* depths) const {
    const size_t i = sections[0][k];
    out.resize(frameCodes.size());
    if (depths) depths->resize(frameCodes.size());
    const uint64_t first = layout().frames[i].first;
    for (size_t j = 0; j < frameCodes.size(); ++j) {
      uint32_t depth = 0;
      const std::string error = nodeDecoder.decode(frameCodes[j], first + j, out[j], depth);
      if (!error.empty()) source.fail(source.where(i) + ": node " + std::to_string(first + j) + ": " + error);
      if (depths) (*depths)[j] = depth;
    }
  }

  // Decodes node frame `k` with `decoder`, into `out`; depths optional.
  void decodeNodeFrame(size_t k, fch::NodeDecoder* nodeDecoder, std::vector<FchNode>& out,
                       std::vector<uint32_t>* depths) {
    if (version1()) {
      const size_t i = sections[0][k];
      source.rawFrame(i, raw, compressed);
      out.clear();
      source.decodeNodes(i, raw, out);
      for (FchNode& node : out)
        for (unsigned c = 0; c < node.childCount; ++c)
          if (node.child[c] & kFaceChild) node.childFaces[c] = 1;
      return;
    }
    readCodes(k, nodeDecoder->structure(), raw, compressed, codes);
    decodeCodes(k, codes, *nodeDecoder, out, depths);
  }

  uint64_t frameFirst(size_t k) const { return layout().frames[sections[0][k]].first; }

  bool compactBoxes() const { return layout().header.boxes == BoxPrecision::Compact; }
  size_t rangeStride() const { return compactBoxes() ? sizeof(IndexedRange) : 3 * sizeof(uint32_t); }

  void recordRanges(size_t k, const std::vector<FchNode>& nodes) {
    if (!rangeFile) rangeFile = std::make_unique<TemporaryFile>(tmp);
    const std::vector<fch::PendingChild>& slots = decoder->frameRanges();
    const size_t stride = rangeStride();
    rangeBytes.resize(nodes.size() * stride);
    for (size_t j = 0; j < nodes.size(); ++j) {
      const NodeBox& box = nodes[j].box;
      const IndexedRange r{nodes[j].first,
                           nodes[j].count,
                           j < slots.size() ? slots[j].parent : 0,
                           {box.center.x, box.center.y, box.center.z},
                           {box.halfExtent.x, box.halfExtent.y, box.halfExtent.z},
                           {box.orientation.x, box.orientation.y, box.orientation.z, box.orientation.w}};
      std::memcpy(&rangeBytes[j * stride], &r, stride);
    }
    rangeFile->write(frameFirst(k) * stride, rangeBytes.data(), rangeBytes.size());
  }

  IndexedRange readRange(uint64_t index) const {
    IndexedRange r{};
    rangeFile->read(index * rangeStride(), &r, rangeStride());
    return r;
  }

  // Node frame `k`, behind the pass, from its codes and the ranges recorded for it; a compact box
  // from its parent's as recorded.
  CachedFrame decodeIndexed(size_t k) {
    const size_t i = sections[0][k];
    std::vector<fch::NodeCode> frameCodes;
    readCodes(k, false, raw, compressed, frameCodes);
    const size_t stride = rangeStride();
    std::vector<char> bytes(frameCodes.size() * stride);
    rangeFile->read(frameFirst(k) * stride, bytes.data(), bytes.size());
    CachedFrame f;
    f.nodes.resize(frameCodes.size());
    for (size_t j = 0; j < frameCodes.size(); ++j) {
      const uint64_t index = frameFirst(k) + j;
      IndexedRange r{};
      std::memcpy(&r, &bytes[j * stride], stride);
      NodeBox parentBox;
      if (compactBoxes() && index > 0) {
        if (r.parent >= index)
          source.fail(source.where(i) + ": node " + std::to_string(index) + ": bad parent");
        const IndexedRange p = readRange(r.parent);
        parentBox.center = glm::vec3(p.center[0], p.center[1], p.center[2]);
        parentBox.halfExtent = glm::vec3(p.half[0], p.half[1], p.half[2]);
        parentBox.orientation.x = p.orientation[0], parentBox.orientation.y = p.orientation[1];
        parentBox.orientation.z = p.orientation[2], parentBox.orientation.w = p.orientation[3];
      }
      const std::string error = fch::decodeNodeAt(layout().header, layout().rootBox, frameCodes[j], index,
                                                  fch::PendingChild{r.first, r.count, 1, r.parent, 0},
                                                  compactBoxes() ? &parentBox : nullptr, false, f.nodes[j]);
      if (!error.empty()) source.fail(source.where(i) + ": node " + std::to_string(index) + ": " + error);
    }
    return f;
  }

  const std::vector<FchNode>& nodeFrame(size_t k) {
    const size_t i = sections[0][k];
    if (CachedFrame* hit = cached(i)) return hit->nodes;
    if (version1()) {
      CachedFrame f;
      decodeNodeFrame(k, nullptr, f.nodes, nullptr);
      return insert(i, std::move(f)).nodes;
    }
    if (k < nextNodeFrame) return insert(i, decodeIndexed(k)).nodes;
    if (!decoder)
      decoder = std::make_unique<fch::NodeDecoder>(layout().header, layout().rootBox, layout().nodesPerFrame,
                                                   frontierBytes, tmp);
    for (;; ++nextNodeFrame) {
      CachedFrame f;
      decodeNodeFrame(nextNodeFrame, decoder.get(), f.nodes, nullptr);
      recordRanges(nextNodeFrame, f.nodes);
      const size_t at = sections[0][nextNodeFrame];
      if (nextNodeFrame == k) {
        ++nextNodeFrame;
        return insert(at, std::move(f)).nodes;
      }
      if (!cached(at)) insert(at, std::move(f));
    }
  }

  // Decodes the elements of geometry section `s` (1 vertices, 2 triangles, 3 ids) in frame `k`
  // into `f`.
  void decodeGeometry(int s, size_t k, CachedFrame& f) {
    const size_t i = sections[s][k];
    source.rawFrame(i, raw, compressed);
    f.vertices.clear(), f.indices.clear(), f.ids.clear();
    if (s == 1) source.decodeVertices(i, raw, f.vertices);
    if (s == 2) source.decodeTriangles(i, raw, f.indices);
    if (s == 3) source.decodeIds(i, raw, f.ids);
  }

  // Frame `k` of geometry section `s`, through the cache.
  const CachedFrame& geometryFrame(int s, size_t k) {
    const size_t i = sections[s][k];
    if (CachedFrame* hit = cached(i)) return *hit;
    CachedFrame f;
    decodeGeometry(s, k, f);
    return insert(i, std::move(f));
  }

  // Frame `k` of geometry section `s` for a pass that uses each frame once: from the cache if it
  // is there, else into `buffer`, leaving the cache to what random access put in it.
  const CachedFrame& passFrame(int s, size_t k, CachedFrame& buffer) {
    if (CachedFrame* hit = cached(sections[s][k])) return *hit;
    decodeGeometry(s, k, buffer);
    peakHeld = std::max(peakHeld, cachedBytes + frameBytes(buffer));
    return buffer;
  }

  uint64_t perFrame() const { return layout().geometryPerFrame; }
};

ClusterFileReader::ClusterFileReader(const std::filesystem::path& path, const ReaderOptions& options)
    : state_(std::make_unique<State>(options, path)) {}
ClusterFileReader::ClusterFileReader(int fd, const std::string& name, const ReaderOptions& options)
    : state_(std::make_unique<State>(options, fd, name)) {}
ClusterFileReader::~ClusterFileReader() = default;

const FchLayout& ClusterFileReader::layout() const {
  return state_->layout();
}
const FileHeader& ClusterFileReader::header() const {
  return state_->layout().header;
}
uint64_t ClusterFileReader::size() const {
  return state_->layout().header.nodeCount;
}
uint64_t ClusterFileReader::memoryBytes() const {
  return state_->memoryBytes;
}
const std::filesystem::path& ClusterFileReader::temporaryDirectory() const {
  return state_->tmp;
}

const std::string& ClusterFileReader::name() const {
  return state_->source.name();
}

FchNode ClusterFileReader::node(uint64_t index) {
  if (index >= size()) throw std::out_of_range("ClusterFileReader::node: index past the nodes");
  const uint64_t per = layout().nodesPerFrame;
  return state_->nodeFrame(index / per)[index % per];
}

std::vector<FchNode> ClusterFileReader::nodeFrame(uint64_t frame) {
  if (frame >= state_->sections[0].size())
    throw std::out_of_range("ClusterFileReader::nodeFrame: frame past the nodes");
  return state_->nodeFrame(frame);
}

uint64_t ClusterFileReader::forEachNode(const std::function<bool(uint64_t, const FchNode&, uint32_t)>& visit,
                                        NodeFields fields) {
  State& s = *state_;
  fch::NodeDecoder decoder(header(), layout().rootBox, layout().nodesPerFrame, s.frontierBytes, s.tmp,
                           fields == NodeFields::Structure);
  struct Account {  // the pass's peak and spill, whichever way it ends
    State& s;
    fch::NodeDecoder& decoder;
    ~Account() { s.spilled += decoder.spilledBytes(); }
  } account{s, decoder};
  // Version 1 records hold their ranges; their depths come from the parents, kept here.
  std::unordered_map<uint64_t, uint32_t> depthV1;
  std::vector<FchNode> nodes;
  std::vector<uint32_t> depths;
  uint64_t visited = 0;
  const size_t frames = s.sections[0].size();
  std::optional<HelperRing<FrameCodes>> pipeline;
  const auto ask = [&](size_t k) {
    if (k < frames) pipeline->slot().index = k, pipeline->submit();
  };
  if (!s.version1() && frames > 1) {
    pipeline.emplace([&s, structure = decoder.structure()](FrameCodes& frame, unsigned) {
      s.readCodes(frame.index, structure, frame.raw, frame.compressed, frame.codes);
      frame.countHeld();
    });
    ask(0), ask(1);
  }
  for (size_t k = 0; k < frames; ++k) {
    uint64_t pipelineBytes = 0;
    if (pipeline) {
      s.decodeCodes(k, pipeline->take().codes, decoder, nodes, &depths);
      for (const FrameCodes& frame : pipeline->slots()) pipelineBytes += frame.held;
    } else {
      s.decodeNodeFrame(k, &decoder, nodes, &depths);
    }
    s.peakHeld = std::max(
        s.peakHeld, heldBytes() + decoder.heldBytes() + nodes.capacity() * sizeof(FchNode) + pipelineBytes);
    const uint64_t first = layout().frames[s.sections[0][k]].first;
    for (size_t j = 0; j < nodes.size(); ++j) {
      const uint64_t index = first + j;
      uint32_t depth = 1;
      if (s.version1()) {
        if (index > 0) {
          const auto it = depthV1.find(index);
          depth = it == depthV1.end() ? 1 : it->second;
          if (it != depthV1.end()) depthV1.erase(it);
        }
        for (unsigned c = 0; c < nodes[j].childCount; ++c)
          if (!(nodes[j].child[c] & kFaceChild) && nodes[j].child[c] < size())
            depthV1[nodes[j].child[c]] = depth + 1;
      } else {
        depth = depths[j];
      }
      ++visited;
      if (!visit(index, nodes[j], depth)) return visited;
    }
    if (pipeline) ask(k + 2);  // frame k + 1 is being made: its failure comes after frame k's visits
  }
  return visited;
}

std::vector<CutCluster> ClusterFileReader::cut(uint64_t clusters) {
  fch::ReaderSource source(*this);
  return fch::prefixCut(source, clusters);
}

std::vector<CutCluster> ClusterFileReader::cutByCost(double maxCost) {
  fch::ReaderSource source(*this);
  return fch::costCut(source, maxCost);
}

std::vector<CutCluster> ClusterFileReader::cutByDepth(uint32_t depth) {
  fch::ReaderSource source(*this);
  return fch::depthCut(source, depth);
}

FaceRangeMesh ClusterFileReader::faces(uint64_t first, uint64_t count, FaceFields fields) {
  State& s = *state_;
  const uint64_t triangles = header().triangleCount;
  if (first > triangles || count > triangles - first)
    throw std::out_of_range("ClusterFileReader::faces: range past the triangles");
  FaceRangeMesh mesh;
  mesh.first = first;
  mesh.indices.reserve(3 * count);
  if (fields == FaceFields::All) mesh.originalFace.reserve(count);
  const uint64_t per = s.perFrame();
  for (uint64_t p = first; p < first + count;) {
    const uint64_t k = p / per, end = std::min(first + count, (k + 1) * per);
    const CachedFrame& tri = s.geometryFrame(2, k);
    for (uint64_t q = p; q < end; ++q)
      for (int c = 0; c < 3; ++c) mesh.indices.push_back(tri.indices[3 * (q - k * per) + c]);
    if (fields == FaceFields::All) {
      const CachedFrame& ids = s.geometryFrame(3, k);
      for (uint64_t q = p; q < end; ++q) mesh.originalFace.push_back(ids.ids[q - k * per]);
    }
    p = end;
  }
  // Local numbering: the vertices used, in file order. Vertices are numbered by first use, so a
  // range's span little more than the vertices it uses: a table over the span numbers them in
  // two passes; a span far wider (references to vertices long before) is sorted instead.
  if (!mesh.indices.empty()) {
    const auto [low, high] = std::minmax_element(mesh.indices.begin(), mesh.indices.end());
    const uint32_t lo = *low, span = *high - *low + 1;
    if (span <= 2 * mesh.indices.size()) {
      constexpr uint32_t kUnused = ~uint32_t{0};
      std::vector<uint32_t> local(span, kUnused);
      for (const uint32_t v : mesh.indices) local[v - lo] = 0;
      uint32_t next = 0;
      for (uint32_t i = 0; i < span; ++i)
        if (local[i] != kUnused) local[i] = next++, mesh.vertexIds.push_back(uint64_t{lo} + i);
      for (uint32_t& v : mesh.indices) v = local[v - lo];
    } else {
      mesh.vertexIds.assign(mesh.indices.begin(), mesh.indices.end());
      std::sort(mesh.vertexIds.begin(), mesh.vertexIds.end());
      mesh.vertexIds.erase(std::unique(mesh.vertexIds.begin(), mesh.vertexIds.end()), mesh.vertexIds.end());
      for (uint32_t& v : mesh.indices)
        v = static_cast<uint32_t>(std::lower_bound(mesh.vertexIds.begin(), mesh.vertexIds.end(), v) -
                                  mesh.vertexIds.begin());
    }
  }
  mesh.vertices.reserve(mesh.vertexIds.size());
  const CachedFrame* frame = nullptr;
  uint64_t frameIndex = ~uint64_t{0};
  for (const uint64_t v : mesh.vertexIds) {
    if (v / per != frameIndex) frameIndex = v / per, frame = &s.geometryFrame(1, frameIndex);
    mesh.vertices.push_back(frame->vertices[v % per]);
  }
  return mesh;
}

void ClusterFileReader::forEachCluster(
    std::span<const CutCluster> cut,
    const std::function<void(const CutCluster&, const FaceRangeMesh&)>& visit) {
  for (const CutCluster& cluster : cut) visit(cluster, faces(cluster.first, cluster.count));
}

BranchingStats branchingStats(ClusterFileReader& reader) {
  ShapePass pass(reader.header());
  reader.forEachNode(
      [&](uint64_t, const FchNode& node, uint32_t depth) {
        pass.visit(node, depth);
        return true;
      },
      NodeFields::Structure);
  return pass.stats();
}

void ClusterFileReader::forEachCutPiece(
    std::span<const CutCluster> cut,
    const std::function<void(const FaceRangeMesh&, std::span<const uint32_t>)>& visit, FaceFields fields) {
  std::vector<uint32_t> clusterOf;
  size_t c = 0;
  forEachFacePiece(
      [&](const FaceRangeMesh& piece) {
        const size_t count = piece.indices.size() / 3;
        clusterOf.resize(count);
        for (size_t t = 0; t < count; ++t) {
          const uint64_t p = piece.first + t;
          while (c < cut.size() && cut[c].first + cut[c].count <= p) ++c;
          if (c == cut.size() || cut[c].first > p)
            throw std::invalid_argument("ClusterFileReader::forEachCutPiece: the cut does not cover face " +
                                        std::to_string(p));
          clusterOf[t] = static_cast<uint32_t>(c);
        }
        visit(piece, clusterOf);
      },
      fields);
}

void ClusterFileReader::forEachFacePiece(const std::function<void(const FaceRangeMesh&)>& visit,
                                         FaceFields fields) {
  const uint64_t triangles = header().triangleCount, per = state_->perFrame();
  for (uint64_t first = 0; first < triangles; first += per)
    visit(faces(first, std::min(per, triangles - first), fields));
}

void ClusterFileReader::forEachVertexFrame(
    const std::function<void(uint64_t, std::span<const glm::vec3>)>& visit) {
  State& s = *state_;
  CachedFrame buffer;
  for (size_t k = 0; k < s.sections[1].size(); ++k)
    visit(k * s.perFrame(), s.passFrame(1, k, buffer).vertices);
}

void ClusterFileReader::forEachTriangleFrame(
    const std::function<void(uint64_t, std::span<const uint32_t>, std::span<const uint64_t>)>& visit,
    FaceFields fields) {
  State& s = *state_;
  CachedFrame triangles, ids;
  for (size_t k = 0; k < s.sections[2].size(); ++k) {
    const std::span<const uint64_t> frameIds = fields == FaceFields::All
                                                   ? std::span<const uint64_t>(s.passFrame(3, k, ids).ids)
                                                   : std::span<const uint64_t>();
    visit(k * s.perFrame(), s.passFrame(2, k, triangles).indices, frameIds);
  }
}

const fch::SourceFile& fch::ReaderAccess::source(const ClusterFileReader& reader) {
  return reader.state_->source;
}

uint64_t ClusterFileReader::heldBytes() const {
  const State& s = *state_;
  return s.cachedBytes + (s.decoder ? s.decoder->heldBytes() : 0) +
         s.layout().frames.capacity() * sizeof(FchFrame) + s.raw.capacity() + s.compressed.capacity() +
         s.codes.capacity() * sizeof(fch::NodeCode);
}

uint64_t ClusterFileReader::peakHeldBytes() const {
  return std::max(state_->peakHeld, heldBytes());
}

uint64_t ClusterFileReader::spilledBytes() const {
  return state_->spilled + (state_->decoder ? state_->decoder->spilledBytes() : 0);
}

}  // namespace facetree
