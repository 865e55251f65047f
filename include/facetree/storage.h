// facetree/storage.h: temporary storage under a memory cap, shared by the cluster file's readers and
// the out-of-core pipeline. Unnamed temporary files read and written at offsets (TemporaryFile);
// the temporary directory of a run and its byte accounting (TempSpace); append-only files of
// independently zstd-compressed blocks (SpillFile, SpillCodec); many record streams in one such
// file (BucketSpill); the external merge sort of fixed-size records (ExternalSorter; Knuth, TAOCP
// vol. 3, sec. 5.4); items made on helper threads ahead of their reader or consumed behind their
// writer (HelperRing), and taken by a team of workers (runWorkers).
#pragma once

#include <algorithm>
#include <atomic>
#include <concepts>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <deque>
#include <exception>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

#include "facetree/error.h"

struct ZSTD_CCtx_s;
struct ZSTD_DCtx_s;

namespace facetree {

// An unnamed temporary file that readers keep their overflow in (a pass's announced children, the
// face ranges of node frames, the queries' pages). Created where the system has unnamed files
// (O_TMPFILE), else named and removed at once: nothing is left behind, whatever ends the process.
// Reads and writes at offsets, so that threads do not share a file position.
class TemporaryFile {
 public:
  // `dir`: empty for the system's temporary directory; `owner` names what it serves in messages.
  // Throws Error (Output) when it cannot be made.
  explicit TemporaryFile(const std::filesystem::path& dir, std::string owner = {});
  ~TemporaryFile();
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;

  // Throw Error (Resource) when the disk is full, (Output) on other failures.
  void write(uint64_t offset, const void* data, uint64_t bytes);
  void read(uint64_t offset, void* data, uint64_t bytes) const;

 private:
  // "OWNER: WHAT in DIR: REASON" (no owner: "WHAT in DIR: REASON").
  std::string message(const char* what, int error) const;
  int fd_ = -1;
  std::filesystem::path dir_;
  std::string owner_;
};

// A file no directory entry names, in `dir`: O_TMPFILE where the file system has it, else a name
// removed at once. Returns its descriptor, or -1 with errno set.
int createUnnamedFile(const std::filesystem::path& dir, const char* prefix);

// The temporary directory of one out-of-core run, and the accounting of the bytes its files hold
// against --max-tmp: temporary files are bounded and removed.

// "PATH: reason: strerror(error)" as a Error (Resource).
[[noreturn]] void throwTempSpaceError(const std::filesystem::path& path, std::string_view reason, int error);

// The temporary directory of one run: created (mkdtemp) as `parent`/facetree-XXXXXX, parent defaulting to
// std::filesystem::temp_directory_path(), when the first file is named in it, so a run that fits in
// memory touches no disk; the destructor removes it with everything inside. Accounts the bytes its
// files hold (current and peak) and enforces maxBytes (0 = no limit). Thread-safe.
// It must outlive the SpillFiles made in it (they release their bytes to it when destroyed).
class TempSpace {
 public:
  // `created` is called with the directory once it exists (e.g. to register it for a signal
  // handler's last-resort cleanup).
  // `accountTo`: a space whose bytes include this one's (a task's of one process, in the run's):
  // every reserve is made there first, against its limit, and every release there too.
  explicit TempSpace(const std::filesystem::path& parent = {}, uint64_t maxBytes = 0,
                     std::function<void(const std::filesystem::path&)> created = {},
                     TempSpace* accountTo = nullptr);
  ~TempSpace();
  TempSpace(const TempSpace&) = delete;
  TempSpace& operator=(const TempSpace&) = delete;

  // The directory, created on the first call. Throws Error (Resource) "PARENT: cannot create
  // temporary directory: <strerror>".
  const std::filesystem::path& path();
  bool created() const { return created_.load(std::memory_order_acquire); }
  uint64_t maxBytes() const { return maxBytes_; }

  // A unique path inside the directory, `stem`-N.spill; the file is not created. Thread-safe.
  std::filesystem::path newFile(std::string_view stem);

  // Accounts `bytes` before they are written; throws Error (Resource) past maxBytes (and accounts nothing).
  void reserve(uint64_t bytes);
  void release(uint64_t bytes);
  // The committed files of a work directory, opened to be read: a task's space of one process
  // counts them here alone, since the run counts them as its own from their commit.
  void reserveOpened(uint64_t bytes) { accountTo_ ? reserveHere(bytes) : reserve(bytes); }
  void releaseOpened(uint64_t bytes) { current_.fetch_sub(bytes, std::memory_order_relaxed); }

  uint64_t currentBytes() const { return current_.load(std::memory_order_relaxed); }
  uint64_t peakBytes() const { return peak_.load(std::memory_order_relaxed); }

