// Internal to io/: an unnamed temporary file that readers keep their overflow in (a pass's announced
// children, the face ranges of node frames for random access). Created where the system has unnamed
// files (O_TMPFILE), else named and removed at once: nothing is left behind, whatever ends the
// process. Reads and writes at offsets, so that threads do not share a file position.
#pragma once

#include <cstdint>
#include <filesystem>

namespace facetree::fch {

// A file no directory entry names, in `dir`: O_TMPFILE where the file system has it, else a name
// removed at once. Returns its descriptor, or -1 with errno set.
int createUnnamedFile(const std::filesystem::path& dir, const char* prefix);

class TemporaryFile {
 public:
  // `dir`: empty for the system's temporary directory. Throws Error (Output) when it cannot be made.
  explicit TemporaryFile(const std::filesystem::path& dir);
  ~TemporaryFile();
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;

  // Throw Error (Resource) when the disk is full, (Output) on other failures.
  void write(uint64_t offset, const void* data, uint64_t bytes);
  void read(uint64_t offset, void* data, uint64_t bytes) const;

 private:
  int fd_ = -1;
  std::filesystem::path dir_;
};

}  // namespace facetree::fch
