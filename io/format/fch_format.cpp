// The cluster file's byte layout: header, frame index, column payloads, zstd frames
// (docs/FORMAT.md). Shared by the writers (write/writer.cpp, write/pieces.cpp), the readers
// (read/lazy_reader.cpp, read/whole_file.cpp), the node records (format/node_code.cpp) and
// truncation (cut/truncate.cpp).
#include "format/fch_format.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#define ZSTD_STATIC_LINKING_ONLY  // ZSTD_estimateCCtxSize_usingCParams, for the memory bound
#include <xxhash.h>
#include <zstd.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <new>
#include <stdexcept>

#include "facetree/io.h"
#include "format/byte_planes.h"

namespace facetree::fch {

uint64_t xxh64(const void* data, size_t bytes, uint64_t seed) {
  return XXH64(data, bytes, seed);
}

namespace {

static_assert(std::endian::native == std::endian::little,
              "the cluster file code assumes a little-endian host");

template <class T>
T get(const uint8_t* p) {
  T value;
  std::memcpy(&value, p, sizeof(T));
  return value;
}

constexpr const char* kSectionWords[] = {"", "node", "vertex", "triangle", "original-id"};
constexpr const char* kElementWords[] = {"", "nodes", "vertices", "triangles", "ids"};

std::string encodeHeader(const FchLayout& layout, uint64_t indexChecksum, uint32_t frameCount) {
  const FileHeader& h = layout.header;
  std::string out(reinterpret_cast<const char*>(kMagic), sizeof kMagic);
  put<uint32_t>(out, h.version);
  put<uint32_t>(out, kHeaderBytes);
  put<uint64_t>(out, layout.fileBytes);
  put<uint64_t>(out, h.nodeCount);
  put<uint64_t>(out, h.originalNodeCount);
  put<uint64_t>(out, h.triangleCount);
  put<uint64_t>(out, h.vertexCount);
  put<uint32_t>(out, frameCount);
  put<uint32_t>(out, layout.nodesPerFrame);
  put<uint32_t>(out, layout.geometryPerFrame);
  put<uint8_t>(out, static_cast<uint8_t>(h.branching));
  put<uint8_t>(out, static_cast<uint8_t>(h.metric));
  put<uint8_t>(out, static_cast<uint8_t>(layout.originalIdBytes));
  put<uint8_t>(out, h.version >= 2 ? static_cast<uint8_t>(h.boxes) : 0);
  put<double>(out, h.k);
  put<double>(out, h.flatThreshold);
  put<uint64_t>(out, h.memoryCapBytes);
  for (int a = 0; a < 3; ++a) put<float>(out, h.boundsMin[a]);
  for (int a = 0; a < 3; ++a) put<float>(out, h.boundsMax[a]);
  put<uint64_t>(out, indexChecksum);
  put<int32_t>(out, layout.zstdLevel);
  put<uint32_t>(out, h.version >= 2 ? h.topClusters : 0);
  for (double w : h.garlandWeights) put<double>(out, w);
  if (h.version >= 2 && h.boxes == BoxPrecision::Compact) {
    for (int a = 0; a < 3; ++a) put<float>(out, layout.rootBox.center[a]);
    for (int a = 0; a < 3; ++a) put<float>(out, layout.rootBox.halfExtent[a]);
  }
  out.resize(kHeaderChecksumOffset, '\0');
  put<uint64_t>(out, xxh64(out.data(), out.size()));
  return out;
}

}  // namespace

std::string encodeNodes(std::span<const FchNode> nodes, uint64_t firstIndex) {
  const size_t n = nodes.size();
  std::string out;
  size_t children = 0;
  for (const FchNode& node : nodes) children += node.childCount;
  out.reserve(kNodeFixedBytes * n + 4 * children);
  putColumn(
      out, n, [&](size_t i) { return nodes[i].childCount; }, 1);
  putColumn(
      out, n, [&](size_t i) { return nodes[i].flags & kStoredFlagMask; }, 1);
  putColumn(out, n, [&](size_t i) { return nodes[i].first; });
  putColumn(out, n, [&](size_t i) { return nodes[i].count; });
  putColumn(out, n, [&](size_t i) { return bits(nodes[i].cost); });
  putColumn(out, n, [&](size_t i) { return bits(nodes[i].area); });
  putColumn(out, n, [&](size_t i) { return bits(nodes[i].perimeter); });
  for (int a = 0; a < 3; ++a) putColumn(out, n, [&](size_t i) { return bits(nodes[i].sumNormal[a]); });
  for (int a = 0; a < 3; ++a) putColumn(out, n, [&](size_t i) { return bits(nodes[i].box.center[a]); });
  for (int a = 0; a < 4; ++a) putColumn(out, n, [&](size_t i) { return bits(nodes[i].box.orientation[a]); });
  for (int a = 0; a < 3; ++a) putColumn(out, n, [&](size_t i) { return bits(nodes[i].box.halfExtent[a]); });
  for (int a = 0; a < 6; ++a) putColumn(out, n, [&](size_t i) { return bits(nodes[i].box.sideArea[a]); });
  // Child references relative to the node (node children) or to its first face (face children):
  // small numbers that compress well, and unchanged by truncation.
  std::vector<uint32_t> refs;
  refs.reserve(children);
  for (size_t i = 0; i < n; ++i)
    for (unsigned c = 0; c < nodes[i].childCount; ++c) {
      const uint32_t ref = nodes[i].child[c];
      refs.push_back(ref & kFaceChild ? kFaceChild | ((ref & ~kFaceChild) - nodes[i].first)
                                      : static_cast<uint32_t>(ref - (firstIndex + i)));
    }
  putColumn(out, refs.size(), [&](size_t i) { return refs[i]; });
  return out;
}

void encodeVertices(std::span<const glm::vec3> vertices, std::string& out) {
  out.clear();
  for (int a = 0; a < 3; ++a) putColumn(out, vertices.size(), [&](size_t i) { return bits(vertices[i][a]); });
}

void encodeTriangles(std::span<const uint32_t> indices, std::string& out) {
  out.clear();
  putColumn(out, indices.size(), [&](size_t i) {
    const uint32_t previous = i ? indices[i - 1] : 0;
    return zigzag32(static_cast<int32_t>(indices[i] - previous));
  });
}

void encodeIds(std::span<const uint64_t> ids, uint32_t width, std::string& out) {
  out.clear();
  putColumn(
      out, ids.size(),
      [&](size_t i) {
        const uint64_t previous = i ? ids[i - 1] : 0;
        return width == 4 ? uint64_t{zigzag32(static_cast<int32_t>(static_cast<uint32_t>(ids[i] - previous)))}
                          : zigzag(static_cast<int64_t>(ids[i] - previous));
      },
      width);
}

FrameData makeFrame(FchSection section, uint64_t first, uint32_t count, const std::string& raw, int level,
                    BoxPrecision boxes) {
  FrameData frame;
  frame.entry = FrameCompressor(level, boxes).compress(section, first, count, raw, frame.compressed);
  return frame;
}

struct FrameCompressor::Context {
  ZSTD_CCtx* cctx = ZSTD_createCCtx();
  int nodeTargetLength = 0;  // for node frames; 0: zstd's default for the level
  int targetLength = 0;      // as set in cctx
  ~Context() { ZSTD_freeCCtx(cctx); }
};

// The default level's match finder (FrameCompressor): zstd's single-hash finder at level 3's
// table size. Byte planes are runs of slowly varying high bytes beside incompressible low ones,
// where the double-hash finder of levels 3 to 4 finds hardly more (docs/benchmarks.md).
constexpr ZSTD_strategy kDefaultLevelStrategy = ZSTD_fast;
constexpr unsigned kDefaultLevelHashLog = 17, kDefaultLevelMinMatch = 4;
// Exact-box node frames at the default level: the finder steps faster through bytes where it finds
// no match (the fast strategy's targetLength). Half of such a frame is the low bytes of floats and
// box fields, random: dragon_vrip's node payload compresses 1.85x faster for 1.4% more bytes,
// while compact boxes' frames would lose 3.4% and the geometry's delta-coded planes 3-12%
// (docs/benchmarks.md).
constexpr int kNodeTargetLength = 2;

FrameCompressor::FrameCompressor(int level, BoxPrecision boxes) : context_(std::make_unique<Context>()) {
  if (!context_->cctx) throw std::bad_alloc();
  ZSTD_CCtx* c = context_->cctx;
  ZSTD_CCtx_setParameter(c, ZSTD_c_compressionLevel, level);
  if (level == kDefaultZstdLevel) {
    if (boxes == BoxPrecision::Exact) context_->nodeTargetLength = kNodeTargetLength;
    ZSTD_CCtx_setParameter(c, ZSTD_c_strategy, kDefaultLevelStrategy);
    ZSTD_CCtx_setParameter(c, ZSTD_c_hashLog, kDefaultLevelHashLog);
    ZSTD_CCtx_setParameter(c, ZSTD_c_minMatch, kDefaultLevelMinMatch);
  }
}

FrameCompressor::~FrameCompressor() = default;

FchFrame FrameCompressor::compress(FchSection section, uint64_t first, uint32_t count, std::string_view raw,
                                   std::string& out) {
  FchFrame entry;
  entry.section = section;
  entry.first = first;
  entry.count = count;
  entry.rawBytes = static_cast<uint32_t>(raw.size());
  if (const int targetLength = section == FchSection::Nodes ? context_->nodeTargetLength : 0;
      targetLength != context_->targetLength) {
    ZSTD_CCtx_setParameter(context_->cctx, ZSTD_c_targetLength, targetLength);
    context_->targetLength = targetLength;
  }
  out.resize(ZSTD_compressBound(raw.size()));
  const size_t got = ZSTD_compress2(context_->cctx, out.data(), out.size(), raw.data(), raw.size());
  if (ZSTD_isError(got))
    throw std::runtime_error(std::string("zstd compression failed: ") + ZSTD_getErrorName(got));
  out.resize(got);
  entry.compressedBytes = static_cast<uint32_t>(got);
  entry.checksum = xxh64(out.data(), got);
  return entry;
}

uint64_t compressedBound(uint64_t rawBytes) {
  return ZSTD_compressBound(static_cast<size_t>(rawBytes));
}

uint64_t compressorMemoryBound(int level, uint64_t rawBytes) {
  ZSTD_compressionParameters params = ZSTD_getCParams(level, rawBytes, 0);
  if (level == kDefaultZstdLevel) {  // as FrameCompressor's
    params.strategy = kDefaultLevelStrategy;
    params.hashLog = kDefaultLevelHashLog;
    params.minMatch = kDefaultLevelMinMatch;
  }
  return ZSTD_estimateCCtxSize_usingCParams(params);
}

std::string encodeHeaderAndIndex(const FchLayout& layout) {
  std::string index;
  index.reserve(kIndexEntryBytes * layout.frames.size());
  for (const FchFrame& f : layout.frames) {
    put<uint32_t>(index, static_cast<uint32_t>(f.section));
    put<uint32_t>(index, f.count);
    put<uint64_t>(index, f.first);
    put<uint64_t>(index, f.offset);
    put<uint32_t>(index, f.compressedBytes);
    put<uint32_t>(index, f.rawBytes);
    put<uint64_t>(index, f.checksum);
  }
  return encodeHeader(layout, xxh64(index.data(), index.size()),
                      static_cast<uint32_t>(layout.frames.size())) +
         index;
}

uint64_t writeFrames(const std::filesystem::path& path, FchLayout layout,
                     const std::vector<FrameData>& frames, const SourceFile* source) {
  uint64_t offset = kHeaderBytes + uint64_t{kIndexEntryBytes} * frames.size();
  layout.frames.clear();
  layout.frames.reserve(frames.size());
  for (const FrameData& f : frames) {
    FchFrame& entry = layout.frames.emplace_back(f.entry);
    entry.offset = offset;
    entry.compressedBytes = static_cast<uint32_t>(f.bytes());
    offset += f.bytes();
  }
  layout.fileBytes = offset;
  OutputFile out(path);
  out.write(encodeHeaderAndIndex(layout));
  std::string copy;
  for (const FrameData& f : frames) {
    if (f.copyOf == FrameData::kNoCopy) {
      out.write(f.compressed);
    } else {
      if (!source) throw std::logic_error("writeFrames: a frame to copy and no source");
      source->compressedFrame(f.copyOf, copy);
      out.write(copy);
    }
  }
  out.commit();
  return offset;
}

// ---------------------------------------------------------------------------------------------
// Reading

void SourceFile::Closer::operator()(std::FILE* f) const {
  std::fclose(f);
}

SourceFile::SourceFile(const std::filesystem::path& path) : name_(path.string()) {
  file_.reset(std::fopen(path.c_str(), "rb"));
  if (!file_) fail(std::string("cannot open: ") + std::strerror(errno));
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) fail("is a directory");  // fopen accepts one
  size_ = std::filesystem::file_size(path, error);
  if (error) fail("cannot read size: " + error.message());
  readLayout();
}

