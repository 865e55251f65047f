// A cluster file from pieces (facetree/io.h assembleClusterFile; format/piece.h has the piece file):
// frames are self-contained (docs/FORMAT.md), so pieces written by independent writers, on other
// machines, join into the file one writer would have written by copying their frames in order
// under a header and index made from their index entries.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <limits>

#include <xxhash.h>
#include <glm/common.hpp>

#include "format/fch_format.h"
#include "format/piece.h"

namespace facetree {
namespace fch {
namespace {

constexpr char kPieceMagic[8] = {'F', 'C', 'H', 'P', 'I', 'E', 'C', 'E'};
constexpr size_t kTail = 2 * sizeof(uint64_t) + sizeof kPieceMagic;  // size, XXH64, magic

}  // namespace

FchLayout startLayout(const StreamFileInfo& info, const WriteOptions& options) {
  FchLayout layout;
  FileHeader& h = layout.header;
  h = info.header;
  h.version = kFchVersion;
  h.originalNodeCount = std::max(h.originalNodeCount, h.nodeCount);
  layout.nodesPerFrame = options.nodesPerFrame;
  layout.geometryPerFrame = options.geometryPerFrame;
  layout.zstdLevel = options.zstdLevel;
  layout.originalIdBytes = info.maxOriginalFace > std::numeric_limits<uint32_t>::max() ? 8 : 4;
  h.boundsMin = glm::vec3(std::numeric_limits<float>::infinity());
  h.boundsMax = -h.boundsMin;
  return layout;
}

std::string encodePieceTrailer(const PieceTrailer& t) {
  std::string out;
  put(out, t.range);
  put(out, t.boundsMin);
  put(out, t.boundsMax);
  put(out, uint8_t{t.hasRoot});
  put(out, t.rootBox);
  put(out, uint64_t{t.frames.size()});
  for (const FchFrame& f : t.frames) put(out, f);
  const uint64_t size = out.size() + kTail;
  put(out, size);
  put(out, uint64_t{XXH64(out.data(), out.size(), 0)});
  out.append(kPieceMagic, sizeof kPieceMagic);
  return out;
}

}  // namespace fch

namespace {

// A piece file open for reading: its trailer, read and checked.
class PieceFile {
 public:
  explicit PieceFile(const std::filesystem::path& path) : path_(path) {
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) fail(std::string("cannot open: ") + std::strerror(errno));
    struct stat st {};
    if (::fstat(fd_, &st) != 0) fail(std::string("cannot stat: ") + std::strerror(errno));
    const auto size = static_cast<uint64_t>(st.st_size);
    if (size < fch::kTail) fail("not a cluster file piece (too short)");
    std::string tail(fch::kTail, '\0');
    read(size - fch::kTail, tail.data(), tail.size());
    uint64_t trailerBytes = 0;
    std::memcpy(&trailerBytes, tail.data(), sizeof trailerBytes);
    if (std::memcmp(tail.data() + 16, fch::kPieceMagic, sizeof fch::kPieceMagic) != 0 ||
        trailerBytes > size || trailerBytes < fch::kTail)
      fail("not a cluster file piece");
    std::string trailer(trailerBytes, '\0');
    read(size - trailerBytes, trailer.data(), trailer.size());
    uint64_t checksum = 0;
    std::memcpy(&checksum, trailer.data() + trailerBytes - fch::kTail + 8, sizeof checksum);
    if (XXH64(trailer.data(), trailerBytes - fch::kTail + 8, 0) != checksum)
      fail("trailer checksum mismatch");
    dataBytes_ = size - trailerBytes;
    const char* at = trailer.data();
    const char* end = trailer.data() + trailerBytes - fch::kTail + 8;
    const auto take = [&](auto& value) {
      if (static_cast<size_t>(end - at) < sizeof value) fail("trailer cut short");
      std::memcpy(&value, at, sizeof value);
      at += sizeof value;
    };
    uint8_t hasRoot = 0;
    uint64_t frames = 0;
    take(trailer_.range);
    take(trailer_.boundsMin);
    take(trailer_.boundsMax);
    take(hasRoot);
    take(trailer_.rootBox);
    take(frames);
    trailer_.hasRoot = hasRoot != 0;
    if (frames > static_cast<uint64_t>(end - at) / sizeof(FchFrame)) fail("trailer cut short");
    trailer_.frames.resize(frames);
    for (FchFrame& f : trailer_.frames) take(f);
    for (const FchFrame& f : trailer_.frames)
      if (f.offset > dataBytes_ || f.compressedBytes > dataBytes_ - f.offset)
        fail("a frame past the piece's end");
  }
  ~PieceFile() {
    if (fd_ >= 0) ::close(fd_);
  }
  PieceFile(const PieceFile&) = delete;
  PieceFile& operator=(const PieceFile&) = delete;

