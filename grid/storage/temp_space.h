// The temporary directory of one out-of-core run, and the accounting of the bytes its files hold
// against --max-tmp: temporary files are bounded and removed. Internal to grid/.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <string>
#include <string_view>

#include "facetree/error.h"

namespace facetree {

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

}  // namespace facetree