SourceFile::SourceFile(int fd, std::string name) : name_(std::move(name)) {
  struct stat status {};
  if (::fstat(fd, &status) != 0)
    fail(std::string("cannot read descriptor ") + std::to_string(fd) + ": " + std::strerror(errno));
  if (!S_ISREG(status.st_mode))
    fail("descriptor " + std::to_string(fd) + " is not a regular file (a cluster file is read at offsets)");
  const int own = ::fcntl(fd, F_DUPFD_CLOEXEC, 0);
  if (own < 0) fail(std::string("cannot duplicate descriptor: ") + std::strerror(errno));
  file_.reset(::fdopen(own, "rb"));
  if (!file_) {
    ::close(own);
    fail(std::string("cannot open descriptor: ") + std::strerror(errno));
  }
  size_ = static_cast<uint64_t>(status.st_size);
  readLayout();
}

SourceFile::~SourceFile() = default;

void SourceFile::fail(const std::string& reason) const {
  throw Error(ErrorCategory::Input, name_ + ": " + reason);
}

std::string SourceFile::readAt(uint64_t offset, uint64_t bytes) const {
  std::string out;
  readAt(offset, bytes, out);
  return out;
}

void SourceFile::readAt(uint64_t offset, uint64_t bytes, std::string& out) const {
  if (offset + bytes > size_) fail("truncated at byte " + std::to_string(size_));
  out.resize(bytes);
  // pread: no shared file position, so that a reader's threads read frames side by side.
  const int fd = ::fileno(file_.get());
  for (uint64_t done = 0; done < bytes;) {
    const ssize_t got = ::pread(fd, out.data() + done, bytes - done, static_cast<off_t>(offset + done));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0)
      fail("read error at byte " + std::to_string(offset + done) + ": " +
           std::strerror(got < 0 ? errno : EIO));
    done += static_cast<uint64_t>(got);
  }
}

