// A reader's nodes laid out for queries (node_pages.h).
#include "node_pages.h"

#include <sys/mman.h>

#include <algorithm>
#include <cstring>
#include <new>
#include <numeric>
#include <string>

#include "facetree/error.h"

namespace facetree::query {

namespace {

constexpr size_t kRecordHead = 56;  // index, first, count, childCount, flags, box

// What a mapping of `bytes` takes: whole pages of the system.
uint64_t mappedBytes(size_t bytes) {
  return (uint64_t{bytes} + 4095) & ~uint64_t{4095};
}

// A file whose structure the pages cannot hold (face ranges that do not nest).
Error badStructure(const std::string& name, uint64_t node, const std::string& reason) {
  return Error(ErrorCategory::Input, name + ": node " + std::to_string(node) + ": " + reason);
}

void encode(uint32_t index, const FchNode& node, unsigned branching, std::byte* out) {
  const uint32_t head[3] = {index, node.first, node.count};
  std::memcpy(out, head, 12);
  out[12] = std::byte{node.childCount};
  out[13] = std::byte{node.flags};
  out[14] = out[15] = std::byte{0};
  const float box[10] = {node.box.center.x,      node.box.center.y,      node.box.center.z,
                         node.box.halfExtent.x,  node.box.halfExtent.y,  node.box.halfExtent.z,
                         node.box.orientation.x, node.box.orientation.y, node.box.orientation.z,
                         node.box.orientation.w};
  std::memcpy(out + 16, box, sizeof box);
  std::memcpy(out + kRecordHead, node.child, 4 * branching);
  std::memcpy(out + kRecordHead + 4 * branching, node.childFaces, 4 * branching);
}

uint32_t recordIndex(const std::byte* record) {
  uint32_t index;
  std::memcpy(&index, record, 4);
  return index;
}

FchNode decode(const std::byte* in, unsigned branching) {
  FchNode node;
  std::memcpy(&node.first, in + 4, 4);
  std::memcpy(&node.count, in + 8, 4);
  node.childCount = static_cast<uint8_t>(in[12]);
  node.flags = static_cast<uint8_t>(in[13]);
  float box[10];
  std::memcpy(box, in + 16, sizeof box);
  node.box.center = {box[0], box[1], box[2]};
  node.box.halfExtent = {box[3], box[4], box[5]};
  node.box.orientation.x = box[6], node.box.orientation.y = box[7], node.box.orientation.z = box[8];
  node.box.orientation.w = box[9];
  std::memcpy(node.child, in + kRecordHead, 4 * branching);
  std::memcpy(node.childFaces, in + kRecordHead + 4 * branching, 4 * branching);
  return node;
}

}  // namespace

MappedBytes::MappedBytes(size_t bytes) : size_(bytes), capacity_(bytes) {
  if (bytes == 0) return;
  void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
  data_ = static_cast<std::byte*>(p);
}

MappedBytes::~MappedBytes() {
  if (data_) ::munmap(data_, capacity_);
}

std::shared_ptr<MappedBytes> SpareMappings::take(const std::shared_ptr<SpareMappings>& spare, size_t bytes) {
  const size_t capacity = (bytes + 16383) & ~size_t{16383};
  std::unique_ptr<MappedBytes> mapping;
  {
    std::lock_guard lock(spare->mutex_);
    if (const auto it = spare->kept_.find(capacity); it != spare->kept_.end()) {
      mapping = std::move(it->second);
      spare->kept_.erase(it);
      spare->held_ -= capacity;
    }
  }
  if (!mapping) mapping = std::make_unique<MappedBytes>(capacity);
  mapping->resize(bytes);
  return {mapping.release(), [spare](MappedBytes* m) { spare->give(std::unique_ptr<MappedBytes>(m)); }};
}

void SpareMappings::give(std::unique_ptr<MappedBytes> bytes) {
  std::lock_guard lock(mutex_);
  if (held_ + bytes->capacity() > limit_) return;  // unmapped
  held_ += bytes->capacity();
  kept_.emplace(bytes->capacity(), std::move(bytes));
}

NodePages::NodePages(ClusterFileReader& reader, uint64_t budget, uint32_t pageFaces, uint32_t topRecords)
    : pageFaces_(pageFaces),
      topRecords_(std::max<uint32_t>(topRecords, 1)),
      branching_(reader.header().branching),
      file_(reader.temporaryDirectory()),
      budget_(std::max<uint64_t>(budget, 1)),
      spare_(std::make_shared<SpareMappings>(budget / 8)) {
  stride_ = kRecordHead + 8 * size_t{branching_};
  build(reader, std::max<uint64_t>(budget / 2, stride_ * 64));
  writeTriangles(reader);
}

// In file order every node's parent comes first, so its page root is known when it arrives: the
// subtree pages found so far are disjoint face ranges, and the one holding the node's first face
// holds the node (ranges nest), else the node is a new page's root.
void NodePages::build(ClusterFileReader& reader, uint64_t stageBytes) {
  std::map<uint32_t, uint32_t> roots;  // first face -> page id, for the pages found so far
  std::vector<std::byte> stage;        // records waiting to be written, and their pages
  std::vector<uint32_t> stagePage;
  std::vector<uint32_t> order;
  std::vector<std::byte> run;
  const auto reserve = [&](uint32_t capacity) {
    pages_.push_back({fileBytes_, capacity, 0});
    fileBytes_ += uint64_t{capacity} * stride_;
    return static_cast<uint32_t>(pages_.size() - 1);
  };
  const auto flush = [&] {
    order.resize(stagePage.size());
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(),
                     [&](uint32_t a, uint32_t b) { return stagePage[a] < stagePage[b]; });
    for (size_t i = 0; i < order.size();) {
      const uint32_t id = stagePage[order[i]];
      size_t j = i;
      run.clear();
      for (; j < order.size() && stagePage[order[j]] == id; ++j) {
        const std::byte* r = &stage[size_t{order[j]} * stride_];
        run.insert(run.end(), r, r + stride_);
      }
      PageEntry& page = pages_[id];
      const uint64_t count = j - i;
      if (page.records + count > page.capacity)
        throw badStructure(name_, recordIndex(run.data()),
                           "more nodes under its page root than its faces allow");
      file_.write(page.offset + uint64_t{page.records} * stride_, run.data(), run.size());
      page.records += static_cast<uint32_t>(count);
      i = j;
    }
    stage.clear(), stagePage.clear();
  };
  uint32_t topInChunk = topRecords_;
  const size_t stageRecords = std::max<size_t>(1, stageBytes / stride_);
  stage.reserve(std::min<size_t>(stageRecords, 1 << 16) * stride_);
  // Version 1 records lack their node children's face counts: a first pass keeps every node's
  // range in a temporary file, read back for each node child.
  std::unique_ptr<TemporaryFile> ranges;
  const uint64_t nodeCount = reader.size();
  if (reader.header().version == 1) {
    ranges = std::make_unique<TemporaryFile>(reader.temporaryDirectory());
    std::vector<uint32_t> run;
    const auto flushRanges = [&](uint64_t next) {
      ranges->write((next - run.size() / 2) * 8, run.data(), run.size() * 4);
      run.clear();
    };
    reader.forEachNode(
        [&](uint64_t index, const FchNode& node, uint32_t) {
          run.push_back(node.first), run.push_back(node.count);
          if (run.size() == 2 * 8192) flushRanges(index + 1);
          return true;
        },
        NodeFields::Structure);
    flushRanges(nodeCount);
  }
  FchNode filled;
  reader.forEachNode([&](uint64_t index, const FchNode& read, uint32_t) {
    const FchNode* source = &read;
    if (ranges) {
      filled = read;
      fillVersion1ChildFaces(filled, nodeCount, [&](uint32_t child) {
        uint32_t range[2];
        ranges->read(uint64_t{child} * 8, range, 8);
        return std::pair{range[0], range[1]};
      });
      source = &filled;
    }
    const FchNode& node = *source;
    if (index == 0) rootCount_ = node.count;
    uint32_t id;
    if (node.count > pageFaces_) {
      if (topInChunk == topRecords_) {
        topPage_.push_back(reserve(topRecords_));
        topFirstIndex_.push_back(static_cast<uint32_t>(index));
        topInChunk = 0;
      }
      id = topPage_.back();
      ++topInChunk;
    } else {
      auto it = roots.upper_bound(node.first);
      if (it != roots.begin()) --it;
      const bool inside =
          it != roots.end() && it->first <= node.first &&
          uint64_t{node.first} + node.count <=
              uint64_t{it->first} + pages_[it->second].capacity;  // capacity = the root's faces
      if (inside) {
        id = it->second;
      } else {
        id = reserve(std::max<uint32_t>(node.count, 1));
        if (!roots.emplace(node.first, id).second)
          throw badStructure(name_, index, "its face range starts another's");
      }
    }
    const size_t at = stage.size();
    stage.resize(at + stride_);
    encode(static_cast<uint32_t>(index), node, branching_, &stage[at]);
    stagePage.push_back(id);
    ++nodes_;
    if (stagePage.size() >= stageRecords) flush();
    return true;
  });
  flush();
  std::vector<std::byte>().swap(stage);
  std::vector<uint32_t>().swap(stagePage);
  std::vector<uint32_t>().swap(order);
  std::vector<std::byte>().swap(run);

