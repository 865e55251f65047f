// Internal to stream/: a file read at given offsets (pread) by the readers of ranges, which many
// processes open at once, each for its own part of the file.
#pragma once

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <string>

#include "read_error.h"

namespace facetree::stream_detail {

// A descriptor closed on every path out; errors name the file and the byte.
class PositionedFile {
 public:
  explicit PositionedFile(const std::string& name)
      : name_(name), fd_(::open(name.c_str(), O_RDONLY | O_CLOEXEC)) {
    if (fd_ < 0) throwReadError(name_, Place::byte(0), "cannot open: " + systemErrorText(errno));
  }
  ~PositionedFile() { ::close(fd_); }
  PositionedFile(const PositionedFile&) = delete;
  PositionedFile& operator=(const PositionedFile&) = delete;

  // Exactly `size` bytes at `offset`; a short file is an error naming `what` there.
  void read(uint64_t offset, char* out, size_t size, const std::string& what) const {
    size_t done = 0;
    while (done < size) {
      const ssize_t got = ::pread(fd_, out + done, size - done, static_cast<off_t>(offset + done));
      if (got > 0) {
        done += static_cast<size_t>(got);
      } else if (got == 0) {
        throwReadError(name_, Place::byte(offset + done), "unexpected end of data in " + what);
      } else if (errno != EINTR) {
        throwReadError(name_, Place::byte(offset + done), "read error: " + systemErrorText(errno));
      }
    }
  }

 private:
  std::string name_;
  int fd_;
};

}  // namespace facetree::stream_detail
