// An output file that appears under its final name only when complete: data goes to a
// temporary name beside the target and is renamed on commit(); destroyed uncommitted, the
// temporary file is removed. Writes are buffered; every failure throws Error (Output) naming the file.
//
// A stream is written in place instead: standard output ("-"), and a target that exists and is
// not a regular file (a named pipe, a device, a socket). Renaming a temporary over a pipe would
// replace it with a regular file while its reader waits forever; a stream takes bytes in order
// only, so writeAt() is refused, and a failed write fails the run as on standard output.
#pragma once

#include <cstdio>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace facetree {

class OutputFile {
 public:
  // "-" writes to standard output (no temporary, nothing to remove).
  explicit OutputFile(const std::filesystem::path& path);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  void write(const void* data, size_t bytes);
  void write(std::string_view text) { write(text.data(), text.size()); }
  // Overwrites bytes already written (a header whose contents are known last); the next write
  // appends at the end again. Not for streams (std::logic_error).
  void writeAt(uint64_t offset, std::string_view bytes);
  uint64_t bytesWritten() const { return written_; }
  bool isStream() const { return stream_; }
  // Flushes, syncs and renames to the final name (a stream: flushes and closes).
  void commit();
  const std::filesystem::path& path() const { return path_; }

 private:
  [[noreturn]] void fail(const char* what) const;
  void startWriteback();  // hands the bytes written since the last call to the disk
  std::filesystem::path path_;
  std::filesystem::path temporary_;
  struct Closer {
    void operator()(std::FILE* f) const;
  };
  std::unique_ptr<std::FILE, Closer> file_;
  bool stream_ = false;
  bool committed_ = false;
  uint64_t written_ = 0;
  uint64_t handedToDisk_ = 0;  // bytes whose writeback has been started
};

}  // namespace facetree