 private:
  void reserveHere(uint64_t bytes);
  std::filesystem::path parent_;
  TempSpace* accountTo_;
  std::function<void(const std::filesystem::path&)> onCreated_;
  std::mutex createMutex_;
  std::atomic<bool> created_{false};
  std::filesystem::path path_;
  uint64_t maxBytes_;
  std::atomic<uint64_t> current_{0};
  std::atomic<uint64_t> peak_{0};
  std::atomic<uint64_t> nextFile_{0};
};

// Append-only temporary files of independently zstd-compressed blocks, the storage under every spill of
// the out-of-core build (face cells, ghost edges, sort runs) and of the readers' sorts and buckets.

// Largest raw block: keeps rawBytes and the compressed bound in 32 bits.
inline constexpr size_t kMaxSpillBlockBytes = size_t{256} << 20;

// zstd level of every spill. Negative levels are zstd's fast mode (the match search skips ahead, literals
// stay raw): spills are written once and read once, so compression time counts more than a few percent
// of temporary bytes; -3 is where faster levels stop paying (docs/benchmarks.md has the trade-off).
inline constexpr int kSpillLevel = -3;
// A level that stores every block as it is, with its checksum: for the spills of records that zstd
// finds little in (the readers' sorts and windows of floats and codes), read back once, where the
// compression would cost more time than the bytes it saves.
inline constexpr int kSpillStored = std::numeric_limits<int>::min();

// Per-thread zstd state for spills (a CCtx and a DCtx, created once, reused): pass one per thread.
// Holds one compressed block of scratch, so its memory is the zstd contexts (~370 KiB at kSpillLevel
// for 64 KiB blocks) plus ZSTD_compressBound of the largest block it has seen.
class SpillCodec {
 public:
  explicit SpillCodec(int level = kSpillLevel);
  ~SpillCodec();
  SpillCodec(SpillCodec&&) noexcept;
  SpillCodec& operator=(SpillCodec&&) noexcept;

  // One zstd frame with content size and checksum, for a block that stores() does not keep as it is
  // (SpillFile writes and reads stored blocks in place); the view lives until the next call.
  // With `recordBytes` > 1 the bytes are first grouped by their place in records of that size
  // (byte 0 of every record, then byte 1, ...; a partial record at the end stays as it is): the
  // bytes of floats and small integers that vary alike end up together, which zstd finds (the
  // shuffle filter of Blosc, Alted 2010).
  std::span<const std::byte> compress(std::span<const std::byte> raw, size_t recordBytes = 1);
  // Whether a block of `rawBytes` is stored as it is (small blocks, kSpillStored) rather than compressed.
  bool stores(size_t rawBytes) const;
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
  bool stored_ = false;              // kSpillStored
};

// Where a block lives in its SpillFile: the handle append() returns and read() takes.
struct SpillBlock {
  uint64_t offset = 0;
  uint32_t compressedBytes = 0;
  uint32_t rawBytes = 0;
};

// The records of a block as read (its raw bytes, whole records) into `records`, replacing them.
template <class T>
void decodeRecords(std::span<const std::byte> bytes, std::vector<T>& records) {
  static_assert(std::is_trivially_copyable_v<T>);
  records.resize(bytes.size() / sizeof(T));
  std::memcpy(static_cast<void*>(records.data()), bytes.data(), records.size() * sizeof(T));
}

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

// Many append-only streams of fixed-size records sharing one SpillFile: the per-cell face spills, ghost
// edge records per cell, per-leaf node and face spills of the out-of-core build.
class BucketSpill {
 public:
  // `bufferBytes` is the in-memory buffer of each bucket, rounded down to whole records (at least one); a
  // full buffer becomes one block of the SpillFile. Memory is memoryBound(): buckets * bufferBytes (touched
  // only as buckets fill) plus one compressed block of scratch in the writer's codec.
  // `discardable`: its blocks can be given back as they are read for the last time (drainBucket).
  // `background`: full buffers are compressed and written on a helper thread while the caller goes on
  // filling (zstd takes most of a pass that only reads, bins and spills records); the blocks, their
  // order and the bytes read back are the same either way.
  BucketSpill(TempSpace& space, std::string_view stem, size_t buckets, size_t recordBytes, size_t bufferBytes,
              int level = kSpillLevel, bool discardable = false, bool background = false);
  // Its blocks in a named file (SpillFile::Named), for a task of the stages that hands the buckets
  // on: commit() writes every buffer and gives the file its name, index() then says where each
  // bucket's blocks are, and open() reads the buckets back in another task.
  BucketSpill(TempSpace& space, SpillFile::Named name, size_t buckets, size_t recordBytes, size_t bufferBytes,
              int level = kSpillLevel, bool background = false);
  void commit();
  // Every bucket's record count and blocks, as bytes for a manifest (after commit or releaseBuffers).
  std::string index() const;
  // The buckets a committed spill's index describes, read-only: reading and draining them leaves
  // the file as it is. Throws Error (Input) naming `path` for an index that does not describe it.
  static std::unique_ptr<BucketSpill> open(TempSpace& space, const std::filesystem::path& path,
                                           std::string_view index);
  // Committed spills of the same buckets (segments: `paths`, whose indexes indexOf(i) gives) read as
  // one: a bucket's blocks are each segment's in turn. Only buckets [first, end) keep their blocks,
  // so a reader of a few buckets of many large spills holds no more than those; every bucket keeps
  // its record count, and `records` gets each segment's, segment by segment (records[i * buckets +
  // b]).
  static std::unique_ptr<BucketSpill> openSegments(TempSpace& space,
                                                   std::span<const std::filesystem::path> paths,
                                                   const std::function<std::string(size_t)>& indexOf,
                                                   size_t first, size_t end, std::vector<uint32_t>& records);
  // openSegments a segment at a time: the indexes given in segment order, so that a reader of several
  // spills of the same segments (a task's faces and ghosts) reads each segment's manifest once.
  class SegmentReader {
   public:
    // `owned`: the segments are this run's alone, so draining a bucket gives their pages back
    // (SpillFile::ownOpened).
    SegmentReader(TempSpace& space, std::span<const std::filesystem::path> paths, size_t first, size_t end,
                  bool owned = false);
    ~SegmentReader();
    // The next segment's index; Error (Input) naming its path when it does not describe it.
    void add(std::string_view index);
    // Every segment's index added: the spill, and `records` as openSegments gives them.
    std::unique_ptr<BucketSpill> finish(std::vector<uint32_t>& records);