void SourceFile::readLayout() {
  const std::string head = readAt(0, std::min<uint64_t>(size_, kHeaderBytes));
  const auto* p = reinterpret_cast<const uint8_t*>(head.data());
  const size_t magicBytes = std::min<size_t>(head.size(), sizeof kMagic);
  if (std::memcmp(p, kMagic, magicBytes) != 0 || head.empty())
    fail("not a facetree cluster file (bad magic)");
  if (head.size() < 12) fail("truncated at byte " + std::to_string(size_));
  const uint32_t version = get<uint32_t>(p + 8);
  if (version != 1 && version != kFchVersion) fail("unsupported version " + std::to_string(version));
  if (head.size() < kHeaderBytes) fail("truncated at byte " + std::to_string(size_));
  if (get<uint32_t>(p + 12) != kHeaderBytes) fail("bad header size " + std::to_string(get<uint32_t>(p + 12)));
  if (get<uint64_t>(p + kHeaderChecksumOffset) != xxh64(p, kHeaderChecksumOffset))
    fail("header checksum mismatch");

  FchLayout& l = layout_;
  FileHeader& h = l.header;
  h.version = version;
  l.headerBytes = kHeaderBytes;
  l.fileBytes = get<uint64_t>(p + 16);
  h.nodeCount = get<uint64_t>(p + 24);
  h.originalNodeCount = get<uint64_t>(p + 32);
  h.triangleCount = get<uint64_t>(p + 40);
  h.vertexCount = get<uint64_t>(p + 48);
  const uint32_t frameCount = get<uint32_t>(p + 56);
  l.nodesPerFrame = get<uint32_t>(p + 60);
  l.geometryPerFrame = get<uint32_t>(p + 64);
  h.branching = p[68];
  const uint8_t metric = p[69];
  l.originalIdBytes = p[70];
  h.k = get<double>(p + 72);
  h.flatThreshold = get<double>(p + 80);
  h.memoryCapBytes = get<uint64_t>(p + 88);
  for (int a = 0; a < 3; ++a)
    h.boundsMin[a] = get<float>(p + 96 + 4 * a), h.boundsMax[a] = get<float>(p + 108 + 4 * a);
  const uint64_t indexChecksum = get<uint64_t>(p + 120);
  l.zstdLevel = get<int32_t>(p + 128);
  for (int w = 0; w < 3; ++w) h.garlandWeights[w] = get<double>(p + 136 + 8 * w);
  if (version >= 2) {
    if (p[71] > static_cast<uint8_t>(BoxPrecision::Compact))
      fail("unknown box precision " + std::to_string(p[71]));
    h.boxes = static_cast<BoxPrecision>(p[71]);
    h.topClusters = get<uint32_t>(p + 132);
    for (int a = 0; a < 3; ++a)
      l.rootBox.center[a] = get<float>(p + 160 + 4 * a),
      l.rootBox.halfExtent[a] = get<float>(p + 172 + 4 * a);
    for (int a = 0; a < 3; ++a)
      if (!std::isfinite(l.rootBox.center[a]) || !(l.rootBox.halfExtent[a] >= 0) ||
          !std::isfinite(l.rootBox.halfExtent[a]))
        fail("bad root box");
  }

  if (l.nodesPerFrame < 1 || l.nodesPerFrame > kMaxNodesPerFrame)
    fail("bad nodes per frame " + std::to_string(l.nodesPerFrame));
  if (l.geometryPerFrame < 1 || l.geometryPerFrame > kMaxGeometryPerFrame)
    fail("bad geometry per frame " + std::to_string(l.geometryPerFrame));
  if (h.branching < 2 || h.branching > kMaxBranching)
    fail("bad branching factor " + std::to_string(h.branching));
  if (metric > static_cast<uint8_t>(Metric::Constant)) fail("unknown metric " + std::to_string(metric));
  h.metric = static_cast<Metric>(metric);
  if (l.originalIdBytes != 4 && l.originalIdBytes != 8)
    fail("bad original id width " + std::to_string(l.originalIdBytes));
  if (h.triangleCount > kMaxTriangles) fail("too many triangles " + std::to_string(h.triangleCount));
  if (h.nodeCount > h.originalNodeCount || h.originalNodeCount > std::max<uint64_t>(h.triangleCount, 1) - 1)
    fail("bad node counts " + std::to_string(h.nodeCount) + " of " + std::to_string(h.originalNodeCount) +
         " for " + std::to_string(h.triangleCount) + " triangles");
  if ((h.triangleCount >= 2) != (h.nodeCount >= 1))
    fail("no root node for " + std::to_string(h.triangleCount) + " triangles");
  if (h.vertexCount > 3 * h.triangleCount) fail("bad vertex count " + std::to_string(h.vertexCount));
  if (size_ < l.fileBytes)
    fail("truncated at byte " + std::to_string(size_) + " (header declares " + std::to_string(l.fileBytes) +
         " bytes)");
  if (size_ > l.fileBytes)
    fail(std::to_string(size_ - l.fileBytes) + " unexpected bytes after byte " + std::to_string(l.fileBytes));
  const uint64_t indexBytes = uint64_t{kIndexEntryBytes} * frameCount;
  if (kHeaderBytes + indexBytes > size_) fail("frame index beyond the end of the file");

  const std::string index = readAt(kHeaderBytes, indexBytes);
  if (xxh64(index.data(), index.size()) != indexChecksum) fail("frame index checksum mismatch");
  const auto* q = reinterpret_cast<const uint8_t*>(index.data());
  const uint64_t sectionCount[5] = {0, h.nodeCount, h.vertexCount, h.triangleCount, h.triangleCount};
  uint64_t offset = kHeaderBytes + indexBytes;
  uint32_t section = 1;
  uint64_t covered = 0;  // elements of `section` covered so far
  l.frames.resize(frameCount);
  for (uint32_t i = 0; i < frameCount; ++i, q += kIndexEntryBytes) {
    FchFrame& f = l.frames[i];
    const uint32_t s = get<uint32_t>(q);
    f.count = get<uint32_t>(q + 4);
    f.first = get<uint64_t>(q + 8);
    f.offset = get<uint64_t>(q + 16);
    f.compressedBytes = get<uint32_t>(q + 24);
    f.rawBytes = get<uint32_t>(q + 28);
    f.checksum = get<uint64_t>(q + 32);
    const std::string entry = "frame index entry " + std::to_string(i) + ": ";
    if (s < section || s > 4) fail(entry + "bad section " + std::to_string(s));
    for (; section < s; ++section, covered = 0)
      if (covered != sectionCount[section])
        fail(entry + std::string(kSectionWords[section]) + " frames are missing");
    f.section = static_cast<FchSection>(s);
    const uint32_t perFrame = s == 1 ? l.nodesPerFrame : l.geometryPerFrame;
    if (f.first != covered) fail(entry + "does not start where the previous frame ended");
    if (f.count == 0 || f.count > perFrame || f.count > sectionCount[s] - covered)
      fail(entry + "bad element count " + std::to_string(f.count));
    if (f.count < perFrame && f.first + f.count != sectionCount[s])
      fail(entry + "short frame before the last");
    covered += f.count;
    uint64_t minRaw = 0, maxRaw = 0;
    switch (s) {
      case 1:
        if (version == 1) {
          minRaw = uint64_t{kNodeFixedBytes} * f.count, maxRaw = minRaw + 4ull * h.branching * f.count;
        } else {  // up to b child references and b - 1 face counts a node
          minRaw = uint64_t{nodeFixedBytes(h.boxes)} * f.count;
          maxRaw = minRaw + 4ull * (2 * h.branching - 1) * f.count;
        }
        break;
      case 2:
        minRaw = maxRaw = 12ull * f.count;
        break;
      case 3:
        minRaw = maxRaw = 12ull * f.count;
        break;
      default:
        minRaw = maxRaw = uint64_t{l.originalIdBytes} * f.count;
        break;
    }
    if (f.rawBytes < minRaw || f.rawBytes > maxRaw)
      fail(entry + "bad decompressed size " + std::to_string(f.rawBytes));
    if (f.offset != offset) fail(entry + "frame does not follow the previous one");
    offset += f.compressedBytes;
    if (offset > l.fileBytes) fail(entry + "frame beyond the end of the file");
  }
  for (; section <= 4; ++section, covered = 0)
    if (covered != sectionCount[section]) fail(std::string(kSectionWords[section]) + " frames are missing");
  if (offset != l.fileBytes)
    fail("frames end at byte " + std::to_string(offset) + ", file at " + std::to_string(l.fileBytes));
}

