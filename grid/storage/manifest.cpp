// Manifests of the stages run as tasks (storage/manifest.h).
#include "storage/manifest.h"

#include <fcntl.h>
#include <unistd.h>
#include <xxhash.h>

#include <cerrno>
#include <fstream>

#include "facetree/error.h"

namespace facetree {
namespace {

constexpr std::string_view kMagic = "facetree stage manifest 1\n";

}  // namespace

void ManifestWriter::commit(const std::filesystem::path& path, std::string_view kind) const {
  std::string out(kMagic);
  out += kind;
  out += '\n';
  out += bytes_;
  const uint64_t sum = XXH64(out.data(), out.size(), 0);
  out.append(reinterpret_cast<const char*>(&sum), sizeof sum);
  std::filesystem::path partial = path;
  partial += ".partial";
  const auto fail = [&](int error) {
    ::unlink(partial.c_str());
    throw Error(ErrorCategory::Output, path.string() + ": cannot write: " + std::strerror(error));
  };
  const int fd = ::open(partial.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) fail(errno);
  for (size_t done = 0; done < out.size();) {
    const ssize_t got = ::write(fd, out.data() + done, out.size() - done);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) {
      const int error = got < 0 ? errno : ENOSPC;
      ::close(fd);
      fail(error);
    }
    done += static_cast<size_t>(got);
  }
  if (::fsync(fd) != 0) {
    const int error = errno;
    ::close(fd);
    fail(error);
  }
  ::close(fd);
  if (::rename(partial.c_str(), path.c_str()) != 0) fail(errno);
}

ManifestReader::ManifestReader(const std::filesystem::path& path, std::string_view kind) : path_(path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) fail(std::string("cannot open: ") + std::strerror(errno));
  bytes_.resize(static_cast<size_t>(in.tellg()));
  in.seekg(0);
  if (!in.read(bytes_.data(), static_cast<std::streamsize>(bytes_.size()))) fail("cannot read it whole");
  const std::string head = std::string(kMagic) + std::string(kind) + "\n";
  if (bytes_.size() < head.size() + sizeof(uint64_t) || bytes_.compare(0, kMagic.size(), kMagic) != 0)
    fail("not a facetree stage manifest");
  if (bytes_.compare(0, head.size(), head) != 0) fail("not a manifest of " + std::string(kind));
  uint64_t sum = 0;
  std::memcpy(&sum, bytes_.data() + bytes_.size() - sizeof sum, sizeof sum);
  bytes_.resize(bytes_.size() - sizeof sum);
  if (XXH64(bytes_.data(), bytes_.size(), 0) != sum) fail("checksum mismatch (changed since it was written)");
  at_ = head.size();
}

const char* ManifestReader::need(uint64_t bytes) {
  if (bytes > bytes_.size() - at_) fail("cut short");
  const char* p = bytes_.data() + at_;
  at_ += static_cast<size_t>(bytes);
  return p;
}

void ManifestReader::finish() {
  if (at_ != bytes_.size()) fail("bytes past its last field");
}

void ManifestReader::fail(const std::string& why) const {
  throw Error(ErrorCategory::Input, path_.string() + ": " + why);
}

}  // namespace facetree
