// Internal to io/: records bucketed by a window of keys (faces, original ids) for a pass that
// visits the windows in order: in memory until they pass a budget, then in runs of an unnamed
// temporary file, a bucket's buffer written as a run when it fills. Buckets are kept by window
// in an ordered map, so that keys far apart cost nothing between them.
#pragma once

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <type_traits>
#include <vector>

#include "files/temporary_file.h"

namespace facetree::fch {

template <class Record>
class WindowBuckets {
  static_assert(std::is_trivially_copyable_v<Record>);

 public:
  // `budget`: bytes in memory before the buckets go to the file; `runBytes`: a bucket's buffer from
  // then on (the windows times it is what the buffers hold).
  WindowBuckets(uint64_t budget, uint64_t runBytes, std::filesystem::path tmp)
      : runRecords_(std::max<uint64_t>(runBytes / sizeof(Record), 1)),
        budget_(budget),
        tmp_(std::move(tmp)) {}

  void add(uint64_t window, const Record& record) {
    Bucket& b = buckets_[window];
    b.buffer.push_back(record);
    ++b.count;
    held_ += sizeof(Record);
    if (!file_ && held_ > budget_) {
      file_ = std::make_unique<TemporaryFile>(tmp_);
      for (auto& [_, each] : buckets_) flush(each);
    } else if (file_ && b.buffer.size() >= runRecords_) {
      flush(b);
    }
  }
  bool empty() const { return buckets_.empty(); }
  uint64_t firstWindow() const { return buckets_.begin()->first; }
  // The bucket of `window` (empty if none), into `out` (replaced); the bucket is dropped.
  void take(uint64_t window, std::vector<Record>& out) {
    out.clear();
    const auto it = buckets_.find(window);
    if (it == buckets_.end()) return;
    Bucket& b = it->second;
    held_ -= b.buffer.size() * sizeof(Record);
    if (b.runs.empty()) {  // all in memory: handed over, not copied
      out.swap(b.buffer);
      buckets_.erase(it);
      return;
    }
    out.reserve(b.count);
    for (const Run& run : b.runs) {
      const size_t at = out.size();
      out.resize(at + run.count);
      file_->read(run.offset, &out[at], uint64_t{run.count} * sizeof(Record));
    }
    out.insert(out.end(), b.buffer.begin(), b.buffer.end());
    buckets_.erase(it);
  }

 private:
  struct Run {
    uint64_t offset;
    uint32_t count;
  };
  struct Bucket {
    std::vector<Record> buffer;
    std::vector<Run> runs;
    uint64_t count = 0;
  };
  void flush(Bucket& b) {
    if (b.buffer.empty()) return;
    const uint64_t bytes = b.buffer.size() * sizeof(Record);
    file_->write(end_, b.buffer.data(), bytes);
    b.runs.push_back({end_, static_cast<uint32_t>(b.buffer.size())});
    end_ += bytes;
    held_ -= bytes;
    b.buffer.clear();
  }

  std::map<uint64_t, Bucket> buckets_;
  uint64_t runRecords_, budget_, held_ = 0, end_ = 0;
  std::filesystem::path tmp_;
  std::unique_ptr<TemporaryFile> file_;
};

}  // namespace facetree::fch
