// Internal to io/: the byte layout of the cluster file (docs/FORMAT.md), shared by the writer,
// the reader and truncation. Nothing here is public API.
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "facetree/io.h"

namespace facetree::fch {

// Appends the bytes of `value` to `out`: the host is little-endian, as the file (fch_format.cpp).
template <class T>
void put(std::string& out, const T& value) {
  static_assert(std::is_trivially_copyable_v<T>);
  out.append(reinterpret_cast<const char*>(&value), sizeof value);
}

inline constexpr uint8_t kMagic[8] = {0x89, 'F', 'C', 'H', '\r', '\n', 0x1A, '\n'};
inline constexpr uint32_t kHeaderBytes = 192;
inline constexpr uint32_t kHeaderChecksumOffset = 184;
inline constexpr uint32_t kIndexEntryBytes = 40;
inline constexpr uint32_t kMaxNodesPerFrame = 65536;
inline constexpr uint32_t kMaxGeometryPerFrame = 1u << 20;
// childCount u8 + flags u8 + first u32 + count u32 + 22 f32 (cost, area, perimeter, S, box).
inline constexpr uint32_t kNodeFixedBytes = 2 + 4 + 4 + 22 * 4;
// Version 2: bytes of a node's fixed columns in a frame of `precision` boxes (refs and counts: 4
// each). Shape, faceMask, derived; cost, area, perimeter; S; side sums; orientation; box.
inline constexpr uint32_t nodeFixedBytes(BoxPrecision precision) {
  return 3 + 12 + 6 + 6 + (precision == BoxPrecision::Compact ? 3 + 6 : 6 + 1 + 12 + 9);
}
inline constexpr uint8_t kStoredFlagMask = kFchJoinsDisjointSurfaces | kFchFlatFrame;
// Face positions share 32 bits with kFaceChild, so a file holds fewer than 2^31 triangles.
inline constexpr uint64_t kMaxTriangles = kFaceChild - 1;

// XXH64 (Collet; libxxhash), seed 0 unless given: the checksum of headers, index and frames.
uint64_t xxh64(const void* data, size_t bytes, uint64_t seed = 0);

class NodeDecoder;

// One frame as assembled for writing: its index entry (offset filled in by writeFrames) and
// its compressed bytes.
struct FrameData {
  static constexpr size_t kNoCopy = ~size_t{0};
  FchFrame entry;
  std::string compressed;
  // Else frame `copyOf` of the source writeFrames is given, copied as its compressed bytes
  // (checksum checked) when written: `compressed` stays empty, entry.compressedBytes is its size.
  size_t copyOf = kNoCopy;
  uint64_t bytes() const { return copyOf == kNoCopy ? compressed.size() : entry.compressedBytes; }
};

// Payload encoders (docs/FORMAT.md "Frame payloads").
std::string encodeNodes(std::span<const FchNode> nodes, uint64_t firstIndex);
// The geometry encoders replace `out`'s contents, keeping its capacity for the next frame.
void encodeVertices(std::span<const glm::vec3> vertices, std::string& out);
void encodeTriangles(std::span<const uint32_t> indices, std::string& out);
void encodeIds(std::span<const uint64_t> ids, uint32_t width, std::string& out);

// Compresses a payload into a frame entry of `section` covering [first, first + count).
// `boxes`: the file's box precision (FrameCompressor).
FrameData makeFrame(FchSection section, uint64_t first, uint32_t count, const std::string& raw, int level,
                    BoxPrecision boxes);

// The same with one zstd context kept across frames (ZSTD_compressCCtx gives the bytes
// ZSTD_compress gives), compressing into a caller-owned buffer whose capacity is reused: the
// streaming writer's per-frame cost is the payload and this buffer, never a fresh context.
class FrameCompressor {
 public:
  // `boxes`: the file's box precision, for the match finder's step in node frames.
  FrameCompressor(int level, BoxPrecision boxes);
  ~FrameCompressor();
  FrameCompressor(const FrameCompressor&) = delete;
  FrameCompressor& operator=(const FrameCompressor&) = delete;
  // Compresses `raw` into `out` and returns the frame's index entry (offset left 0).
  FchFrame compress(FchSection section, uint64_t first, uint32_t count, std::string_view raw,
                    std::string& out);

 private:
  struct Context;
  std::unique_ptr<Context> context_;
};

// ZSTD_compressBound: the largest compressed frame of `rawBytes`.
uint64_t compressedBound(uint64_t rawBytes);
// Bytes a FrameCompressor at `level` holds for payloads of up to `rawBytes` (zstd's estimate).
uint64_t compressorMemoryBound(int level, uint64_t rawBytes);

// The header followed by the frame index of `layout`, whose frames carry their offsets and
// whose fileBytes is the final size.
std::string encodeHeaderAndIndex(const FchLayout& layout);

// Writes header + index + frames through OutputFile (atomic); `layout` supplies the header
// fields, the frame offsets and sizes are computed here. Returns the file size.
class SourceFile;
uint64_t writeFrames(const std::filesystem::path& path, FchLayout layout,
                     const std::vector<FrameData>& frames, const SourceFile* source = nullptr);

// A cluster file open for reading: validated header and index, frames read on demand.
class SourceFile {
 public:
  explicit SourceFile(const std::filesystem::path& path);
  // An open descriptor of a regular file, read at offsets through a duplicate of it (the caller
  // keeps and closes its own); `name` in every message.
  SourceFile(int fd, std::string name);
  ~SourceFile();
  SourceFile(const SourceFile&) = delete;
  SourceFile& operator=(const SourceFile&) = delete;

  const FchLayout& layout() const { return layout_; }
  const std::string& name() const { return name_; }
  // The compressed bytes of frame `i`, checksum checked.
  std::string compressedFrame(size_t i) const;
  void compressedFrame(size_t i, std::string& out) const;  // into `out`, whose capacity is reused
  // The decompressed payload of frame `i`, checksum and size checked.
  std::string rawFrame(size_t i) const;
  // The same into `raw`, with `compressed` as the read buffer; both keep their capacity.
  void rawFrame(size_t i, std::string& raw, std::string& compressed) const;
  // Version 1: decodes node frame `i` (payload `raw`) and appends its nodes to `out` (the frames
  // of version 1 stand on their own; version 2's decode in order through a NodeDecoder).
  void decodeNodes(size_t i, const std::string& raw, std::vector<FchNode>& out) const;
  void decodeVertices(size_t i, const std::string& raw, std::vector<glm::vec3>& out) const;
  void decodeTriangles(size_t i, const std::string& raw, std::vector<uint32_t>& out) const;
  void decodeIds(size_t i, const std::string& raw, std::vector<uint64_t>& out) const;
  // "FILE: node frame 3 (nodes 12288-16383)"
  std::string where(size_t i) const;
  [[noreturn]] void fail(const std::string& reason) const;

 private:
  std::string readAt(uint64_t offset, uint64_t bytes) const;
  void readAt(uint64_t offset, uint64_t bytes, std::string& out) const;
  void readLayout();
  std::string name_;
  struct Closer {
    void operator()(std::FILE* f) const;
  };
  std::unique_ptr<std::FILE, Closer> file_;
  uint64_t size_ = 0;
  FchLayout layout_;
};

// What io's own code takes from a ClusterFileReader beyond its public face: the frames as stored.
struct ReaderAccess {
  static const SourceFile& source(const ClusterFileReader& reader);
};

}  // namespace facetree::fch
