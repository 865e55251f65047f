// Compressed block files for the out-of-core spills (facetree/storage.h). Each block is one zstd frame
// with its content size and checksum, or, below kStoredBelow bytes or at kSpillStored, the bytes as they
// are between a tag and a 32-bit XXH3 of them, written and read in place (pwritev, preadv): a block
// damaged on disk is an error, never garbage records.
#include "facetree/storage.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>
#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>

namespace facetree {

void SpillCodec::CCtxDeleter::operator()(ZSTD_CCtx_s* context) const {
  ZSTD_freeCCtx(context);
}
void SpillCodec::DCtxDeleter::operator()(ZSTD_DCtx_s* context) const {
  ZSTD_freeDCtx(context);
}

SpillCodec::SpillCodec(int level)
    : compressor_(ZSTD_createCCtx()), decompressor_(ZSTD_createDCtx()), stored_(level == kSpillStored) {
  if (!compressor_ || !decompressor_) throw std::bad_alloc();
  if (!stored_) ZSTD_CCtx_setParameter(compressor_.get(), ZSTD_c_compressionLevel, level);
  // 4 bytes per block; catches a temp file changed under us where the frame would still decode.
  ZSTD_CCtx_setParameter(compressor_.get(), ZSTD_c_checksumFlag, 1);
}

SpillCodec::~SpillCodec() = default;
SpillCodec::SpillCodec(SpillCodec&&) noexcept = default;
SpillCodec& SpillCodec::operator=(SpillCodec&&) noexcept = default;

namespace {

// Byte k of record i goes to k * records + i; the bytes past the last whole record stay last.
void shuffleRecords(std::span<const std::byte> in, std::byte* out, size_t recordBytes) {
  const size_t records = in.size() / recordBytes;
  for (size_t i = 0; i < records; ++i)
    for (size_t k = 0; k < recordBytes; ++k) out[k * records + i] = in[i * recordBytes + k];
  std::copy(in.begin() + records * recordBytes, in.end(), out + records * recordBytes);
}

void unshuffleRecords(std::span<const std::byte> in, std::byte* out, size_t recordBytes) {
  const size_t records = in.size() / recordBytes;
  for (size_t i = 0; i < records; ++i)
    for (size_t k = 0; k < recordBytes; ++k) out[i * recordBytes + k] = in[k * records + i];
  std::copy(in.begin() + records * recordBytes, in.end(), out + records * recordBytes);
}

// Blocks under this many bytes are stored, not compressed: zstd's frame and context setup cost more
// than the few bytes it would save (the top runs of a leaf's nodes are one to a few nodes).
constexpr size_t kStoredBelow = 1024;
// The tag of a stored block (a zstd frame starts with 28 B5 2F FD), then the bytes, then their checksum.
constexpr std::array<std::byte, 4> kStoredTag = {std::byte{'F'}, std::byte{'T'}, std::byte{'S'},
                                                 std::byte{'B'}};
constexpr size_t kStoredOverhead = kStoredTag.size() + sizeof(uint32_t);

uint32_t storedChecksum(std::span<const std::byte> raw) {
  return static_cast<uint32_t>(XXH3_64bits(raw.data(), raw.size()));
}

// Writes (kWrite) or reads `parts` at `offset` in full; false with errno set on failure (0: the
// file ended, or took no bytes).
template <bool kWrite>
bool transferParts(int fd, std::span<iovec> parts, uint64_t offset) {
  size_t first = 0;
  while (first < parts.size()) {
    const int count = static_cast<int>(parts.size() - first);
    const ssize_t got = kWrite ? ::pwritev(fd, &parts[first], count, static_cast<off_t>(offset))
                               : ::preadv(fd, &parts[first], count, static_cast<off_t>(offset));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) {
      if (got == 0) errno = 0;
      return false;
    }
    offset += static_cast<uint64_t>(got);
    size_t left = static_cast<size_t>(got);
    for (; first < parts.size() && left >= parts[first].iov_len; ++first) left -= parts[first].iov_len;
    if (left > 0) {  // a part taken in part: the rest of it next
      parts[first].iov_base = static_cast<char*>(parts[first].iov_base) + left;
      parts[first].iov_len -= left;
    }
  }
  return true;
}

}  // namespace

