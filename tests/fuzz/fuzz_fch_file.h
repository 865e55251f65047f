// Shared by the cluster-file fuzz targets: a memfd the readers open by path, and the checksums of
// docs/FORMAT.md recomputed so that mutations reach the field checks and the frame decoders.
#pragma once

#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "io/format/fch_format.h"

namespace facetree::fuzz {

[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "fuzz check failed: %s\n", what.c_str());
  std::abort();
}

// One memfd for the whole run, rewritten for every input.
class MemFile {
 public:
  MemFile() : fd_(::memfd_create("fuzz.fch", MFD_CLOEXEC)) {
    if (fd_ < 0) fail("memfd_create failed");
    path_ = "/proc/self/fd/" + std::to_string(fd_);
  }
  ~MemFile() { ::close(fd_); }
  const std::string& write(const uint8_t* data, size_t size) {
    if (::ftruncate(fd_, 0) != 0) fail("ftruncate failed");
    size_t done = 0;
    while (done < size) {
      const ssize_t n = ::pwrite(fd_, data + done, size - done, static_cast<off_t>(done));
      if (n <= 0) fail("pwrite failed");
      done += static_cast<size_t>(n);
    }
    return path_;
  }

 private:
  int fd_;
  std::string path_;
};

inline uint64_t load64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = v << 8 | p[i];
  return v;
}
inline uint32_t load32(const uint8_t* p) {
  return uint32_t{p[0]} | uint32_t{p[1]} << 8 | uint32_t{p[2]} << 16 | uint32_t{p[3]} << 24;
}
inline void store64(uint8_t* p, uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}

// Recomputes the checksums of docs/FORMAT.md where the bytes they cover are present.
inline void fixChecksums(std::vector<uint8_t>& bytes) {
  if (bytes.size() < fch::kHeaderBytes || std::memcmp(bytes.data(), fch::kMagic, sizeof fch::kMagic) != 0)
    return;
  const uint64_t frames = load32(&bytes[56]);
  const uint64_t indexEnd = fch::kHeaderBytes + frames * fch::kIndexEntryBytes;
  if (indexEnd <= bytes.size()) {
    for (uint64_t i = 0; i < frames; ++i) {
      uint8_t* entry = &bytes[fch::kHeaderBytes + i * fch::kIndexEntryBytes];
      const uint64_t offset = load64(entry + 16);
      const uint64_t compressed = load32(entry + 24);
      if (offset <= bytes.size() && compressed <= bytes.size() - offset)
        store64(entry + 32, fch::xxh64(bytes.data() + offset, compressed));
    }
    store64(&bytes[120], fch::xxh64(bytes.data() + fch::kHeaderBytes, indexEnd - fch::kHeaderBytes));
  }
  store64(&bytes[fch::kHeaderChecksumOffset], fch::xxh64(bytes.data(), fch::kHeaderChecksumOffset));
}

inline void checkMessage(const char* what) {
  if (std::strchr(what, '\n') != nullptr) fail(std::string("error message spans lines: ") + what);
}

}  // namespace facetree::fuzz
