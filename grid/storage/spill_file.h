// Append-only temporary files of independently zstd-compressed blocks, the storage under every spill of
// the out-of-core build (face cells, ghost edges, sort runs). Internal to grid/.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include "storage/temp_space.h"

struct ZSTD_CCtx_s;
struct ZSTD_DCtx_s;

namespace facetree {

// Largest raw block: keeps rawBytes and the compressed bound in 32 bits.
inline constexpr size_t kMaxSpillBlockBytes = size_t{256} << 20;

// zstd level of every spill. Negative levels are zstd's fast mode (the match search skips ahead, literals
// stay raw): spills are written once and read once, so compression time counts more than a few percent
// of temporary bytes; -3 is where faster levels stop paying (docs/benchmarks.md has the trade-off).
inline constexpr int kSpillLevel = -3;

// Per-thread zstd state for spills (a CCtx and a DCtx, created once, reused): pass one per thread.
// Holds one compressed block of scratch, so its memory is the zstd contexts (~370 KiB at kSpillLevel
// for 64 KiB blocks) plus ZSTD_compressBound of the largest block it has seen.
class SpillCodec {
 public:
  explicit SpillCodec(int level = kSpillLevel);
  ~SpillCodec();
  SpillCodec(SpillCodec&&) noexcept;
  SpillCodec& operator=(SpillCodec&&) noexcept;

  // One zstd frame with content size and checksum; the view lives until the next call on this codec.
  // With `recordBytes` > 1 the bytes are first grouped by their place in records of that size
  // (byte 0 of every record, then byte 1, ...; a partial record at the end stays as it is): the
  // bytes of floats and small integers that vary alike end up together, which zstd finds (the
  // shuffle filter of Blosc, Alted 2010).
  std::span<const std::byte> compress(std::span<const std::byte> raw, size_t recordBytes = 1);
  // Scratch for a compressed block of `bytes`, as read() fills it.
  std::span<std::byte> compressedScratch(size_t bytes);
  // Decompresses `compressed` into exactly raw.size() bytes; false (with `reason`) if it is not a whole
  // valid frame of that size.
  // `recordBytes` as the block was compressed with.
  bool decompress(std::span<const std::byte> compressed, std::span<std::byte> raw, const char*& reason,
                  size_t recordBytes = 1);

 private:
  struct CCtxDeleter {
    void operator()(ZSTD_CCtx_s* context) const;
  };
  struct DCtxDeleter {
    void operator()(ZSTD_DCtx_s* context) const;
  };
  std::unique_ptr<ZSTD_CCtx_s, CCtxDeleter> compressor_;
  std::unique_ptr<ZSTD_DCtx_s, DCtxDeleter> decompressor_;
  std::vector<std::byte> scratch_;
  std::vector<std::byte> shuffled_;  // a block's bytes by record place (recordBytes > 1)
};

// Where a block lives in its SpillFile: the handle append() returns and read() takes.
struct SpillBlock {
  uint64_t offset = 0;
  uint32_t compressedBytes = 0;
  uint32_t rawBytes = 0;
};

// An append-only temporary file of independently zstd-compressed blocks, read back by handle in any order.
// append() and read() may be called from several threads at once (append serialises the write with a mutex,
// read uses pread). The file is deleted and its bytes released from the TempSpace by the destructor.
//
// A temporary file's name is unlinked right after the file is created, so the data goes away with the
// descriptor even when the process is killed; path() is the name it had, for messages. A named file
// (SpillFile::Named) keeps its name once committed, for the stages run as tasks.
class SpillFile {
 public:
  // `discardable`: the file counts the blocks on each of its pages (2 bytes a page, 4 KiB), so that
  // discard() can give back every page whose blocks are all discarded.
  // `recordBytes`: the size of the records its blocks hold, for SpillCodec's shuffle (1: none).
  SpillFile(TempSpace& space, std::string_view stem, bool discardable = false, size_t recordBytes = 1);
  // A named file that outlives the process, for a task of the stages that hands its blocks to a
  // later task (docs/out_of_core.md): written as `path`.partial and accounted in `space` like any
  // spill, renamed to `path` by commit(); the destructor deletes a file never committed, so a task
  // that fails or is killed before commit leaves no file under the final name.
  // Its handles carry `segment` in their offsets' top bits (kSegmentShift), so that the files of
  // several tasks, opened together, read by the handles each task handed on as they are.
  // `sync`: commit puts its bytes on the disk (fsync) first, for a later task on another machine
  // or after a crash; a private work directory that lives and dies with one process does without.
  struct Named {
    std::filesystem::path path;
    uint32_t segment = 0;
    bool sync = true;
  };
  static constexpr unsigned kSegmentShift = 48;
  static constexpr uint32_t kMaxSegments = 1u << 16;
  SpillFile(TempSpace& space, Named name, size_t recordBytes = 1);
  // Committed named files read back together: segments[i] is the file written as segment i. They
  // are read-only: discard keeps their blocks (a rerun of the reading task needs them), and blocks
  // appended go to a temporary file of the reader, one segment past them. Throws Error (Input)
  // "PATH: cannot open: REASON".
  static std::unique_ptr<SpillFile> open(TempSpace& space, std::span<const std::filesystem::path> segments,
                                         size_t recordBytes = 1);
  static std::unique_ptr<SpillFile> open(TempSpace& space, const std::filesystem::path& path,
                                         size_t recordBytes = 1) {
    return open(space, std::span(&path, 1), recordBytes);
  }
  ~SpillFile();
  SpillFile(const SpillFile&) = delete;
  SpillFile& operator=(const SpillFile&) = delete;