   private:
    std::vector<std::filesystem::path> paths_;
    size_t first_, end_, added_ = 0;
    bool owned_ = false;
    std::unique_ptr<SpillFile> file_;
    std::unique_ptr<BucketSpill> spill_;
    std::vector<uint32_t> records_, counts_;
  };
  ~BucketSpill();
  BucketSpill(const BucketSpill&) = delete;
  BucketSpill& operator=(const BucketSpill&) = delete;

  // With `background`, add backgroundBytes(bufferBytes).
  static uint64_t memoryBound(size_t buckets, size_t recordBytes, size_t bufferBytes);
  static uint64_t backgroundBytes(size_t bufferBytes);

  void append(size_t bucket, const void* record) {
    std::byte* buffer = buffer_.get() + bucket * bufferBytes_;
    std::memcpy(buffer + fill_[bucket], record, recordBytes_);
    fill_[bucket] += recordBytes_;
    ++records_[bucket];
    if (fill_[bucket] == bufferBytes_) flush(bucket);
  }
  void appendMany(size_t bucket, const void* records, size_t n);  // n records
  void flush(size_t bucket);                                      // its buffer becomes a block
  // Every buffer becomes a block, written before it returns (rethrows a failed background write).
  void flushAll();
  // flushAll(), then frees the buffers (buckets * bufferBytes) and the helper: the spill is read-only
  // afterwards.
  void releaseBuffers();
  // Every bucket's list of blocks goes to a file of `space`, a chunk per bucket, and the lists'
  // memory (a ChainedBlock per block, which grows with the spill: about a million blocks for 56M
  // faces in cells of 3 KiB buffers) goes back; with `entries`, again whenever the lists in memory
  // reach that many blocks, so they stay bounded while the spill grows. A bucket's chunks are
  // chained backwards (each starts with the handle of the one before); reading a bucket reads them
  // first, then the blocks still listed in memory. Not for a spill whose index is handed on.
  void offloadBlocks(TempSpace& space, size_t entries = 0);

  uint64_t records(size_t bucket) const { return records_[bucket]; }
  size_t recordBytes() const { return recordBytes_; }

  // Reads every record of `bucket` (blocks in order, then what is still buffered), appending to `out`.
  void readBucket(size_t bucket, std::vector<std::byte>& out, SpillCodec& codec) const;
  // Streams a bucket block by block: calls f(std::span<const std::byte>) per block (whole records), the
  // buffered tail last. Holds one decompressed block.
  template <class F>
  void forEachBlock(size_t bucket, SpillCodec& codec, F&& f) const {
    visitBlocks(bucket, codec, f, [](const SpillBlock&) {});
  }

  // forEachBlock for the last time: each block's disk space goes back once f has had it, and the
  // buffered tail is dropped. The bucket is empty afterwards. Only for a discardable spill.
  template <class F>
  void drainBucket(size_t bucket, SpillCodec& codec, F&& f) {
    visitBlocks(bucket, codec, f, [this](const SpillBlock& block) { file_->discard(block); });
    if (lists_) {
      std::vector<SpillBlock> chunks;
      blockList(bucket, codec, &chunks);
      for (const SpillBlock& chunk : chunks) lists_->discard(chunk);
      std::exchange(listOf_[bucket], {});
    }
    head_[bucket] = tail_[bucket] = kNoBlock;
    fill_[bucket] = 0;
    records_[bucket] = 0;
  }