  const fch::PieceTrailer& trailer() const { return trailer_; }
  [[noreturn]] void fail(const std::string& why) const {
    throw Error(ErrorCategory::Input, path_.string() + ": " + why);
  }
  void read(uint64_t offset, char* out, size_t size) const {
    for (size_t done = 0; done < size;) {
      const ssize_t got = ::pread(fd_, out + done, size - done, static_cast<off_t>(offset + done));
      if (got < 0 && errno == EINTR) continue;
      if (got <= 0) fail(got == 0 ? "cut short" : std::string("read error: ") + std::strerror(errno));
      done += static_cast<size_t>(got);
    }
  }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  uint64_t dataBytes_ = 0;
  fch::PieceTrailer trailer_;
};

}  // namespace

ClusterFileAssembly beginClusterFile(const std::filesystem::path& partial, const StreamFileInfo& info,
                                     const WriteOptions& options,
                                     std::span<const std::filesystem::path> paths) {
  std::vector<std::unique_ptr<PieceFile>> pieces;
  for (const auto& path : paths) pieces.push_back(std::make_unique<PieceFile>(path));
  FchLayout layout = fch::startLayout(info, options);
  FileHeader& h = layout.header;
  const uint64_t declared[4] = {h.nodeCount, h.vertexCount, h.triangleCount, h.triangleCount};
  const FchSection sections[4] = {FchSection::Nodes, FchSection::Vertices, FchSection::Triangles,
                                  FchSection::OriginalFaces};
  const auto rangeOf = [](const PieceRange& r, int s) {
    return s == 0   ? std::pair(r.firstNode, r.endNode)
           : s == 1 ? std::pair(r.firstVertex, r.endVertex)
                    : std::pair(r.firstTriangle, r.endTriangle);
  };
  uint64_t frames = 0;
  for (const auto& p : pieces) {
    const fch::PieceTrailer& t = p->trailer();
    frames += t.frames.size();
    h.boundsMin = glm::min(h.boundsMin, t.boundsMin);
    h.boundsMax = glm::max(h.boundsMax, t.boundsMax);
    if (t.hasRoot) layout.rootBox = t.rootBox;
  }
  if (h.vertexCount == 0) h.boundsMin = h.boundsMax = glm::vec3(0.0f);
  ClusterFileAssembly assembly;
  uint64_t offset = fch::kHeaderBytes + uint64_t{fch::kIndexEntryBytes} * frames;
  for (int s = 0; s < 4; ++s) {
    std::vector<uint32_t> order;
    for (uint32_t i = 0; i < pieces.size(); ++i)
      if (const auto [first, end] = rangeOf(pieces[i]->trailer().range, s); end > first) order.push_back(i);
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
      return rangeOf(pieces[a]->trailer().range, s).first < rangeOf(pieces[b]->trailer().range, s).first;
    });
    uint64_t next = 0;
    for (const uint32_t i : order) {
      const PieceFile& p = *pieces[i];
      const auto [first, end] = rangeOf(p.trailer().range, s);
      if (first != next)
        p.fail(std::string(sectionName(sections[s])) + " " + std::to_string(first) + " ... where " +
               std::to_string(next) + " comes next: pieces that leave a gap or overlap");
      for (const FchFrame& f : p.trailer().frames) {
        if (f.section != sections[s]) continue;
        if (f.first != next) p.fail(std::string(sectionName(sections[s])) + " frames out of order");
        FchFrame placed = f;
        placed.offset = offset;
        layout.frames.push_back(placed);
        // Consecutive frames of one piece are consecutive in it: one copy.
        PieceCopy* last = assembly.copies.empty() ? nullptr : &assembly.copies.back();
        if (last && last->piece == i && last->from + last->bytes == f.offset &&
            last->to + last->bytes == offset)
          last->bytes += f.compressedBytes;
        else
          assembly.copies.push_back({i, f.offset, offset, f.compressedBytes});
        offset += f.compressedBytes;
        next += f.count;
      }
      if (next != end) p.fail(std::string(sectionName(sections[s])) + " frames short of the piece's range");
    }
    if (next != declared[s])
      throw Error(ErrorCategory::Input, partial.string() + ": the pieces hold " + std::to_string(next) +
                                            " of " + std::to_string(declared[s]) + " " +
                                            sectionName(sections[s]));
  }
  layout.fileBytes = assembly.fileBytes = offset;
  const std::string front = fch::encodeHeaderAndIndex(layout);
  const int fd = ::open(partial.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  const auto fail = [&](const char* what) {
    const int error = errno;
    if (fd >= 0) ::close(fd);
    throw Error(ErrorCategory::Output, partial.string() + ": " + what + ": " + std::strerror(error));
  };
  if (fd < 0) fail("cannot create");
  if (::ftruncate(fd, static_cast<off_t>(offset)) != 0) fail("cannot size");
  for (size_t done = 0; done < front.size();) {
    const ssize_t put = ::pwrite(fd, front.data() + done, front.size() - done, static_cast<off_t>(done));
    if (put < 0 && errno == EINTR) continue;
    if (put <= 0) fail("cannot write");
    done += static_cast<size_t>(put);
  }
  if (::fdatasync(fd) != 0) fail("cannot sync");
  ::close(fd);
  return assembly;
}