std::span<const std::byte> SpillCodec::compress(std::span<const std::byte> raw, size_t recordBytes) {
  if (recordBytes > 1) {
    shuffled_.resize(raw.size());
    shuffleRecords(raw, shuffled_.data(), recordBytes);
    raw = shuffled_;
  }
  scratch_.resize(ZSTD_compressBound(raw.size()));
  const size_t got =
      ZSTD_compress2(compressor_.get(), scratch_.data(), scratch_.size(), raw.data(), raw.size());
  // Only a bad parameter or allocation failure can fail with a large enough destination.
  if (ZSTD_isError(got))
    throw std::runtime_error(std::string("zstd compression failed: ") + ZSTD_getErrorName(got));
  return {scratch_.data(), got};
}

bool SpillCodec::stores(size_t rawBytes) const {
  return stored_ || rawBytes < kStoredBelow;
}

std::span<std::byte> SpillCodec::compressedScratch(size_t bytes) {
  if (scratch_.size() < bytes) scratch_.resize(bytes);
  return {scratch_.data(), bytes};
}

bool SpillCodec::decompress(std::span<const std::byte> compressed, std::span<std::byte> raw,
                            const char*& reason, size_t recordBytes) {
  if (recordBytes > 1) {
    shuffled_.resize(raw.size());
    if (!decompress(compressed, shuffled_, reason)) return false;
    unshuffleRecords(shuffled_, raw.data(), recordBytes);
    return true;
  }
  if (ZSTD_getFrameContentSize(compressed.data(), compressed.size()) != raw.size()) {
    reason = "frame size disagrees with the block";
    return false;
  }
  const size_t got =
      ZSTD_decompressDCtx(decompressor_.get(), raw.data(), raw.size(), compressed.data(), compressed.size());
  if (ZSTD_isError(got)) {
    reason = ZSTD_getErrorName(got);
    return false;
  }
  if (got != raw.size()) {
    reason = "decompressed size disagrees with the block";
    return false;
  }
  return true;
}

namespace {

// The unit discard() gives back: blocks are small (a few KiB compressed), so they share pages.
constexpr uint64_t kPageBytes = 4096;

}  // namespace

SpillFile::SpillFile(TempSpace& space, std::string_view stem, bool discardable, size_t recordBytes)
    : space_(space), path_(space.newFile(stem)), discardable_(discardable), recordBytes_(recordBytes) {
  fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd_ < 0) throwTempSpaceError(path_, "cannot create", errno);
  // Anonymous from here on: the kernel frees the blocks when the descriptor closes, on any exit.
  if (::unlink(path_.c_str()) != 0) {
    const int error = errno;
    ::close(fd_);
    throwTempSpaceError(path_, "cannot unlink", error);
  }
}

SpillFile::SpillFile(TempSpace& space, Named name, size_t recordBytes)
    : space_(space), path_(std::move(name.path)), recordBytes_(recordBytes), sync_(name.sync) {
  if (name.segment >= kMaxSegments) throw std::invalid_argument("SpillFile: segment past 65535");
  base_ = uint64_t{name.segment} << kSegmentShift;
  partial_ = path_;
  partial_ += ".partial";
  // A partial file of an earlier attempt is replaced: the task starts over.
  fd_ = ::open(partial_.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) throwTempSpaceError(partial_, "cannot create", errno);
}

SpillFile::SpillFile(TempSpace& space, std::vector<Segment> segments, size_t recordBytes)
    : space_(space), path_(segments.front().path), opened_(std::move(segments)), recordBytes_(recordBytes) {
  for (const Segment& segment : opened_) openedBytes_ += segment.bytes;
  held_ = openedBytes_;  // open() reserved them
  base_ = uint64_t{opened_.size()} << kSegmentShift;
}