  // The subtree pages by their roots' ranges.
  rootFirst_.reserve(roots.size()), rootEnd_.reserve(roots.size()), rootPage_.reserve(roots.size());
  for (const auto& [first, id] : roots) {
    rootFirst_.push_back(first);
    rootEnd_.push_back(first + pages_[id].capacity);
    rootPage_.push_back(id);
  }
}

uint32_t NodePages::pageOf(const NodeRef& ref) const {
  if (inTop(ref)) {
    const auto it = std::upper_bound(topFirstIndex_.begin(), topFirstIndex_.end(), ref.index);
    if (it == topFirstIndex_.begin()) throw badStructure(name_, ref.index, "not in the top");
    return topPage_[static_cast<size_t>(it - topFirstIndex_.begin() - 1)];
  }
  const auto it = std::upper_bound(rootFirst_.begin(), rootFirst_.end(), ref.first);
  const size_t k = static_cast<size_t>(it - rootFirst_.begin());
  if (k == 0 || ref.first >= rootEnd_[k - 1])
    throw badStructure(name_, ref.index, "its faces lie in no page");
  return rootPage_[k - 1];
}

NodePages::Page NodePages::page(uint32_t id) {
  const PageEntry& entry = pages_[id];
  return cached(id, entry.offset, size_t{entry.records} * stride_);
}

