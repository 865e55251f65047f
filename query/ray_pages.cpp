// A reader's pages laid out for rays (ray_pages.h).
#include "ray_pages.h"

#include <algorithm>
#include <atomic>
#include <cstring>
#include <map>
#include <thread>

#include "facetree/storage.h"

namespace facetree::query {

namespace {

// A page's layout in one mapping: counts, then packets, ranges, original ids and corners (each
// aligned for its type: a packet is 256 bytes, a range and an id 8, corners 36 a face).
struct PageHead {
  uint64_t packets, ranges, cornerFirst, corners;
};
constexpr size_t kHeadBytes = sizeof(RayPacket);  // the packets stay 64-byte aligned

// A subtree page's records as a traversal's view reads them.
class PageView {
 public:
  PageView(const NodePages& pages, std::span<const std::byte> records) : pages_(pages), records_(records) {}
  FchNode node(const NodeRef& ref) const { return pages_.find(records_, ref); }
  bool isCutOff(uint32_t ref) const { return !(ref & kFaceChild) && ref >= pages_.nodeCount(); }

 private:
  const NodePages& pages_;
  std::span<const std::byte> records_;
};

// The nodes above the pages: the top's records from its chunks, a page's root's from its page.
class TopView {
 public:
  explicit TopView(NodePages& pages) : pages_(pages) {}
  const FchNode& node(const NodeRef& ref) {
    auto it = read_.find(ref.index);
    if (it == read_.end()) {
      const uint32_t id = pages_.pageOf(ref);
      it = read_
               .emplace(ref.index,
                        pages_.inTop(ref) ? pages_.find(*pages_.page(id), ref) : pages_.root(id).second)
               .first;
    }
    return it->second;
  }
  bool isCutOff(uint32_t ref) const { return !(ref & kFaceChild) && ref >= pages_.nodeCount(); }

 private:
  NodePages& pages_;
  std::map<uint32_t, FchNode> read_;  // each record read once
};

// Lays out subtree page `id` into `blob`: counts, packets, ranges, corners.
void layOutPage(NodePages& pages, uint32_t id, std::vector<std::byte>& blob) {
  const std::vector<std::byte> records = pages.records(id);
  const auto [root, rootNode] = pages.root(records);
  PageView view(pages, records);
  std::vector<RayPacket> packets;
  std::vector<FaceRange> ranges;
  layOut(
      view, root, rootNode.box, [](const NodeRef&) { return kNoPage; }, packets, ranges);
  const PageHead head{packets.size(), ranges.size(), root.first, root.count};
  blob.resize(kHeadBytes + packets.size() * sizeof(RayPacket) + ranges.size() * sizeof(FaceRange) +
              root.count * (sizeof(Corners) + sizeof(uint64_t)));
  std::byte* at = blob.data();
  std::memcpy(at, &head, sizeof head);
  at += kHeadBytes;
  std::memcpy(at, packets.data(), packets.size() * sizeof(RayPacket));
  at += packets.size() * sizeof(RayPacket);
  std::memcpy(at, ranges.data(), ranges.size() * sizeof(FaceRange));
  at += ranges.size() * sizeof(FaceRange);
  pages.readCorners(root.first, root.count, reinterpret_cast<Corners*>(at + root.count * sizeof(uint64_t)),
                    reinterpret_cast<uint64_t*>(at));
}

}  // namespace

// The nodes above the pages laid out here; every subtree page laid out once, on every core, and
// written beside the pages, so that a ray entering a page reads its layout and nothing more.
RayPages::RayPages(NodePages& pages) : pages_(pages) {
  if (pages.nodeCount() == 0) return;
  TopView view(pages);
  const NodeRef root = pages.root();
  const FchNode& rootNode = view.node(root);
  layOut(
      view, root, rootNode.box,
      [&](const NodeRef& ref) { return pages.inTop(ref) ? kNoPage : pages.pageOf(ref); }, top_, topRanges_);
  const std::span<const uint32_t> ids = pages.subtreePages();
  std::atomic<size_t> next{0};
  runWorkers(std::clamp(std::thread::hardware_concurrency(), 1u, 8u),
             [&](unsigned, const std::atomic<bool>& failed) {
               std::vector<std::byte> blob;
               for (size_t k; !failed && (k = next.fetch_add(1)) < ids.size();) {
                 layOutPage(pages, ids[k], blob);
                 pages.writeDerived(ids[k], blob);
               }
             });
}

RaySpans RayPages::spans(const MappedBytes& page) {
  PageHead head;
  std::memcpy(&head, page.data(), sizeof head);
  const std::byte* at = page.data() + kHeadBytes;
  const auto* packets = reinterpret_cast<const RayPacket*>(at);
  at += head.packets * sizeof(RayPacket);
  const auto* ranges = reinterpret_cast<const FaceRange*>(at);
  at += head.ranges * sizeof(FaceRange);
  const auto* originals = reinterpret_cast<const uint64_t*>(at);
  at += head.corners * sizeof(uint64_t);
  const auto* corners = reinterpret_cast<const Corners*>(at);
  return {{packets, head.packets},
          {ranges, head.ranges},
          {corners, head.corners},
          head.cornerFirst,
          {originals, head.corners}};
}

NodePages::Page RayPages::page(uint32_t id) {
  return pages_.derived(id);
}

}  // namespace facetree::query