std::unique_ptr<SpillFile> SpillFile::open(TempSpace& space, std::span<const std::filesystem::path> paths,
                                           size_t recordBytes) {
  if (paths.empty() || paths.size() > kMaxSegments)
    throw std::invalid_argument("SpillFile::open: 1 to 65536 segments");
  std::vector<Segment> segments;
  const auto closeAll = [&] {
    for (const Segment& segment : segments) ::close(segment.fd);
  };
  for (const std::filesystem::path& path : paths) {
    Segment segment{path, ::open(path.c_str(), O_RDONLY | O_CLOEXEC), 0};
    struct stat info {};
    if (segment.fd < 0 || ::fstat(segment.fd, &info) != 0) {
      const int error = errno;
      if (segment.fd >= 0) ::close(segment.fd);
      closeAll();
      throw Error(ErrorCategory::Input, path.string() + ": cannot open: " + std::strerror(error));
    }
    segment.bytes = static_cast<uint64_t>(info.st_size);
    segments.push_back(std::move(segment));
  }
  // Its files count against the job's temporary bytes while it reads them (throws past the limit).
  uint64_t total = 0;
  for (const Segment& segment : segments) total += segment.bytes;
  try {
    space.reserveOpened(total);
  } catch (...) {
    closeAll();
    throw;
  }
  try {
    return std::unique_ptr<SpillFile>(new SpillFile(space, std::move(segments), recordBytes));
  } catch (...) {  // allocation: the descriptors are still the vector's
    space.releaseOpened(total);
    closeAll();
    throw;
  }
}

void SpillFile::commit() {
  if (partial_.empty()) throw std::logic_error("SpillFile::commit: not a named file being written");
  std::lock_guard lock(writeMutex_);
  const auto fail = [&](int error) {
    throw Error(ErrorCategory::Output, path_.string() + ": cannot commit: " + std::strerror(error));
  };
  if (sync_ && ::fsync(fd_) != 0) fail(errno);
  if (::rename(partial_.c_str(), path_.c_str()) != 0) fail(errno);
  partial_.clear();
  readOnly_ = true;  // its handles are handed on: the blocks are final
}

SpillFile::~SpillFile() {
  if (fd_ >= 0) ::close(fd_);
  for (const Segment& segment : opened_) ::close(segment.fd);
  if (!partial_.empty()) ::unlink(partial_.c_str());
  const uint64_t opened = std::min(held_, openedBytes_);  // reserveOpened's, less pages given back
  space_.releaseOpened(opened);
  space_.release(held_ - opened);
}

SpillBlock SpillFile::append(std::span<const std::byte> raw, SpillCodec& codec) {
  if (readOnly_) throw std::logic_error("SpillFile::append: " + path_.string() + " is committed");
  if (raw.size() > kMaxSpillBlockBytes) throw std::invalid_argument("spill block larger than 256 MiB");
  // Compress outside the lock: each thread has its own codec. A stored block goes out as its tag,
  // the bytes in place and their checksum.
  const bool stored = codec.stores(raw.size());
  std::array<std::byte, kStoredTag.size()> tag = kStoredTag;
  uint32_t sum = 0;
  std::span<const std::byte> compressed;
  std::array<iovec, 3> parts{};
  if (stored) {
    sum = storedChecksum(raw);
    parts = {iovec{tag.data(), tag.size()}, iovec{const_cast<std::byte*>(raw.data()), raw.size()},
             iovec{&sum, sizeof sum}};
  } else {
    compressed = codec.compress(raw, recordBytes_);
    parts[0] = {const_cast<std::byte*>(compressed.data()), compressed.size()};
  }
  const uint64_t footprint = stored ? raw.size() + kStoredOverhead : compressed.size();
  std::lock_guard lock(writeMutex_);
  if (fd_ < 0) {  // opened files: the reader's own blocks go to a temporary file of its own
    const std::filesystem::path name = space_.newFile("appended");
    fd_ = ::open(name.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd_ < 0) throwTempSpaceError(name, "cannot create", errno);
    ::unlink(name.c_str());
  }
  const uint64_t offset = bytes_.load(std::memory_order_relaxed);
  space_.reserve(footprint);
  if (!transferParts<true>(fd_, std::span(parts).first(stored ? 3 : 1), offset)) {
    // ENOSPC, EDQUOT, EFBIG (RLIMIT_FSIZE with SIGXFSZ ignored), EIO...; a zero-byte write counts as full.
    const int error = errno != 0 ? errno : ENOSPC;
    space_.release(footprint);
    // Drop the partial block so the file stays exactly its blocks (best effort: it is deleted anyway).
    [[maybe_unused]] const int ignored = ::ftruncate(fd_, static_cast<off_t>(offset));
    throwTempSpaceError(path_, "write failed", error);
  }
  held_ += footprint;
  if (discardable_ && footprint > 0) {
    const uint64_t last = (offset + footprint - 1) / kPageBytes;
    if (live_.size() <= last) live_.resize(last + 1, 0);
    for (uint64_t page = offset / kPageBytes; page <= last; ++page) ++live_[page];
  }
  bytes_.store(offset + footprint, std::memory_order_release);
  return {base_ + offset, static_cast<uint32_t>(footprint), static_cast<uint32_t>(raw.size())};
}