  size_t buckets() const { return fill_.size(); }
  uint64_t bytesOnDisk() const {
    settle();
    return file_->bytes();
  }

 private:
  static constexpr uint32_t kNoBlock = UINT32_MAX;

  // f per block in order, then after(block) once f has had it; the buffered tail last.
  template <class F, class After>
  void visitBlocks(size_t bucket, SpillCodec& codec, F& f, const After& after) const {
    settle();
    std::vector<std::byte> raw;
    if (lists_) {  // offloaded: those blocks first
      const std::vector<SpillBlock> list = blockList(bucket, codec);
      for (const SpillBlock& block : list) {
        file_->read(block, raw, codec);
        f(std::span<const std::byte>(raw));
        after(block);
      }
    }
    for (uint32_t b = head_[bucket]; b != kNoBlock; b = blocks_[b].next) {
      file_->read(blocks_[b].block, raw, codec);
      f(std::span<const std::byte>(raw));
      after(blocks_[b].block);
    }
    if (fill_[bucket] > 0)
      f(std::span<const std::byte>(buffer_.get() + bucket * bufferBytes_, fill_[bucket]));
  }
  // The blocks of all buckets in one array, each bucket's chained in append order. A deque: the helper
  // fills in a block's handle through a pointer while the caller appends more.
  struct ChainedBlock {
    SpillBlock block;
    uint32_t next = kNoBlock;
  };
  // The helper thread of a background spill: buffers handed over in flush order, written in that
  // order, each into the handle reserved for it.
  class Writer;
  // Waits for the helper's writes, rethrowing the first that failed.
  void settle() const;
  // A bucket's offloaded blocks, in order; its chunks' handles in `chunks`, when given.
  std::vector<SpillBlock> blockList(size_t bucket, SpillCodec& codec,
                                    std::vector<SpillBlock>* chunks = nullptr) const;
  // The lists in memory to the lists' file, each bucket's as a chunk after its last.
  void offloadRound();
  uint32_t reserveBlock(size_t bucket);

  BucketSpill(std::unique_ptr<SpillFile> file, size_t buckets, size_t recordBytes, size_t bufferBytes,
              int level, bool background);

  std::unique_ptr<SpillFile> file_;
  SpillCodec writer_;
  std::unique_ptr<Writer> background_;
  size_t recordBytes_;
  size_t bufferBytes_;
  std::unique_ptr<std::byte[]> buffer_;  // bucket b at [b * bufferBytes_, (b + 1) * bufferBytes_)
  std::vector<size_t> fill_;             // bytes buffered per bucket
  std::vector<uint64_t> records_;
  std::vector<uint32_t> head_, tail_;
  std::deque<ChainedBlock> blocks_;
  std::unique_ptr<SpillFile> lists_;  // offloadBlocks: the buckets' offloaded lists, in chunks
  std::vector<SpillBlock> listOf_;    // each bucket's last chunk
  size_t offloadAt_ = 0;              // blocks listed in memory that start another round (0: none)
};

// External merge sort of fixed-size records under a memory budget (Knuth, TAOCP vol. 3, 5.4): runs
// of a full buffer sorted in memory, combined by a P-way heap merge in as many balanced passes as
// the budget's fan-in needs. The edge matching across cells sorts its half-edge records with it,
// the cut's fit its faces in Morton order.
// Memory: the budget, plus one compressed block, the zstd contexts and 16 bytes a spilled block
// (sort_memory_probe checks them).

// Sizes derived from a budget (see storage/external_sort.cpp for the constants).
struct SortPlan {
  size_t bufferRecords = 0;  // records sorted in memory per run
  size_t blockRecords = 0;   // records per compressed block of a run
  size_t fanIn = 0;          // runs merged at once
};
SortPlan sortPlan(size_t recordBytes, size_t budgetBytes);

namespace sort_detail {

// Sorted runs, each a sequence of consecutive blocks of one SpillFile.
class RunStore {
 public:
  RunStore(TempSpace& space, const std::string& stem);
  void beginRun() { runStart_.push_back(blocks_.size()); }
  void append(std::span<const std::byte> raw, SpillCodec& codec) {
    blocks_.push_back(file_->append(raw, codec));
  }
  size_t runs() const { return runStart_.size(); }
  std::span<const SpillBlock> run(size_t r) const {
    const size_t end = r + 1 < runStart_.size() ? runStart_[r + 1] : blocks_.size();
    return std::span<const SpillBlock>(blocks_).subspan(runStart_[r], end - runStart_[r]);
  }
  const SpillFile& file() const { return *file_; }

