// TemporaryFile (facetree/io.h): an unnamed temporary file, O_TMPFILE where the file system has
// it, else a name removed at once; reads and writes at offsets, so that threads share no position.
#include "files/temporary_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "facetree/error.h"

namespace facetree::fch {

int createUnnamedFile(const std::filesystem::path& dir, const char* prefix) {
  int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (fd < 0) {
    std::string name = (dir / (std::string(prefix) + "XXXXXX")).string();
    fd = ::mkostemp(name.data(), O_CLOEXEC);
    if (fd >= 0) ::unlink(name.c_str());
  }
  return fd;
}

}  // namespace facetree::fch

namespace facetree {

TemporaryFile::TemporaryFile(const std::filesystem::path& dir)
    : dir_(dir.empty() ? std::filesystem::temp_directory_path() : dir) {
  fd_ = fch::createUnnamedFile(dir_, "facetree-reader-");
  if (fd_ < 0)
    throw Error(ErrorCategory::Output,
                "cannot create a temporary file in " + dir_.string() + ": " + std::strerror(errno));
}

TemporaryFile::~TemporaryFile() {
  ::close(fd_);
}

void TemporaryFile::write(uint64_t offset, const void* data, uint64_t bytes) {
  const auto* p = static_cast<const char*>(data);
  for (uint64_t done = 0; done < bytes;) {
    const ssize_t n = ::pwrite(fd_, p + done, bytes - done, static_cast<off_t>(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int error = n < 0 ? errno : ENOSPC;
      throw Error(error == ENOSPC || error == EDQUOT ? ErrorCategory::Resource : ErrorCategory::Output,
                  "cannot write a temporary file in " + dir_.string() + ": " + std::strerror(error));
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
      throw Error(ErrorCategory::Output, "cannot read a temporary file in " + dir_.string() + ": " +
                                             std::strerror(n < 0 ? errno : EIO));
    done += static_cast<uint64_t>(n);
  }
}

}  // namespace facetree