void SpillFile::ownOpened() {
  openedLive_.clear();
  for (Segment& segment : opened_) {
    // Punching holes needs a descriptor open for writing; without one the pages stay, accounted.
    const int fd = ::open(segment.path.c_str(), O_RDWR | O_CLOEXEC);
    if (fd >= 0) {
      ::close(segment.fd);
      segment.fd = fd;
    }
    openedLive_.emplace_back((segment.bytes + kPageBytes - 1) / kPageBytes, 0);
  }
}

std::pair<uint64_t, uint64_t> SpillFile::openedPlace(const SpillBlock& block) const {
  const uint64_t segment = block.offset >> kSegmentShift;
  const uint64_t offset = block.offset & ((uint64_t{1} << kSegmentShift) - 1);
  if (segment >= opened_.size() || offset + block.compressedBytes > opened_[segment].bytes)
    corrupt(block, "no such segment");
  return {segment, offset};
}

void SpillFile::countBlock(const SpillBlock& block) {
  if (openedLive_.empty() || block.compressedBytes == 0) return;
  const auto [segment, offset] = openedPlace(block);
  std::vector<uint16_t>& live = openedLive_[segment];
  for (uint64_t page = offset / kPageBytes; page <= (offset + block.compressedBytes - 1) / kPageBytes; ++page)
    if (++live[page] == 0) throw std::length_error("SpillFile: more than 65535 blocks on a page");
}

void SpillFile::releasePages(int fd, std::vector<uint16_t>& live, uint64_t offset, uint64_t bytes,
                             uint64_t keepFrom, uint64_t fileBytes) {
  // The pages freed, in runs, each punched once.
  uint64_t runStart = 0, runPages = 0;
  const auto punch = [&] {
    if (runPages == 0) return;
    const uint64_t released = std::min(runPages * kPageBytes, fileBytes - runStart * kPageBytes);
    if (::fallocate(fd, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, static_cast<off_t>(runStart * kPageBytes),
                    static_cast<off_t>(runPages * kPageBytes)) == 0) {
      held_ -= released;
      space_.release(released);
    }  // else (EOPNOTSUPP and the like) the pages keep their space, still accounted
    runPages = 0;
  };
  for (uint64_t page = offset / kPageBytes; page <= (offset + bytes - 1) / kPageBytes; ++page) {
    if (live[page] == 0 || --live[page] != 0 || page >= keepFrom) {
      punch();
      continue;
    }
    if (runPages == 0) runStart = page;
    ++runPages;
  }
  punch();
}

void SpillFile::discard(const SpillBlock& block) {
  if (!opened_.empty()) {
    // The task outputs of a run of stages stay for a rerun, unless this run owns them: a page of
    // one of them is the file's bytes on it (the last one may be short).
    if (openedLive_.empty() || block.compressedBytes == 0) return;
    const auto [segment, offset] = openedPlace(block);
    std::lock_guard lock(writeMutex_);
    releasePages(opened_[segment].fd, openedLive_[segment], offset, block.compressedBytes, UINT64_MAX,
                 opened_[segment].bytes);
    return;
  }
  if (!discardable_) throw std::logic_error("SpillFile::discard: the file was not made discardable");
  if (block.compressedBytes == 0) return;
  std::lock_guard lock(writeMutex_);
  if (block.offset + block.compressedBytes > bytes_.load(std::memory_order_relaxed))
    throw std::invalid_argument("SpillFile::discard: not a block of this file");
  // Every page before the one holding the end of the file is covered by blocks end to end, so a
  // page none of whose blocks is live holds exactly kPageBytes of accounted bytes; the page at the
  // end stays until the file is complete past it.
  releasePages(fd_, live_, block.offset, block.compressedBytes,
               bytes_.load(std::memory_order_relaxed) / kPageBytes, UINT64_MAX);
}