 private:
  std::unique_ptr<SpillFile> file_;
  std::vector<SpillBlock> blocks_;
  std::vector<size_t> runStart_;
};

// Reads one run a block at a time; holds one decompressed block.
class RunCursor {
 public:
  RunCursor(const SpillFile& file, std::span<const SpillBlock> blocks) : file_(&file), blocks_(blocks) {}
  // The next `recordBytes` bytes of the run, or nullptr at its end.
  const std::byte* next(size_t recordBytes, SpillCodec& codec) {
    if (position_ == raw_.size()) {
      if (nextBlock_ == blocks_.size()) return nullptr;
      file_->read(blocks_[nextBlock_++], raw_, codec);
      position_ = 0;
      if (raw_.size() % recordBytes != 0 || raw_.empty())
        throw Error(ErrorCategory::Resource, file_->path().string() + ": corrupt run block");
    }
    const std::byte* record = raw_.data() + position_;
    position_ += recordBytes;
    return record;
  }

 private:
  const SpillFile* file_;
  std::span<const SpillBlock> blocks_;
  size_t nextBlock_ = 0;
  std::vector<std::byte> raw_;
  size_t position_ = 0;
};

}  // namespace sort_detail

// A Less whose order is that of a 64-bit key of each record (less.key(r)).
template <class Less, class Record>
concept KeyedOrder = requires(const Less& less, const Record& r) {
  { less.key(r) } -> std::convertible_to<uint64_t>;
};

// The next capacity of a buffer of T that grows to `budget` elements: about a MiB first, then
// fourfold steps, so that what a small pass allocates follows what it holds, not its budget (a
// reader's cap), and a large one copies a third of what it holds. The last step goes to the budget
// from at most half of it: the old and new buffers' touched pages never pass the budget while the
// elements move.
template <class T>
size_t grownWithin(size_t capacity, size_t budget) {
  constexpr size_t kFirst = std::max<size_t>((size_t{1} << 20) / sizeof(T), 1);
  if (capacity == 0) return 2 * kFirst > budget ? budget : kFirst;
  return 8 * capacity > budget ? budget : 4 * capacity;
}

// Sorts trivially copyable records with bounded memory (Knuth vol. 3, 5.4: run formation + multiway merge).
// Records are buffered up to `budgetBytes`; a full buffer is sorted (std::sort with `less`, which must be a
// strict TOTAL order so the result is deterministic) and spilled as a run of blocks. finish() merges the runs
// with a heap; when there are more runs than the budget allows open at once (each open run holds one
// decompressed block), it merges them in passes. With everything fitting in the budget nothing touches disk.
// Budgets below 16 records are raised to 16 records.
// With a KeyedOrder the sort is stable instead (equal keys keep the order pushed): a buffer sorts
// pairs of key and place, which std::sort moves faster than large records, and the records are
// gathered through them; the heap gives ties to the earlier run.
template <class Record, class Less = std::less<Record>>
class ExternalSorter {
  static_assert(std::is_trivially_copyable_v<Record>, "records are spilled as bytes");
  static constexpr bool kKeyed = KeyedOrder<Less, Record>;
  using Order = std::pair<uint64_t, uint32_t>;  // a keyed record's key and place in the buffer

 public:
  ExternalSorter(TempSpace& space, std::string_view stem, size_t budgetBytes, Less less = {},
                 int level = kSpillLevel)
      : space_(space),
        stem_(stem),
        plan_(sortPlan(sizeof(Record) + (kKeyed ? sizeof(Order) : 0), budgetBytes)),
        less_(less),
        level_(level) {}

  void push(const Record& r) {
    if (buffer_.size() == plan_.bufferRecords) spillRun();
    if (buffer_.size() == buffer_.capacity())
      buffer_.reserve(grownWithin<Record>(buffer_.capacity(), plan_.bufferRecords));
    buffer_.push_back(r);
    ++size_;
  }

  // No push() after it.
  void finish() {
    if (!store_) {
      sortBuffer();
      return;
    }
    if (!buffer_.empty()) spillRun();
    std::vector<Record>().swap(buffer_);  // the budget now goes to the merge's blocks
    std::vector<Order>().swap(order_);
    while (store_->runs() > plan_.fanIn) mergePass();
    openMerge(*store_, 0, store_->runs());
    ++mergePasses_;
  }

  // The next records in sorted order; 0 at the end.
  size_t read(std::span<Record> out) {
    if (!store_) {
      const size_t n = std::min(out.size(), buffer_.size() - readPosition_);
      for (size_t i = 0; i < n; ++i) out[i] = sorted(readPosition_ + i);
      readPosition_ += n;
      if (readPosition_ == buffer_.size()) {  // done: free the budget now
        std::vector<Record>().swap(buffer_);
        std::vector<Order>().swap(order_);
        readPosition_ = 0;
      }
      return n;
    }
    size_t n = 0;
    while (n < out.size() && popMerge(out[n])) ++n;
    if (n < out.size()) {  // done: the blocks and the runs' file go now, not with the sorter
      closeMerge();
      store_.reset();
    }
    return n;
  }

