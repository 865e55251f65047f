// The run's temporary directory and its byte accounting (facetree/storage.h).
#include "facetree/storage.h"

#include <stdlib.h>  // mkdtemp

#include <cerrno>
#include <cstring>
#include <system_error>

namespace facetree {

void throwTempSpaceError(const std::filesystem::path& path, std::string_view reason, int error) {
  std::string message = path.string();
  message += ": ";
  message += reason;
  message += ": ";
  message += std::strerror(error);
  throw Error(ErrorCategory::Resource, message);
}

TempSpace::TempSpace(const std::filesystem::path& parent, uint64_t maxBytes,
                     std::function<void(const std::filesystem::path&)> created, TempSpace* accountTo)
    : parent_(parent), accountTo_(accountTo), onCreated_(std::move(created)), maxBytes_(maxBytes) {}

const std::filesystem::path& TempSpace::path() {
  if (created_.load(std::memory_order_acquire)) return path_;
  const std::lock_guard lock(createMutex_);
  if (created_.load(std::memory_order_relaxed)) return path_;
  std::filesystem::path base = parent_;
  if (base.empty()) {
    std::error_code ec;
    base = std::filesystem::temp_directory_path(ec);
    // temp_directory_path fails when $TMPDIR is not a directory; name what it rejected.
    if (ec)
      throwTempSpaceError(base.empty() ? "$TMPDIR" : base, "cannot create temporary directory", ec.value());
  }
  std::string pattern = (base / "facetree-XXXXXX").string();
  if (!mkdtemp(pattern.data())) throwTempSpaceError(base, "cannot create temporary directory", errno);
  path_ = pattern;
  created_.store(true, std::memory_order_release);
  if (onCreated_) onCreated_(path_);
  return path_;
}

TempSpace::~TempSpace() {
  if (!created()) return;
  std::error_code ignored;  // a destructor cannot report; the files were the run's scratch only
  std::filesystem::remove_all(path_, ignored);
}

std::filesystem::path TempSpace::newFile(std::string_view stem) {
  const uint64_t n = nextFile_.fetch_add(1, std::memory_order_relaxed);
  std::string name(stem);
  name += '-';
  name += std::to_string(n);
  name += ".spill";
  return path() / name;
}

void TempSpace::reserve(uint64_t bytes) {
  if (!accountTo_) return reserveHere(bytes);
  accountTo_->reserve(bytes);
  try {
    reserveHere(bytes);
  } catch (...) {
    accountTo_->release(bytes);
    throw;
  }
}

void TempSpace::reserveHere(uint64_t bytes) {
  uint64_t current = current_.load(std::memory_order_relaxed);
  uint64_t next;
  do {
    next = current + bytes;
    if (maxBytes_ != 0 && (next > maxBytes_ || next < current))
      throw Error(ErrorCategory::Resource, (created() ? path_ : parent_).string() +
                                               ": temporary files would exceed --max-tmp " +
                                               std::to_string(maxBytes_) + " bytes");
  } while (!current_.compare_exchange_weak(current, next, std::memory_order_relaxed));
  uint64_t peak = peak_.load(std::memory_order_relaxed);
  while (peak < next && !peak_.compare_exchange_weak(peak, next, std::memory_order_relaxed)) {
  }
}

void TempSpace::release(uint64_t bytes) {
  current_.fetch_sub(bytes, std::memory_order_relaxed);
  if (accountTo_) accountTo_->release(bytes);
}

}  // namespace facetree