void SpillFile::discardBefore(uint64_t end) {
  if (!opened_.empty()) return;
  if (!discardable_) throw std::logic_error("SpillFile::discardBefore: the file was not made discardable");
  std::lock_guard lock(writeMutex_);
  const uint64_t pages = std::min(end, bytes_.load(std::memory_order_relaxed)) / kPageBytes;
  // The live pages below `end` in runs, each punched once (those given back before stay so); the
  // pages below an earlier call's end are all given back already, so the scan starts there.
  uint64_t page = discardedBelow_;
  discardedBelow_ = std::max(discardedBelow_, pages);
  while (page < pages) {
    if (live_[page] == 0) {
      ++page;
      continue;
    }
    const uint64_t start = page;
    while (page < pages && live_[page] != 0) live_[page++] = 0;
    const uint64_t count = page - start;
    if (::fallocate(fd_, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, static_cast<off_t>(start * kPageBytes),
                    static_cast<off_t>(count * kPageBytes)) == 0) {
      held_ -= count * kPageBytes;
      space_.release(count * kPageBytes);
    }  // else the pages keep their space, still accounted
  }
}

void SpillFile::read(const SpillBlock& block, std::vector<std::byte>& raw, SpillCodec& codec) const {
  raw.resize(block.rawBytes);
  read(block, std::span<std::byte>(raw), codec);
}

void SpillFile::read(const SpillBlock& block, std::span<std::byte> raw, SpillCodec& codec) const {
  if (raw.size() != block.rawBytes)
    throw std::invalid_argument("SpillFile::read: buffer size is not the block's");
  // The segment the handle names: this file's own, or one of the opened ones.
  const uint64_t segment = block.offset >> kSegmentShift;
  const uint64_t local = block.offset & ((uint64_t{1} << kSegmentShift) - 1);
  int fd = fd_;
  uint64_t size = 0;
  const std::filesystem::path* file = &path_;
  if (segment < opened_.size()) {
    fd = opened_[segment].fd;
    size = opened_[segment].bytes;
    file = &opened_[segment].path;
  } else if (segment != (base_ >> kSegmentShift) || fd < 0) {
    corrupt(block, opened_.empty() ? "not a block of this file" : "no such segment");
  } else {
    size = bytes_.load(std::memory_order_acquire);
  }
  if (local + block.compressedBytes > size) corrupt(block, "block lies past the end of the file", file);
  const auto failed = [&] {
    if (errno == 0) corrupt(block, "unexpected end of file", file);
    throwTempSpaceError(*file, "read failed", errno);
  };
  if (block.compressedBytes == uint64_t{block.rawBytes} + kStoredOverhead) {  // stored, or a frame that size
    std::array<std::byte, kStoredTag.size()> tag{};
    uint32_t sum = 0;
    std::array<iovec, 3> parts = {iovec{tag.data(), tag.size()}, iovec{raw.data(), raw.size()},
                                  iovec{&sum, sizeof sum}};
    if (!transferParts<false>(fd, parts, local)) failed();
    if (tag == kStoredTag) {
      if (sum != storedChecksum(raw)) corrupt(block, "stored block checksum mismatch", file);
      return;
    }
  }
  const std::span<std::byte> compressed = codec.compressedScratch(block.compressedBytes);
  std::array<iovec, 1> whole = {iovec{compressed.data(), compressed.size()}};
  if (!transferParts<false>(fd, whole, local)) failed();
  const char* reason = nullptr;
  if (!codec.decompress(compressed, raw, reason, recordBytes_)) corrupt(block, reason, file);
}

void SpillFile::corrupt(const SpillBlock& block, std::string_view reason,
                        const std::filesystem::path* file) const {
  const uint64_t local = block.offset & ((uint64_t{1} << kSegmentShift) - 1);
  throw Error(ErrorCategory::Resource, (file ? *file : path_).string() + ": corrupt block at byte " +
                                           std::to_string(local) + ": " + std::string(reason));
}

}  // namespace facetree