  uint64_t size() const { return size_; }              // records pushed
  size_t runs() const { return runs_; }                // runs spilled (0 = in memory)
  size_t mergePasses() const { return mergePasses_; }  // passes over the spilled data, the final one included
  const SortPlan& plan() const { return plan_; }

 private:
  struct HeapEntry {
    Record record;
    uint32_t cursor;
  };

  SpillCodec& codec() {
    if (!codec_) codec_.emplace(level_);
    return *codec_;
  }

  void sortBuffer() {
    if constexpr (kKeyed) {
      order_.resize(buffer_.size());
      for (size_t i = 0; i < buffer_.size(); ++i)
        order_[i] = {less_.key(buffer_[i]), static_cast<uint32_t>(i)};
      std::sort(order_.begin(), order_.end());
    } else {
      std::sort(buffer_.begin(), buffer_.end(), less_);
    }
  }
  // The i-th record of the sorted buffer.
  const Record& sorted(size_t i) const {
    if constexpr (kKeyed) return buffer_[order_[i].second];
    return buffer_[i];
  }

  // Sorts the buffer and writes it as one run of blocks (a keyed one's gathered a block at a time).
  void spillRun() {
    sortBuffer();
    if (!store_) store_.emplace(space_, stem_);
    store_->beginRun();
    std::vector<Record> gathered;
    for (size_t first = 0; first < buffer_.size(); first += plan_.blockRecords) {
      const size_t n = std::min(plan_.blockRecords, buffer_.size() - first);
      std::span<const Record> block(buffer_.data() + first, n);
      if constexpr (kKeyed) {
        gathered.resize(n);
        for (size_t i = 0; i < n; ++i) gathered[i] = sorted(first + i);
        block = gathered;
      }
      store_->append(std::as_bytes(block), codec());
    }
    buffer_.clear();
    ++runs_;
  }

  // One balanced pass: every group of fanIn runs becomes one run of a new file; the old file goes.
  void mergePass() {
    sort_detail::RunStore next(space_, stem_);
    std::vector<Record> block;
    block.reserve(plan_.blockRecords);
    for (size_t first = 0; first < store_->runs(); first += plan_.fanIn) {
      openMerge(*store_, first, std::min(store_->runs(), first + plan_.fanIn));
      next.beginRun();
      block.clear();
      for (Record r; popMerge(r);) {
        block.push_back(r);
        if (block.size() == plan_.blockRecords) {
          next.append(std::as_bytes(std::span<const Record>(block)), codec());
          block.clear();
        }
      }
      if (!block.empty()) next.append(std::as_bytes(std::span<const Record>(block)), codec());
      closeMerge();
    }
    store_.emplace(std::move(next));
    ++mergePasses_;
  }

  // Heap order: smallest record first, ties (equal under a total order: identical keys) by run, so the
  // merge is deterministic even for a Less that is only a strict weak order.
  bool before(const HeapEntry& a, const HeapEntry& b) const {
    if (less_(a.record, b.record)) return true;
    if (less_(b.record, a.record)) return false;
    return a.cursor < b.cursor;
  }

  void openMerge(const sort_detail::RunStore& store, size_t firstRun, size_t endRun) {
    cursors_.clear();
    heap_.clear();
    for (size_t r = firstRun; r < endRun; ++r) {
      cursors_.emplace_back(store.file(), store.run(r));
      if (const std::byte* head = cursors_.back().next(sizeof(Record), codec())) {
        HeapEntry entry{Record{}, static_cast<uint32_t>(cursors_.size() - 1)};
        std::memcpy(&entry.record, head, sizeof(Record));
        heap_.push_back(entry);
      }
    }
    for (size_t i = heap_.size() / 2; i-- > 0;) siftDown(i);
  }

  void closeMerge() {
    std::vector<sort_detail::RunCursor>().swap(cursors_);
    heap_.clear();
  }

  bool popMerge(Record& out) {
    if (heap_.empty()) return false;
    out = heap_[0].record;
    if (const std::byte* head = cursors_[heap_[0].cursor].next(sizeof(Record), codec())) {
      std::memcpy(&heap_[0].record, head, sizeof(Record));
    } else {
      heap_[0] = heap_.back();
      heap_.pop_back();
      if (heap_.empty()) return true;
    }
    siftDown(0);
    return true;
  }

  void siftDown(size_t i) {
    const size_t n = heap_.size();
    const HeapEntry moving = heap_[i];
    for (size_t child; (child = 2 * i + 1) < n; i = child) {
      if (child + 1 < n && before(heap_[child + 1], heap_[child])) ++child;
      if (!before(heap_[child], moving)) break;
      heap_[i] = heap_[child];
    }
    heap_[i] = moving;
  }