std::string SourceFile::where(size_t i) const {
  const FchFrame& f = layout_.frames[i];
  const auto s = static_cast<uint32_t>(f.section);
  size_t ordinal = 0;
  for (size_t j = 0; j < i; ++j) ordinal += layout_.frames[j].section == f.section;
  return std::string(kSectionWords[s]) + " frame " + std::to_string(ordinal) + " (" + kElementWords[s] + " " +
         std::to_string(f.first) + "-" + std::to_string(f.first + f.count - 1) + ")";
}

std::string SourceFile::compressedFrame(size_t i) const {
  std::string bytes;
  compressedFrame(i, bytes);
  return bytes;
}

void SourceFile::compressedFrame(size_t i, std::string& bytes) const {
  const FchFrame& f = layout_.frames[i];
  readAt(f.offset, f.compressedBytes, bytes);
  if (xxh64(bytes.data(), bytes.size()) != f.checksum) fail(where(i) + ": checksum mismatch");
}

std::string SourceFile::rawFrame(size_t i) const {
  std::string raw, compressed;
  rawFrame(i, raw, compressed);
  return raw;
}

void SourceFile::rawFrame(size_t i, std::string& raw, std::string& compressed) const {
  const FchFrame& f = layout_.frames[i];
  compressedFrame(i, compressed);
  if (ZSTD_getFrameContentSize(compressed.data(), compressed.size()) != f.rawBytes)
    fail(where(i) + ": zstd frame size disagrees with the index");
  raw.resize(f.rawBytes);
  const size_t got = ZSTD_decompress(raw.data(), raw.size(), compressed.data(), compressed.size());
  if (ZSTD_isError(got)) fail(where(i) + ": corrupt zstd data (" + ZSTD_getErrorName(got) + ")");
  if (got != f.rawBytes) fail(where(i) + ": decompressed size disagrees with the index");
}