void NodePages::pastTriangles(uint64_t p) const {
  throw Error(ErrorCategory::Input, name_ + ": face " + std::to_string(p) + " past the triangles");
}

NodePages::Page NodePages::block(uint64_t b) {
  const uint64_t first = b * kBlockTriangles;
  if (first >= faces_) pastTriangles(first);
  const uint64_t n = std::min<uint64_t>(kBlockTriangles, faces_ - first);
  return cached(pages_.size() + b, trianglesOffset_ + b * kBlockTriangles * kTriangleBytes,
                n * kTriangleBytes);
}

void NodePages::corners(const MappedBytes& block, uint64_t p, glm::vec3 (&out)[3]) {
  std::memcpy(out, block.data() + (p % kBlockTriangles) * kCornerBytes, kCornerBytes);
}

uint64_t NodePages::originalFace(const MappedBytes& block, uint64_t p) {
  const uint64_t n = block.size() / kTriangleBytes;  // the block's triangles
  uint64_t id;
  std::memcpy(&id, block.data() + n * kCornerBytes + (p % kBlockTriangles) * 8, 8);
  return id;
}

NodePages::Page NodePages::lookup(uint64_t key) {
  const auto it = cache_.find(key);
  if (it == cache_.end()) return nullptr;
  uses_.splice(uses_.begin(), uses_, it->second.use);
  return it->second.bytes;
}

NodePages::Page NodePages::cached(uint64_t key, uint64_t offset, size_t bytes) {
  std::lock_guard lock(mutex_);
  if (Page page = lookup(key)) return page;
  auto mapped = allocate(bytes);
  file_.read(offset, mapped->data(), mapped->size());
  return insert(key, std::move(mapped));
}

NodePages::Page NodePages::insert(uint64_t key, std::shared_ptr<MappedBytes> bytes) {
  held_ += mappedBytes(bytes->capacity());
  uses_.push_front(key);
  Page page = cache_.emplace(key, Cached{std::move(bytes), uses_.begin()}).first->second.bytes;
  while (held_ > budget_ && cache_.size() > 1) {  // the least recently used other entry leaves
    const auto oldest = cache_.find(uses_.back());
    held_ -= mappedBytes(oldest->second.bytes->capacity());
    cache_.erase(oldest);
    uses_.pop_back();
  }
  peak_ = std::max(peak_, held_);
  return page;
}

NodePages::Page NodePages::derived(uint32_t id) {
  const uint64_t key = pages_.size() + (faces_ + kBlockTriangles - 1) / kBlockTriangles + id;
  std::pair<uint64_t, uint64_t> at;
  {
    std::lock_guard lock(mutex_);
    if (Page page = lookup(key)) return page;
    at = derived_.at(id);
  }
  auto mapped = allocate(at.second);  // read outside the lock: the other threads' pages meanwhile
  file_.read(at.first, mapped->data(), at.second);
  std::lock_guard lock(mutex_);
  if (Page page = lookup(key)) return page;  // another thread read it meanwhile
  return insert(key, std::move(mapped));
}

