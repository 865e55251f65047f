// The manifests a run keeps in its memory, and the work directory that hands them on
// (job/manifest.h).
#include "job/manifest.h"

#include <filesystem>

namespace facetree {

bool ManifestShelf::put(const std::filesystem::path& path, std::string& bytes) {
  const std::lock_guard lock(mutex_);
  const auto at = entries_.find(path);
  const uint64_t replaced = at != entries_.end() && at->second.bytes ? at->second.bytes->size() : 0;
  if (bytes_ - replaced + bytes.size() > budget_) {
    if (at != entries_.end()) {
      bytes_ -= replaced;
      at->second = Entry{};
    }
    return false;
  }
  bytes_ += bytes.size() - replaced;
  entries_[path] = Entry{std::make_shared<const std::string>(std::move(bytes)), nullptr};
  return true;
}

std::shared_ptr<const std::string> ManifestShelf::find(const std::filesystem::path& path) const {
  const std::lock_guard lock(mutex_);
  const auto at = entries_.find(path);
  return at == entries_.end() ? nullptr : at->second.bytes;
}

void ManifestShelf::remove(const std::filesystem::path& path) {
  const std::lock_guard lock(mutex_);
  const auto at = entries_.find(path);
  if (at == entries_.end()) return;
  if (at->second.bytes) bytes_ -= at->second.bytes->size();
  entries_.erase(at);
}

void ManifestShelf::forgetDecoded() {
  const std::lock_guard lock(mutex_);
  for (auto at = entries_.begin(); at != entries_.end();) {
    at->second.decoded.reset();
    at = at->second.bytes ? std::next(at) : entries_.erase(at);
  }
}

bool ManifestShelf::fits(const std::filesystem::path& path, uint64_t bytes) const {
  const std::lock_guard lock(mutex_);
  const auto at = entries_.find(path);
  const uint64_t replaced = at != entries_.end() && at->second.bytes ? at->second.bytes->size() : 0;
  return bytes_ - replaced + bytes <= budget_;
}

uint64_t ManifestShelf::bytes() const {
  const std::lock_guard lock(mutex_);
  return bytes_;
}

bool WorkDirectory::has(const std::filesystem::path& path) const {
  return (shelf_ && shelf_->find(path)) || std::filesystem::exists(path);
}

void WorkDirectory::commit(const ManifestWriter& manifest, const std::filesystem::path& path,
                           std::string_view kind) const {
  // Sealed in memory only for a shelf that keeps it; the rest goes to its file part by part.
  if (shelf_) {
    if (shelf_->fits(path, manifest.sealedBytes(kind))) {
      std::string bytes = manifest.sealed(kind);
      if (shelf_->put(path, bytes)) return;
    } else {
      shelf_->remove(path);
    }
  }
  manifest.commit(path, kind);
}

ManifestReader WorkDirectory::read(const std::filesystem::path& path, std::string_view kind) const {
  if (shelf_)
    if (std::shared_ptr<const std::string> kept = shelf_->find(path))
      return ManifestReader(path, std::move(kept), kind);
  return ManifestReader(path, kind);
}

void WorkDirectory::remove(const std::filesystem::path& path) const {
  if (shelf_) shelf_->remove(path);
  std::filesystem::remove(path);
}

}  // namespace facetree
