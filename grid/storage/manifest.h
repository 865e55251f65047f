// The manifests of the stages run as tasks (docs/out_of_core.md): what a task hands on, as bytes
// in a file of the work directory that appears under its name only once complete. Internal to grid/.
//
// A manifest is a magic, its kind, the fields little-endian as this machine lays them out (the
// tasks of one job run the same build), and an XXH64 of everything before it.
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
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
    bytes_.append(reinterpret_cast<const char*>(&value), sizeof value);
  }
  void putBytes(std::string_view bytes) {
    put(uint64_t{bytes.size()});
    bytes_.append(bytes);
  }
  template <class T>
  void putVector(const std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    putBytes({reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T)});
  }
  // Writes `path` (as PATH.partial, synced, renamed): Error (Output) naming it when it cannot.
  void commit(const std::filesystem::path& path, std::string_view kind) const;

 private:
  std::string bytes_;
};

class ManifestReader {
 public:
  // Reads and checks `path`; Error (Input) "PATH: REASON" when it is missing, cut short, of
  // another kind or changed since it was written.
  ManifestReader(const std::filesystem::path& path, std::string_view kind);
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
  // Every field taken: the manifest ends here.
  void finish();

 private:
  const char* need(uint64_t bytes);
  [[noreturn]] void fail(const std::string& why) const;
  std::filesystem::path path_;
  std::string bytes_;
  size_t at_ = 0;
};

}  // namespace facetree
