// Internal to io/: records sorted by a 64-bit key under a memory budget (Knuth, TAOCP vol. 3, sec.
// 5.4.1): a full buffer is sorted and written as a run to an unnamed temporary file, and the runs are
// merged through a heap, each read in slices of an equal share of the budget. Records that fit the
// budget never touch the file. Equal keys keep the order records were added in: a run sorts pairs of
// (key, position), which std::sort moves far faster than the records, and the heap gives ties to the
// earlier run.
#pragma once

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <queue>
#include <type_traits>
#include <vector>

#include "files/temporary_file.h"

namespace facetree::fch {

template <class Record, class Key>
class SortedRuns {
  static_assert(std::is_trivially_copyable_v<Record>);

 public:
  SortedRuns(uint64_t budget, std::filesystem::path tmp, Key key = {})
      : capacity_(std::max<uint64_t>(budget / (sizeof(Record) + sizeof(Order)), 64)),
        tmp_(std::move(tmp)),
        key_(key) {}

  void add(const Record& r) {
    if (buffer_.size() == capacity_) writeRun();
    if (buffer_.size() == buffer_.capacity() && 2 * buffer_.capacity() > capacity_)
      buffer_.reserve(capacity_);
    buffer_.push_back(r);
  }
  // Calls visit(record) for every record in sorted order (equal keys in the order added); once.
  template <class Visit>
  void forEachSorted(Visit&& visit) {
    if (runs_.empty()) {
      sortBuffer();
      for (const Order& o : order_) visit(buffer_[o.second]);
      return;
    }
    writeRun();
    std::vector<Record>().swap(buffer_);
    std::vector<Order>().swap(order_);
    const uint64_t slice = std::max<uint64_t>(capacity_ / runs_.size(), 16);
    struct Cursor {
      uint64_t next, end;  // records of the run not yet read: [next, end)
      std::vector<Record> slice;
      size_t at = 0;
    };
    std::vector<Cursor> cursors(runs_.size());
    const auto refill = [&](Cursor& c) {
      const uint64_t n = std::min(slice, c.end - c.next);
      c.slice.resize(n);
      if (n) file_->read(c.next * sizeof(Record), c.slice.data(), n * sizeof(Record));
      c.next += n, c.at = 0;
      return n > 0;
    };
    // The heap's top is the smallest head; ties go to the earlier run, which holds earlier records.
    const auto later = [&](size_t a, size_t b) {
      const Record& x = cursors[a].slice[cursors[a].at];
      const Record& y = cursors[b].slice[cursors[b].at];
      const uint64_t kx = key_(x), ky = key_(y);
      return ky < kx || (kx == ky && a > b);
    };
    std::priority_queue<size_t, std::vector<size_t>, decltype(later)> heap(later);
    for (size_t i = 0; i < runs_.size(); ++i) {
      cursors[i].next = runs_[i].first, cursors[i].end = runs_[i].second;
      if (refill(cursors[i])) heap.push(i);
    }
    while (!heap.empty()) {
      const size_t i = heap.top();
      heap.pop();
      Cursor& c = cursors[i];
      visit(c.slice[c.at]);
      if (++c.at < c.slice.size() || refill(c)) heap.push(i);
    }
  }

 private:
  using Order = std::pair<uint64_t, uint32_t>;  // a record's key and its position in the buffer
  void sortBuffer() {
    order_.resize(buffer_.size());
    for (size_t i = 0; i < buffer_.size(); ++i) order_[i] = {key_(buffer_[i]), static_cast<uint32_t>(i)};
    std::sort(order_.begin(), order_.end());
  }
  // The buffer sorted, written as a run in slices gathered through the order.
  void writeRun() {
    sortBuffer();
    if (!file_) file_ = std::make_unique<TemporaryFile>(tmp_);
    constexpr size_t kSlice = 4096;
    std::vector<Record> slice;
    slice.reserve(std::min(kSlice, buffer_.size()));
    for (size_t at = 0; at < order_.size(); at += kSlice) {
      slice.clear();
      for (size_t i = at; i < std::min(order_.size(), at + kSlice); ++i)
        slice.push_back(buffer_[order_[i].second]);
      file_->write((end_ + at) * sizeof(Record), slice.data(), slice.size() * sizeof(Record));
    }
    runs_.emplace_back(end_, end_ + buffer_.size());
    end_ += buffer_.size();
    buffer_.clear();
  }

  uint64_t capacity_;
  std::filesystem::path tmp_;
  Key key_;
  std::vector<Record> buffer_;
  std::vector<Order> order_;
  std::vector<std::pair<uint64_t, uint64_t>> runs_;  // records [first, end) of the file
  uint64_t end_ = 0;
  std::unique_ptr<TemporaryFile> file_;
};

}  // namespace facetree::fch