void SourceFile::decodeNodes(size_t i, const std::string& raw, std::vector<FchNode>& out) const {
  const FchFrame& f = layout_.frames[i];
  const FileHeader& h = layout_.header;
  const size_t n = f.count;
  Columns col(raw);
  col.next(n, 1);
  uint64_t children = 0;
  for (size_t j = 0; j < n; ++j) {
    const uint64_t c = col.at(j);
    if (c > h.branching)
      fail(where(i) + ": node " + std::to_string(f.first + j) + ": " + std::to_string(c) + " children");
    children += c;
  }
  if (raw.size() != kNodeFixedBytes * n + 4 * children)
    fail(where(i) + ": payload size disagrees with the child counts");
  const size_t base = out.size();
  out.resize(base + n);
  FchNode* nodes = out.data() + base;
  for (size_t j = 0; j < n; ++j) nodes[j].childCount = static_cast<uint8_t>(col.at(j));
  col.next(n, 1);
  for (size_t j = 0; j < n; ++j) {
    nodes[j].flags = static_cast<uint8_t>(col.at(j));
    if (nodes[j].flags & ~kStoredFlagMask)
      fail(where(i) + ": node " + std::to_string(f.first + j) + ": unknown flags");
  }
  col.next(n);
  for (size_t j = 0; j < n; ++j) nodes[j].first = static_cast<uint32_t>(col.at(j));
  col.next(n);
  for (size_t j = 0; j < n; ++j) {
    nodes[j].count = static_cast<uint32_t>(col.at(j));
    if (uint64_t{nodes[j].first} + nodes[j].count > h.triangleCount)
      fail(where(i) + ": node " + std::to_string(f.first + j) + ": face range beyond the triangles");
  }
  auto floats = [&](auto&& assign) {
    col.next(n);
    for (size_t j = 0; j < n; ++j) assign(nodes[j], col.f(j));
  };
  floats([](FchNode& d, float v) { d.cost = v; });
  floats([](FchNode& d, float v) { d.area = v; });
  floats([](FchNode& d, float v) { d.perimeter = v; });
  for (size_t j = 0; j < n; ++j)
    if (!std::isfinite(nodes[j].cost) || !std::isfinite(nodes[j].area) || !std::isfinite(nodes[j].perimeter))
      fail(where(i) + ": node " + std::to_string(f.first + j) + ": cost, area or perimeter not finite");
  for (int a = 0; a < 3; ++a) floats([a](FchNode& d, float v) { d.sumNormal[a] = v; });
  for (int a = 0; a < 3; ++a) floats([a](FchNode& d, float v) { d.box.center[a] = v; });
  for (int a = 0; a < 4; ++a) floats([a](FchNode& d, float v) { d.box.orientation[a] = v; });
  for (int a = 0; a < 3; ++a) floats([a](FchNode& d, float v) { d.box.halfExtent[a] = v; });
  for (int a = 0; a < 6; ++a) floats([a](FchNode& d, float v) { d.box.sideArea[a] = v; });
  col.next(children);
  size_t r = 0;
  for (size_t j = 0; j < n; ++j) {
    const uint64_t self = f.first + j;
    for (unsigned c = 0; c < nodes[j].childCount; ++c, ++r) {
      const uint32_t ref = static_cast<uint32_t>(col.at(r));
      uint64_t target;
      if (ref & kFaceChild) {
        target = uint64_t{nodes[j].first} + (ref & ~kFaceChild);
        if (target >= h.triangleCount)
          fail(where(i) + ": node " + std::to_string(self) + ": face child beyond the triangles");
        nodes[j].child[c] = kFaceChild | static_cast<uint32_t>(target);
      } else {
        target = self + ref;
        if (ref == 0 || target >= kFaceChild)
          fail(where(i) + ": node " + std::to_string(self) + ": bad child reference");
        nodes[j].child[c] = static_cast<uint32_t>(target);
        if (target >= h.nodeCount) nodes[j].flags |= kFchTruncated;
      }
    }
  }
  // Version 1 stores no child face counts: those of node children come from their own records,
  // once read (fillVersion1ChildFaces).
}