  TempSpace& space_;
  std::string stem_;
  SortPlan plan_;
  Less less_;
  int level_;
  std::optional<SpillCodec> codec_;  // created at the first spill: in-memory sorts need no zstd state
  std::vector<Record> buffer_;
  std::vector<Order> order_;  // keyed: the buffer's order
  size_t readPosition_ = 0;
  std::optional<sort_detail::RunStore> store_;
  std::vector<sort_detail::RunCursor> cursors_;
  std::vector<HeapEntry> heap_;
  uint64_t size_ = 0;
  size_t runs_ = 0;
  size_t mergePasses_ = 0;
};

// A ring of `slots` items handed between the caller and `workers` helper threads, so that a pass's
// reads, writes or compression overlap its own work. The caller fills slot() and hands it on with
// submit(); the helpers begin the items in turn (with one helper they also end in turn), each with
// `consume(item, worker)`. Written behind: the caller fills what the helpers consume. Read ahead:
// the caller submits requests and the helpers make the items, which the caller takes back in turn
// with take(), each valid until its slot is filled again; it fills no slot it has not taken.
// settle() waits until every item submitted is consumed. The first exception of a helper reaches
// the caller at the next slot() or settle(), or at the take() of the item it failed on (the items
// before it are taken as made); the items begun after it are skipped.
template <class Item>
class HelperRing {
 public:
  template <class Consume>
  explicit HelperRing(Consume consume, size_t slots = 2, unsigned workers = 1)
      : slots_(slots), state_(slots, kFree) {
    const auto shared = std::make_shared<Consume>(std::move(consume));  // one, called by every helper
    for (unsigned w = 0; w < workers; ++w) threads_.emplace_back([this, w, shared] { run(*shared, w); });
  }
  ~HelperRing() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    queued_.notify_all();
    for (std::thread& t : threads_) t.join();
  }
  HelperRing(const HelperRing&) = delete;
  HelperRing& operator=(const HelperRing&) = delete;

  // The caller's slot to fill next: waits until the helpers are done with the item `slots` before.
  Item& slot() { return wait(made_, true); }
  void submit() {
    {
      std::lock_guard lock(mutex_);
      state_[made_++ % slots_.size()] = kBusy;
    }
    queued_.notify_one();
  }
  Item& take() { return wait(taken_++, false); }
  bool full() const { return made_ - taken_ == slots_.size(); }  // of items not taken back
  bool empty() const { return made_ == taken_; }
  void settle() {
    std::unique_lock lock(mutex_);
    consumed_.wait(lock, [&] { return done_ == made_ || failure_; });
    if (failure_) std::rethrow_exception(failure_);
  }
  // Every slot, for the bytes they hold: a helper may be filling one, so only what it publishes
  // atomically in an item may be read while items are in flight.
  const std::vector<Item>& slots() const { return slots_; }

 private:
  enum : uint8_t { kFree, kBusy, kFailed };  // a slot's item: consumed, submitted, failed or skipped
  Item& wait(uint64_t item, bool anyFailure) {
    std::unique_lock lock(mutex_);
    uint8_t& state = state_[item % slots_.size()];
    consumed_.wait(lock, [&] { return state != kBusy || (anyFailure && failure_); });
    if (failure_ && (anyFailure || state == kFailed)) std::rethrow_exception(failure_);
    return slots_[item % slots_.size()];
  }
  template <class Consume>
  void run(Consume& consume, unsigned worker) {
    std::unique_lock lock(mutex_);
    for (;;) {
      queued_.wait(lock, [&] { return made_ > begun_ || stop_; });
      if (made_ == begun_) return;
      const uint64_t item = begun_++;
      const bool skip = failure_ != nullptr;
      lock.unlock();
      std::exception_ptr failure;
      try {
        if (!skip) consume(slots_[item % slots_.size()], worker);
      } catch (...) {
        failure = std::current_exception();
      }
      lock.lock();
      if (failure && !failure_) failure_ = failure;
      state_[item % slots_.size()] = skip || failure ? kFailed : kFree;
      ++done_;
      consumed_.notify_one();  // only the caller waits on it
    }
  }

  std::vector<Item> slots_;     // a ring: item i in slots_[i % size]
  std::vector<uint8_t> state_;  // each slot's item's state
  std::mutex mutex_;
  std::condition_variable queued_, consumed_;  // the helpers wait on the one, the caller on the other
  uint64_t made_ = 0, begun_ = 0, done_ = 0, taken_ = 0;  // items submitted, begun, consumed, taken back
  bool stop_ = false;
  std::exception_ptr failure_;
  std::vector<std::thread> threads_;  // last: start once the rest exists
};

