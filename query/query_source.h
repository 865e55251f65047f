// Internal to query/: what a traversal reads, from a ClusterFile in memory or through a
// ClusterFileReader. A source gives the root (root()) and hands each thread a view: node(ref) (a
// reference or a copy), isCutOff(ref), corners(p, out) and originalFace(p) for face positions p.
//
// Through a reader, nodes and triangles come from its query index's pages and blocks
// (node_pages.h), cached for all threads; a view keeps the pages and the block it used last, so
// that a traversal that stays in them takes no lock. The reader itself is read only while the
// index is built.
#pragma once

#include <cstdint>
#include <memory>

#include "facetree/io.h"
#include "facetree/query.h"
#include "node_pages.h"
#include "ray_pages.h"

namespace facetree {

// A file whose nodes, triangles and layout for rays fit half the reader's cap is read whole and
// queried as the file in memory; a larger one through pages.
struct ReaderQueryIndex::State {
  explicit State(ClusterFileReader& r);
  ClusterFileReader& reader;
  std::unique_ptr<ClusterFile> file;        // the file read whole, or none
  std::unique_ptr<RayLayout> layout;        // ... and laid out for rays
  std::unique_ptr<query::NodePages> pages;  // else its pages
  std::unique_ptr<query::RayPages> rays;    // ... laid out for rays
  // What the file read whole and its layout for rays take at most.
  static uint64_t wholeBytes(const FileHeader& header);
};

namespace query {

class FileSource {
 public:
  explicit FileSource(const ClusterFile& file) : file_(file) {}
  uint64_t nodeCount() const { return file_.nodes.size(); }
  uint64_t faceCount() const { return file_.indices.size() / 3; }
  NodeRef root() const { return {0, 0, static_cast<uint32_t>(faceCount())}; }

  class View {
   public:
    explicit View(const FileSource& source) : file_(source.file_) {}
    uint64_t faceCount() const { return file_.indices.size() / 3; }
    const FchNode& node(const NodeRef& ref) { return file_.nodes[ref.index]; }
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
  explicit ReaderSource(ReaderQueryIndex& index) : pages_(*index.state_->pages), rays_(*index.state_->rays) {}
  // The file read whole and its layout for rays, where the index holds them (else null).
  static const ClusterFile* wholeFile(const ReaderQueryIndex& index) { return index.state_->file.get(); }
  static const RayLayout* layout(const ReaderQueryIndex& index) { return index.state_->layout.get(); }
  uint64_t nodeCount() const { return pages_.nodeCount(); }
  uint64_t faceCount() const { return pages_.faceCount(); }
  NodeRef root() const { return pages_.root(); }
  // The centre of the root's box (the origin for a file without nodes).
  glm::vec3 center() const {
    if (rays_.empty()) return glm::vec3(0.0f);
    const BoxPacket& root = rays_.top().boxes(0);
    return {root.center[0][0], root.center[1][0], root.center[2][0]};
  }

  class View {
   public:
    explicit View(ReaderSource& source) : pages_(source.pages_), rays_(source.rays_), top_(rays_.top()) {}
    FchNode node(const NodeRef& ref) {
      const uint32_t id = pages_.pageOf(ref);
      Slot& slot = slots_[pages_.inTop(ref) ? 0 : 1];  // a top chunk, a subtree page
      if (!slot.page || slot.id != id) slot.page = pages_.page(id), slot.id = id;
      return pages_.find(*slot.page, ref);
    }
    uint64_t faceCount() const { return pages_.faceCount(); }
    bool isCutOff(uint32_t ref) const { return !(ref & kFaceChild) && ref >= pages_.nodeCount(); }
    void corners(uint64_t p, glm::vec3 (&out)[3]) { NodePages::corners(block(p), p, out); }
    // The layouts for rays: 0 the nodes above the pages, 1 + id subtree page id's.
    bool empty() const { return rays_.empty(); }
    const RaySpans& layout(uint32_t at) {
      if (at == 0) return top_;
      Laid& slot = laid_[at % kLaid];
      if (!slot.page || slot.at != at)
        slot.page = rays_.page(at - 1), slot.at = at, slot.spans = RayPages::spans(*slot.page);
      return slot.spans;
    }
    uint64_t originalFace(uint64_t p) { return NodePages::originalFace(block(p), p); }

   private:
    struct Slot {
      NodePages::Page page;
      uint64_t id = 0;
    };
    const MappedBytes& block(uint64_t p) {
      // The last block holds fewer: a position past the triangles would read past it.
      if (p >= pages_.faceCount()) pages_.pastTriangles(p);
      const uint64_t b = p / NodePages::kBlockTriangles;
      if (!triangles_.page || triangles_.id != b) triangles_.page = pages_.block(b), triangles_.id = b;
      return *triangles_.page;
    }
    struct Laid {
      NodePages::Page page;
      uint32_t at = 0;
      RaySpans spans;
    };
    static constexpr uint32_t kLaid = 8;  // page layouts held by a thread, by page id
    NodePages& pages_;
    RayPages& rays_;
    RaySpans top_;
    Slot slots_[2], triangles_;
    Laid laid_[kLaid];
  };

 private:
  NodePages& pages_;
  RayPages& rays_;
};

}  // namespace query
}  // namespace facetree