void placePieces(const std::filesystem::path& partial, std::span<const std::filesystem::path> paths,
                 std::span<const PieceCopy> copies) {
  const int fd = ::open(partial.c_str(), O_WRONLY | O_CLOEXEC);
  const auto fail = [&](const char* what) {
    const int error = errno;
    if (fd >= 0) ::close(fd);
    throw Error(ErrorCategory::Output, partial.string() + ": " + what + ": " + std::strerror(error));
  };
  if (fd < 0) fail("cannot open");
  std::vector<char> buffer(size_t{1} << 20);
  std::unique_ptr<PieceFile> piece;
  uint32_t open = UINT32_MAX;
  for (const PieceCopy& c : copies) {
    if (c.piece >= paths.size())
      throw std::invalid_argument("placePieces: no piece " + std::to_string(c.piece));
    if (c.piece != open) piece = std::make_unique<PieceFile>(paths[c.piece]), open = c.piece;
    for (uint64_t done = 0; done < c.bytes;) {
      const size_t want = static_cast<size_t>(std::min<uint64_t>(buffer.size(), c.bytes - done));
      piece->read(c.from + done, buffer.data(), want);
      for (size_t put = 0; put < want;) {
        const ssize_t n =
            ::pwrite(fd, buffer.data() + put, want - put, static_cast<off_t>(c.to + done + put));
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) fail("cannot write");
        put += static_cast<size_t>(n);
      }
      done += want;
    }
  }
  if (::fdatasync(fd) != 0) fail("cannot sync");
  ::close(fd);
}

void commitClusterFile(const std::filesystem::path& partial, const std::filesystem::path& out) {
  std::error_code error;
  std::filesystem::rename(partial, out, error);
  if (error)
    throw Error(ErrorCategory::Output,
                out.string() + ": cannot rename " + partial.string() + ": " + error.message());
}

uint64_t assembleClusterFile(const std::filesystem::path& out, const StreamFileInfo& info,
                             const WriteOptions& options, std::span<const std::filesystem::path> pieces) {
  const std::filesystem::path partial = temporaryOutputPath(out);
  try {
    const ClusterFileAssembly assembly = beginClusterFile(partial, info, options, pieces);
    placePieces(partial, pieces, assembly.copies);
    commitClusterFile(partial, out);
    return assembly.fileBytes;
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove(partial, ignored);
    throw;
  }
}

}  // namespace facetree
