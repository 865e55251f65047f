// Many append-only streams of fixed-size records sharing one SpillFile: the per-cell face spills, ghost
// edge records per cell, per-leaf node and face spills of the out-of-core build. Internal to grid/.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <deque>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "storage/spill_file.h"

namespace facetree {

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

}  // namespace facetree
