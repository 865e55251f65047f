// The manifests of the stages run as tasks (docs/out_of_core.md): what a task hands on, as bytes
// under a name in its work directory. Tasks in processes of their own (Slurm, Dask, the stage
// commands) hand them on as files that appear under their names only once complete; the tasks of
// one process hand them on in its memory (a ManifestShelf), with no file between; a reader checks
// either alike (the manifest's format: facetree/storage.h). Internal to grid/.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>

#include "facetree/storage.h"

namespace facetree {

// A run's manifests kept in this process's memory, by the paths they would have as files, up to a
// budget of bytes: one that does not fit goes to its file (a count task's bins of a shuffled mesh
// reach a megabyte and more, which the tasks' memory plan does not hold). And what the tasks
// decode of a manifest once for all of them (the grid's owner table, 8 MiB a copy), wherever it
// is kept, as long as the shelf holds its name. Safe to use from the tasks' threads at once.
class ManifestShelf {
 public:
  explicit ManifestShelf(uint64_t budget) : budget_(budget) {}
  // Keeps `bytes` (taking them) as the manifest at `path` if they fit; false if not, keeping
  // nothing under `path` and leaving `bytes` to be written as its file.
  bool put(const std::filesystem::path& path, std::string& bytes);
  // Whether `bytes` would fit in place of what it keeps at `path`.
  bool fits(const std::filesystem::path& path, uint64_t bytes) const;
  std::shared_ptr<const std::string> find(const std::filesystem::path& path) const;  // null if not kept
  void remove(const std::filesystem::path& path);
  void forgetDecoded();  // what was decoded (its users keep theirs); the manifests stay
  uint64_t bytes() const;
  template <class T>
  std::shared_ptr<const T> decoded(const std::filesystem::path& path, const std::function<T()>& decode) {
    {
      const std::lock_guard lock(mutex_);
      const auto at = entries_.find(path);
      if (at != entries_.end() && at->second.decoded)
        return std::static_pointer_cast<const T>(at->second.decoded);
    }
    // Decoded unlocked (it reads the manifest): of two tasks that decode it at once, the first kept
    // is both's.
    auto made = std::make_shared<const T>(decode());
    const std::lock_guard lock(mutex_);
    Entry& entry = entries_[path];
    if (!entry.decoded) entry.decoded = made;
    return std::static_pointer_cast<const T>(entry.decoded);
  }

 private:
  struct Entry {
    std::shared_ptr<const std::string> bytes;  // null: the manifest is its file
    std::shared_ptr<const void> decoded;
  };
  mutable std::mutex mutex_;
  std::map<std::filesystem::path, Entry> entries_;
  uint64_t budget_, bytes_ = 0;
};

// The work directory of a run's tasks: where their spills go, and where their manifests are handed
// on: its files, or with a shelf in this process's memory first. A path converts to a directory of
// files.
class WorkDirectory {
 public:
  // Implicit: the stage commands, Slurm and Dask name a directory, whose manifests are files.
  WorkDirectory(std::filesystem::path path) : path_(std::move(path)) {}
  WorkDirectory(std::filesystem::path path, ManifestShelf& shelf) : path_(std::move(path)), shelf_(&shelf) {}
  const std::filesystem::path& path() const { return path_; }
  std::string string() const { return path_.string(); }
  std::filesystem::path operator/(const std::filesystem::path& name) const { return path_ / name; }

  // The manifest at `path` (a path of this directory): on the shelf, else its file.
  bool has(const std::filesystem::path& path) const;
  void commit(const ManifestWriter& manifest, const std::filesystem::path& path, std::string_view kind) const;
  ManifestReader read(const std::filesystem::path& path, std::string_view kind) const;
  void remove(const std::filesystem::path& path) const;
  // What every reader decodes alike of the manifest at `path`: once for the shelf's process, else
  // for each.
  template <class T>
  std::shared_ptr<const T> decoded(const std::filesystem::path& path,
                                   const std::function<T()>& decode) const {
    return shelf_ ? shelf_->decoded<T>(path, decode) : std::make_shared<const T>(decode());
  }
  void forgetDecoded() const {
    if (shelf_) shelf_->forgetDecoded();
  }

 private:
  std::filesystem::path path_;
  ManifestShelf* shelf_ = nullptr;
};

}  // namespace facetree
