// Internal to query/: what a traversal reads, from a ClusterFile in memory or through a
// ClusterFileReader. A source hands each thread a view: node(i) (a reference or a copy),
// isCutOff(ref), corners(p, out) and originalFace(p) for face positions p.
//
// Through a reader, node frames and whole triangle frames (with their vertices, as faces() gives
// them) wait in one cache shared by the threads, bounded in bytes, the least recently used leaving
// first; a view keeps the frames it used last, so that a traversal that stays in a frame takes no
// lock. The reader itself is used under the cache's lock: it is not thread-safe.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "facetree/io.h"

namespace facetree::query {

class FileSource {
 public:
  explicit FileSource(const ClusterFile& file) : file_(file) {}
  uint64_t nodeCount() const { return file_.nodes.size(); }
  uint64_t faceCount() const { return file_.indices.size() / 3; }

  class View {
   public:
    explicit View(const FileSource& source) : file_(source.file_) {}
    uint64_t faceCount() const { return file_.indices.size() / 3; }
    const FchNode& node(uint32_t index) { return file_.nodes[index]; }
    bool isCutOff(uint32_t ref) const { return file_.isCutOff(ref); }
    void corners(uint64_t p, glm::vec3 (&out)[3]) {
      for (int c = 0; c < 3; ++c) out[c] = file_.vertices[file_.indices[3 * p + c]];
    }
    uint64_t originalFace(uint64_t p) { return p < file_.originalFace.size() ? file_.originalFace[p] : p; }

   private:
    const ClusterFile& file_;
  };

 private:
  const ClusterFile& file_;
};

class ReaderSource {
 public:
  // `budget`: the bytes the frames may hold (0: a quarter of the reader's cap).
  explicit ReaderSource(ClusterFileReader& reader, uint64_t budget = 0)
      : reader_(reader),
        budget_(budget ? budget : reader.memoryBytes() / 4),
        nodesPerFrame_(reader.layout().nodesPerFrame),
        facesPerFrame_(reader.layout().geometryPerFrame) {}
  uint64_t nodeCount() const { return reader_.size(); }
  uint64_t faceCount() const { return reader_.header().triangleCount; }
  uint64_t peakBytes() const { return peak_; }

  class View {
   public:
    explicit View(ReaderSource& source) : source_(source) {}
    FchNode node(uint32_t index) {
      const uint64_t k = index / source_.nodesPerFrame_;
      if (!nodes_ || k != nodeFrame_) nodes_ = source_.nodeFrame(k), nodeFrame_ = k;
      return (*nodes_)[index % source_.nodesPerFrame_];
    }
    bool isCutOff(uint32_t ref) const { return !(ref & kFaceChild) && ref >= source_.nodeCount(); }
    void corners(uint64_t p, glm::vec3 (&out)[3]) {
      const FaceRangeMesh& frame = faces(p);
      const uint64_t t = p - frame.first;
      for (int c = 0; c < 3; ++c) out[c] = frame.vertices[frame.indices[3 * t + c]];
    }
    uint64_t originalFace(uint64_t p) {
      const FaceRangeMesh& frame = faces(p);
      return frame.originalFace[p - frame.first];
    }

   private:
    const FaceRangeMesh& faces(uint64_t p) {
      const uint64_t k = p / source_.facesPerFrame_;
      if (!faces_ || k != faceFrame_) faces_ = source_.faceFrame(k), faceFrame_ = k;
      return *faces_;
    }
    ReaderSource& source_;
    std::shared_ptr<const std::vector<FchNode>> nodes_;
    std::shared_ptr<const FaceRangeMesh> faces_;
    uint64_t nodeFrame_ = 0, faceFrame_ = 0;
  };

 private:
  struct Entry {
    std::shared_ptr<const std::vector<FchNode>> nodes;
    std::shared_ptr<const FaceRangeMesh> faces;
    uint64_t bytes = 0, lastUse = 0;
  };
  // Keys: node frames k as 2k, triangle frames as 2k + 1.
  // A copy of the entry (its frames shared), taken under the lock: another thread may evict it.
  template <class Make>
  Entry entry(uint64_t key, Make&& make) {
    std::lock_guard lock(mutex_);
    auto it = cache_.find(key);
    if (it == cache_.end()) {
      Entry e = make();
      held_ += e.bytes;
      it = cache_.emplace(key, std::move(e)).first;
      while (held_ > budget_ && cache_.size() > 1) {  // the least recently used other frame leaves
        auto oldest = cache_.end();
        for (auto j = cache_.begin(); j != cache_.end(); ++j)
          if (j != it && (oldest == cache_.end() || j->second.lastUse < oldest->second.lastUse)) oldest = j;
        held_ -= oldest->second.bytes;
        cache_.erase(oldest);
      }
      peak_ = std::max(peak_, held_);
    }
    it->second.lastUse = ++clock_;
    return it->second;
  }
  std::shared_ptr<const std::vector<FchNode>> nodeFrame(uint64_t k) {
    return entry(2 * k,
                 [&] {
                   Entry e;
                   auto nodes = std::make_shared<std::vector<FchNode>>(reader_.nodeFrame(k));
                   e.bytes = nodes->size() * sizeof(FchNode) + 64;
                   e.nodes = std::move(nodes);
                   return e;
                 })
        .nodes;
  }
  std::shared_ptr<const FaceRangeMesh> faceFrame(uint64_t k) {
    return entry(2 * k + 1,
                 [&] {
                   Entry e;
                   const uint64_t first = k * facesPerFrame_;
                   auto mesh = std::make_shared<FaceRangeMesh>(
                       reader_.faces(first, std::min(facesPerFrame_, faceCount() - first)));
                   std::vector<uint64_t>().swap(mesh->vertexIds);  // not needed: its memory goes
                   e.bytes = mesh->vertices.size() * sizeof(glm::vec3) +
                             mesh->indices.size() * sizeof(uint32_t) +
                             mesh->originalFace.size() * sizeof(uint64_t) + 64;
                   e.faces = std::move(mesh);
                   return e;
                 })
        .faces;
  }

  ClusterFileReader& reader_;
  uint64_t budget_;
  uint64_t nodesPerFrame_, facesPerFrame_;
  std::mutex mutex_;
  std::map<uint64_t, Entry> cache_;
  uint64_t held_ = 0, peak_ = 0, clock_ = 0;
};

}  // namespace facetree::query