void NodePages::writeDerived(uint32_t id, std::span<const std::byte> bytes) {
  std::lock_guard lock(mutex_);
  if (derived_.empty()) derived_.resize(pages_.size());
  derived_[id] = {fileBytes_, bytes.size()};
  file_.write(fileBytes_, bytes.data(), bytes.size());
  fileBytes_ += bytes.size();
  derivedBytes_ += bytes.size();
}

std::vector<std::byte> NodePages::records(uint32_t id) {
  const PageEntry& entry = pages_[id];
  std::vector<std::byte> out(size_t{entry.records} * stride_);
  file_.read(entry.offset, out.data(), out.size());
  return out;
}

std::pair<NodeRef, FchNode> NodePages::root(uint32_t id) {
  std::vector<std::byte> record(stride_);
  file_.read(pages_[id].offset, record.data(), stride_);
  return root(record);
}

std::pair<NodeRef, FchNode> NodePages::root(std::span<const std::byte> records) const {
  const FchNode node = decode(records.data(), branching_);
  return {NodeRef{recordIndex(records.data()), node.first, node.count}, node};
}

void NodePages::readCorners(uint64_t first, uint64_t count, std::array<glm::vec3, 3>* out,
                            uint64_t* originals) {
  if (count > 0 && first + count > faces_) pastTriangles(first + count - 1);
  for (uint64_t p = first; p < first + count;) {  // block by block: its corners, then its ids
    const uint64_t b = p / kBlockTriangles, end = std::min(first + count, (b + 1) * kBlockTriangles);
    const uint64_t block = trianglesOffset_ + b * kBlockTriangles * kTriangleBytes;
    const uint64_t n = std::min<uint64_t>(kBlockTriangles, faces_ - b * kBlockTriangles);
    file_.read(block + (p % kBlockTriangles) * kCornerBytes, out + (p - first), (end - p) * kCornerBytes);
    file_.read(block + n * kCornerBytes + (p % kBlockTriangles) * 8, originals + (p - first), (end - p) * 8);
    p = end;
  }
}

// The triangle frames in face order, each triangle's corners and id into its block.
void NodePages::writeTriangles(ClusterFileReader& reader) {
  faces_ = reader.header().triangleCount;
  trianglesOffset_ = fileBytes_;
  std::vector<std::byte> block(size_t{kBlockTriangles} * kTriangleBytes);
  uint64_t next = 0;  // the next face position to place
  const auto put = [&](uint64_t p, const glm::vec3(&corner)[3], uint64_t id) {
    if (p != next)
      throw Error(ErrorCategory::Input,
                  name_ + ": face " + std::to_string(p) + ": out of order in the triangle pass");
    const uint64_t first = p - p % kBlockTriangles;
    const uint64_t n = std::min<uint64_t>(kBlockTriangles, faces_ - first);
    const uint64_t k = p % kBlockTriangles;
    std::memcpy(&block[k * kCornerBytes], corner, kCornerBytes);
    std::memcpy(&block[n * kCornerBytes + k * 8], &id, 8);
    if (k + 1 == n) file_.write(trianglesOffset_ + first * kTriangleBytes, block.data(), n * kTriangleBytes);
    ++next;
  };
  reader.forEachFacePiece([&](const FaceRangeMesh& piece) {
    const size_t triangles = piece.indices.size() / 3;
    for (size_t t = 0; t < triangles; ++t) {
      glm::vec3 corner[3];
      for (int c = 0; c < 3; ++c) corner[c] = piece.vertices[piece.indices[3 * t + c]];
      put(piece.first + t, corner, t < piece.originalFace.size() ? piece.originalFace[t] : piece.first + t);
    }
  });
  if (next != faces_)
    throw Error(ErrorCategory::Input, name_ + ": the triangle pass gave " + std::to_string(next) + " of " +
                                          std::to_string(faces_) + " triangles");
  fileBytes_ += faces_ * kTriangleBytes;
}

FchNode NodePages::find(const MappedBytes& page, const NodeRef& ref) const {
  return find(std::span<const std::byte>(page.data(), page.size()), ref);
}

FchNode NodePages::find(std::span<const std::byte> records, const NodeRef& ref) const {
  size_t lo = 0, hi = records.size() / stride_;
  while (lo < hi) {
    const size_t mid = (lo + hi) / 2;
    if (recordIndex(&records[mid * stride_]) < ref.index)
      lo = mid + 1;
    else
      hi = mid;
  }
  if (lo == records.size() / stride_ || recordIndex(&records[lo * stride_]) != ref.index)
    throw badStructure(name_, ref.index, "not in the page of its face range");
  return decode(&records[lo * stride_], branching_);
}

}  // namespace facetree::query