// Runs work(worker, failed) on `workers` threads, the calling one as worker 0, and rethrows the
// first exception any of them throws once all have returned. `failed` turns true at that
// exception, for the others to stop taking items at their next one.
template <class Work>
void runWorkers(unsigned workers, Work&& work) {
  std::atomic<bool> failed{false};
  std::exception_ptr first;
  std::mutex mutex;
  const auto run = [&](unsigned worker) {
    try {
      work(worker, std::as_const(failed));
    } catch (...) {
      const std::lock_guard lock(mutex);
      if (!first) first = std::current_exception();
      failed = true;
    }
  };
  {
    std::vector<std::jthread> pool;
    for (unsigned w = 1; w < workers; ++w) pool.emplace_back(run, w);
    run(0);
  }
  if (first) std::rethrow_exception(first);
}

// Manifests: what a task of a run hands on to the tasks after it, as bytes under a name. A manifest
// is a magic, its kind, the fields little-endian as this machine lays them out (the tasks of one job
// run the same build), and an XXH64 of everything before it; a file appears under its name only
// once complete. The stages of the out-of-core build and the tiles' tasks use them alike.
class ManifestWriter {
 public:
  template <class T>
  void put(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    append({reinterpret_cast<const char*>(&value), sizeof value});
  }
  void putBytes(std::string_view bytes) {
    put(uint64_t{bytes.size()});
    append(bytes);
  }
  template <class T>
  void putVector(const std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    putBytes({reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T)});
  }
  // One field, as ManifestReader::field reads it back: a record's list of fields, written once,
  // serves both (a string goes as its bytes, a vector as its elements).
  template <class T>
  void field(const T& value) {
    if constexpr (std::is_same_v<T, std::string>)
      putBytes(value);
    else
      put(value);
  }
  template <class T>
  void field(const std::vector<T>& values) {
    putVector(values);
  }
  // Vectors as field writes them, each freed once in: their owner never holds one beside the
  // manifest.
  template <class... T>
  void tables(std::vector<T>&... values) {
    (putVector(std::exchange(values, {})), ...);
  }
  // Writes `path` (as PATH.partial, synced, renamed): Error (Output) naming it when it cannot.
  void commit(const std::filesystem::path& path, std::string_view kind) const;
  // The manifest's bytes as commit writes them, and their size.
  std::string sealed(std::string_view kind) const;
  uint64_t sealedBytes(std::string_view kind) const;

 private:
  // The fields in chunks: a large one (a write plan's table, megabytes) is a chunk of its own,
  // so that the manifest never holds its bytes twice while it grows, nor when it is written.
  void append(std::string_view bytes);
  std::vector<std::string> chunks_;
  uint64_t bytes_ = 0;
};

class ManifestReader {
 public:
  // Reads and checks `path`; Error (Input) "PATH: REASON" when it is missing, cut short, of
  // another kind or changed since it was written.
  ManifestReader(const std::filesystem::path& path, std::string_view kind);
  // Checks the manifest `path` kept in memory (`bytes`, as sealed), as the file's.
  ManifestReader(const std::filesystem::path& path, std::shared_ptr<const std::string> bytes,
                 std::string_view kind);
  template <class T>
  T take() {
    static_assert(std::is_trivially_copyable_v<T>);
    T value;
    std::memcpy(&value, need(sizeof value), sizeof value);
    return value;
  }
  std::string takeBytes() { return std::string(takeView()); }
  // The bytes of a field in place, valid while the reader lives.
  std::string_view takeView() {
    const auto n = take<uint64_t>();
    return std::string_view(need(n), n);
  }
  template <class T>
  std::vector<T> takeVector() {
    const auto n = take<uint64_t>();
    if (n % sizeof(T) != 0) fail("a field of part of a record");
    std::vector<T> values(n / sizeof(T));
    const char* from = need(n);
    if (n > 0) std::memcpy(values.data(), from, n);  // an empty vector's data() may be null
    return values;
  }
  template <class T>
  void field(T& value) {
    if constexpr (std::is_same_v<T, std::string>)
      value = takeBytes();
    else
      value = take<T>();
  }
  template <class T>
  void field(std::vector<T>& values) {
    values = takeVector<T>();
  }
  template <class... T>
  void tables(std::vector<T>&... values) {
    (field(values), ...);
  }
  // Every field taken: the manifest ends here.
  void finish();
  // Error (Input) "PATH: WHY": for a field its reader finds wrong.
  [[noreturn]] void fail(const std::string& why) const;

 private:
  void check(std::string_view kind);
  const char* need(uint64_t bytes);
  std::filesystem::path path_;
  std::shared_ptr<const std::string> bytes_;
  size_t at_ = 0, end_ = 0;  // the fields: [at_, end_), the checksum past them
};

}  // namespace facetree