void SourceFile::decodeVertices(size_t i, const std::string& raw, std::vector<glm::vec3>& out) const {
  const size_t n = layout_.frames[i].count, base = out.size();
  out.resize(base + n);
  Columns col(raw);
  for (int a = 0; a < 3; ++a) {
    col.next(n);
    for (size_t j = 0; j < n; ++j) out[base + j][a] = col.f(j);
  }
}

void SourceFile::decodeTriangles(size_t i, const std::string& raw, std::vector<uint32_t>& out) const {
  const size_t n = 3 * size_t{layout_.frames[i].count}, base = out.size();
  out.resize(base + n);
  Columns col(raw);
  col.next(n);
  uint32_t previous = 0;
  for (size_t j = 0; j < n; ++j) {
    previous += static_cast<uint32_t>(unzigzag32(static_cast<uint32_t>(col.at(j))));
    if (previous >= layout_.header.vertexCount)
      fail(where(i) + ": vertex index " + std::to_string(previous) + " beyond the vertices");
    out[base + j] = previous;
  }
}

void SourceFile::decodeIds(size_t i, const std::string& raw, std::vector<uint64_t>& out) const {
  const size_t n = layout_.frames[i].count, base = out.size();
  out.resize(base + n);
  Columns col(raw);
  col.next(n, layout_.originalIdBytes);
  uint64_t previous = 0;
  for (size_t j = 0; j < n; ++j) {
    if (layout_.originalIdBytes == 4)
      previous = static_cast<uint32_t>(previous +
                                       static_cast<uint32_t>(unzigzag32(static_cast<uint32_t>(col.at(j)))));
    else
      previous += static_cast<uint64_t>(unzigzag(col.at(j)));
    out[base + j] = previous;
  }
}

}  // namespace facetree::fch