  // raw.size() <= kMaxSpillBlockBytes. Throws Error (Resource) "PATH: write failed: <strerror>" when the
  // disk refuses the bytes (or past --max-tmp); the file then holds exactly the blocks appended before.
  SpillBlock append(std::span<const std::byte> raw, SpillCodec& codec);
  // Resizes `raw` to block.rawBytes and fills it.
  void read(const SpillBlock& block, std::vector<std::byte>& raw, SpillCodec& codec) const;
  // Fills `raw`, whose size must be block.rawBytes (decompresses in place, e.g. into a larger array).
  void read(const SpillBlock& block, std::span<std::byte> raw, SpillCodec& codec) const;

  // Marks a block of a discardable file read for the last time: the pages that hold only discarded
  // blocks are punched out and their bytes released from the TempSpace (the page at the end of the
  // file stays until the file is complete past it). Reading the block again fails its checksum.
  // Thread-safe, also against append() and read() of other blocks. Where the file system cannot
  // punch holes the pages keep their space, still accounted.
  void discard(const SpillBlock& block);
  // For a file read in order: every block wholly before byte `end` is read for the last time, and
  // the pages below it are punched out at once (one punch instead of one per block of a few KiB, which
  // would dominate a pass over small blocks). Blocks on those pages read back as corrupt.
  void discardBefore(uint64_t end);

  // Opened segments that are this run's alone (a work directory inside its temporary directory):
  // discard gives their pages back as it does a discardable file's, once every block on a page
  // that countBlock counted is discarded. Call before countBlock.
  void ownOpened();
  void countBlock(const SpillBlock& block);

  // A named file: its bytes reach the disk (fsync; not for Named::sync false) and it takes its
  // final name. Throws Error
  // (Output) "PATH: cannot commit: REASON".
  void commit();

  // On disk (compressed): the end of the last block (of every segment, opened files).
  uint64_t bytes() const { return openedBytes_ + bytes_.load(std::memory_order_acquire); }
  const std::filesystem::path& path() const { return path_; }

 private:
  [[noreturn]] void corrupt(const SpillBlock& block, std::string_view reason,
                            const std::filesystem::path* file = nullptr) const;
  // An opened segment: its file, descriptor and size.
  struct Segment {
    std::filesystem::path path;
    int fd = -1;
    uint64_t bytes = 0;
  };
  SpillFile(TempSpace& space, std::vector<Segment> segments, size_t recordBytes);
  // An opened block's segment and offset in it; Error (Input) when it lies in none.
  std::pair<uint64_t, uint64_t> openedPlace(const SpillBlock& block) const;
  // Under writeMutex_: the blocks on the pages of [offset, + bytes) one fewer each; the pages left
  // with none below `keepFrom` punched out of `fd` and their bytes (up to `fileBytes`) released.
  void releasePages(int fd, std::vector<uint16_t>& live, uint64_t offset, uint64_t bytes, uint64_t keepFrom,
                    uint64_t fileBytes);

  TempSpace& space_;
  std::filesystem::path path_;
  int fd_ = -1;
  std::filesystem::path partial_;  // a named file not yet committed: its name until then
  uint64_t base_ = 0;              // a named file's segment, in its handles' offsets
  std::vector<Segment> opened_;    // opened files: every segment (fd_ is then -1)
  uint64_t openedBytes_ = 0;       // of the opened segments
  bool readOnly_ = false;          // a committed named file: its blocks are final
  bool discardable_ = false;
  size_t recordBytes_ = 1;
  bool sync_ = true;  // a named file: commit syncs it
  mutable std::mutex writeMutex_;
  // Of the file it appends to, written under writeMutex_, read by read() without it.
  std::atomic<uint64_t> bytes_{0};
  uint64_t held_ = 0;                              // accounted in the TempSpace, under writeMutex_
  std::vector<uint16_t> live_;                     // discardable: blocks not yet discarded on each page
  std::vector<std::vector<uint16_t>> openedLive_;  // ownOpened: the same, per opened segment
  uint64_t discardedBelow_ = 0;                    // discardBefore: every page below this is given back
};

}  // namespace facetree
