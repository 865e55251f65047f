// External merge sort of fixed-size records under a memory budget (Knuth, TAOCP vol. 3, 5.4): runs
// of a full buffer sorted in memory, combined by a P-way heap merge in as many balanced passes as
// the budget's fan-in needs. The edge matching across cells sorts its half-edge records with it.
// Memory: the budget, plus one compressed block, the zstd contexts and 16 bytes a spilled block
// (sort_memory_probe checks them). Internal to grid/.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "storage/spill_file.h"
#include "storage/temp_space.h"

namespace facetree {

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

// Sorts trivially copyable records with bounded memory (Knuth vol. 3, 5.4: run formation + multiway merge).
// Records are buffered up to `budgetBytes`; a full buffer is sorted (std::sort with `less`, which must be a
// strict TOTAL order so the result is deterministic) and spilled as a run of blocks. finish() merges the runs
// with a heap; when there are more runs than the budget allows open at once (each open run holds one
// decompressed block), it merges them in passes. With everything fitting in the budget nothing touches disk.
// Budgets below 16 records are raised to 16 records.
template <class Record, class Less = std::less<Record>>
class ExternalSorter {
  static_assert(std::is_trivially_copyable_v<Record>, "records are spilled as bytes");

 public:
  ExternalSorter(TempSpace& space, std::string_view stem, size_t budgetBytes, Less less = {},
                 int level = kSpillLevel)
      : space_(space),
        stem_(stem),
        plan_(sortPlan(sizeof(Record), budgetBytes)),
        less_(less),
        level_(level) {}

  void push(const Record& r) {
    if (buffer_.size() == plan_.bufferRecords) spillRun();
    if (buffer_.capacity() == 0) buffer_.reserve(plan_.bufferRecords);  // exactly the budget, never 2x
    buffer_.push_back(r);
    ++size_;
  }

  // No push() after it.
  void finish() {
    if (!store_) {
      std::sort(buffer_.begin(), buffer_.end(), less_);
      return;
    }
    if (!buffer_.empty()) spillRun();
    std::vector<Record>().swap(buffer_);  // the budget now goes to the merge's blocks
    while (store_->runs() > plan_.fanIn) mergePass();
    openMerge(*store_, 0, store_->runs());
    ++mergePasses_;
  }

  // The next records in sorted order; 0 at the end.
  size_t read(std::span<Record> out) {
    if (!store_) {
      const size_t n = std::min(out.size(), buffer_.size() - readPosition_);
      std::copy_n(buffer_.begin() + readPosition_, n, out.begin());
      readPosition_ += n;
      if (readPosition_ == buffer_.size()) {  // done: free the budget now
        std::vector<Record>().swap(buffer_);
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

  // Sorts the buffer and writes it as one run of blocks.
  void spillRun() {
    std::sort(buffer_.begin(), buffer_.end(), less_);
    if (!store_) store_.emplace(space_, stem_);
    store_->beginRun();
    for (size_t first = 0; first < buffer_.size(); first += plan_.blockRecords) {
      const size_t n = std::min(plan_.blockRecords, buffer_.size() - first);
      store_->append(std::as_bytes(std::span<const Record>(buffer_.data() + first, n)), codec());
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
  size_t readPosition_ = 0;
  std::optional<sort_detail::RunStore> store_;
  std::vector<sort_detail::RunCursor> cursors_;
  std::vector<HeapEntry> heap_;
  uint64_t size_ = 0;
  size_t runs_ = 0;
  size_t mergePasses_ = 0;
};

}  // namespace facetree
