// The manifests of the stages run as tasks (docs/out_of_core.md): what a task hands on, as bytes
// under a name in its work directory. Tasks in processes of their own (Slurm, Dask, the stage
// commands) hand them on as files that appear under their names only once complete; the tasks of
// one process hand them on in its memory (a ManifestShelf), with no file between. Internal to grid/.
//
// A manifest is a magic, its kind, the fields little-endian as this machine lays them out (the
// tasks of one job run the same build), and an XXH64 of everything before it, wherever it is kept:
// a reader checks it alike.
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace facetree {

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
  // serves both (a string goes as its bytes).
  template <class T>
  void field(const T& value) {
    if constexpr (std::is_same_v<T, std::string>)
      putBytes(value);
    else
      put(value);
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
  // Every field taken: the manifest ends here.
  void finish();

 private:
  void check(std::string_view kind);
  const char* need(uint64_t bytes);
  [[noreturn]] void fail(const std::string& why) const;
  std::filesystem::path path_;
  std::shared_ptr<const std::string> bytes_;
  size_t at_ = 0, end_ = 0;  // the fields: [at_, end_), the checksum past them
};

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
