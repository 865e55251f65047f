// TemporaryFile (facetree/storage.h): an unnamed temporary file, O_TMPFILE where the file system has
// it, else a name removed at once; reads and writes at offsets, so that threads share no position.
#include "facetree/storage.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>
#include <utility>

#include "facetree/error.h"

namespace facetree {

int createUnnamedFile(const std::filesystem::path& dir, const char* prefix) {
  int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (fd < 0) {
    std::string name = (dir / (std::string(prefix) + "XXXXXX")).string();
    fd = ::mkostemp(name.data(), O_CLOEXEC);
    if (fd >= 0) ::unlink(name.c_str());
  }
  return fd;
}

TemporaryFile::TemporaryFile(const std::filesystem::path& dir, std::string owner)
    : dir_(dir.empty() ? std::filesystem::temp_directory_path() : dir), owner_(std::move(owner)) {
  fd_ = createUnnamedFile(dir_, "facetree-");
  if (fd_ < 0) throw Error(ErrorCategory::Output, message("cannot create a temporary file", errno));
}

TemporaryFile::~TemporaryFile() {
  ::close(fd_);
}

std::string TemporaryFile::message(const char* what, int error) const {
  return (owner_.empty() ? "" : owner_ + ": ") + what + " in " + dir_.string() + ": " + std::strerror(error);
}

void TemporaryFile::write(uint64_t offset, const void* data, uint64_t bytes) {
  const auto* p = static_cast<const char*>(data);
  for (uint64_t done = 0; done < bytes;) {
    const ssize_t n = ::pwrite(fd_, p + done, bytes - done, static_cast<off_t>(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int error = n < 0 ? errno : ENOSPC;
      throw Error(error == ENOSPC || error == EDQUOT ? ErrorCategory::Resource : ErrorCategory::Output,
                  message("cannot write a temporary file", error));
    }
    done += static_cast<uint64_t>(n);
  }
}

void TemporaryFile::read(uint64_t offset, void* data, uint64_t bytes) const {
  auto* p = static_cast<char*>(data);
  for (uint64_t done = 0; done < bytes;) {
    const ssize_t n = ::pread(fd_, p + done, bytes - done, static_cast<off_t>(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw Error(ErrorCategory::Output, message("cannot read a temporary file", n < 0 ? errno : EIO));
    done += static_cast<uint64_t>(n);
  }
}

}  // namespace facetree
