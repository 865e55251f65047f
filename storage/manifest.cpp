// Manifests: what a task hands on, sealed with a checksum (facetree/storage.h).
#include <fcntl.h>
#include <unistd.h>
#include <xxhash.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <functional>
#include <memory>
#include <new>
#include <string>

#include "facetree/error.h"
#include "facetree/storage.h"

namespace facetree {
namespace {

constexpr std::string_view kMagic = "facetree stage manifest 1\n";

// Fields smaller than this go into the last chunk; larger ones are chunks of their own.
constexpr size_t kChunkBytes = size_t{1} << 16;

}  // namespace

void ManifestWriter::append(std::string_view bytes) {
  if (chunks_.empty() || bytes.size() >= kChunkBytes || chunks_.back().size() + bytes.size() > kChunkBytes)
    chunks_.emplace_back().reserve(bytes.size() >= kChunkBytes ? bytes.size() : kChunkBytes);
  chunks_.back().append(bytes);
  bytes_ += bytes.size();
}

uint64_t ManifestWriter::sealedBytes(std::string_view kind) const {
  return kMagic.size() + kind.size() + 1 + bytes_ + sizeof(uint64_t);
}

namespace {

// The manifest's parts in order: its head (magic, kind), its chunks, then its checksum.
template <class F>
void sealedParts(std::string_view kind, const std::vector<std::string>& chunks, const F& part) {
  const std::string head = std::string(kMagic) + std::string(kind) + "\n";
  const std::unique_ptr<XXH64_state_t, decltype(&XXH64_freeState)> state(XXH64_createState(),
                                                                         &XXH64_freeState);
  if (!state) throw std::bad_alloc();
  XXH64_reset(state.get(), 0);
  XXH64_update(state.get(), head.data(), head.size());
  part(std::string_view(head));
  for (const std::string& chunk : chunks) {
    XXH64_update(state.get(), chunk.data(), chunk.size());
    part(std::string_view(chunk));
  }
  const uint64_t sum = XXH64_digest(state.get());
  part(std::string_view(reinterpret_cast<const char*>(&sum), sizeof sum));
}

}  // namespace

std::string ManifestWriter::sealed(std::string_view kind) const {
  std::string out;
  out.reserve(sealedBytes(kind));
  sealedParts(kind, chunks_, [&](std::string_view part) { out.append(part); });
  return out;
}

namespace {

// Writes the parts of sealed manifest bytes as the file `path` (as PATH.partial, synced, renamed).
void writeSealed(const std::filesystem::path& path,
                 const std::function<void(const std::function<void(std::string_view)>&)>& parts) {
  std::filesystem::path partial = path;
  partial += ".partial";
  const auto fail = [&](int error) {
    ::unlink(partial.c_str());
    throw Error(ErrorCategory::Output, path.string() + ": cannot write: " + std::strerror(error));
  };
  const int fd = ::open(partial.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) fail(errno);
  parts([&](std::string_view out) {
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
  });
  if (::fsync(fd) != 0) {
    const int error = errno;
    ::close(fd);
    fail(error);
  }
  ::close(fd);
  if (::rename(partial.c_str(), path.c_str()) != 0) fail(errno);
}

}  // namespace

void ManifestWriter::commit(const std::filesystem::path& path, std::string_view kind) const {
  writeSealed(path, [&](const auto& part) { sealedParts(kind, chunks_, part); });
}

ManifestReader::ManifestReader(const std::filesystem::path& path, std::string_view kind) : path_(path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) fail(std::string("cannot open: ") + std::strerror(errno));
  auto bytes = std::make_shared<std::string>(static_cast<size_t>(in.tellg()), '\0');
  in.seekg(0);
  if (!in.read(bytes->data(), static_cast<std::streamsize>(bytes->size()))) fail("cannot read it whole");
  bytes_ = std::move(bytes);
  check(kind);
}

ManifestReader::ManifestReader(const std::filesystem::path& path, std::shared_ptr<const std::string> bytes,
                               std::string_view kind)
    : path_(path), bytes_(std::move(bytes)) {
  if (!bytes_) fail("cannot open: " + std::string(std::strerror(ENOENT)));
  check(kind);
}

void ManifestReader::check(std::string_view kind) {
  const std::string& bytes = *bytes_;
  const std::string head = std::string(kMagic) + std::string(kind) + "\n";
  if (bytes.size() < head.size() + sizeof(uint64_t) || bytes.compare(0, kMagic.size(), kMagic) != 0)
    fail("not a facetree stage manifest");
  if (bytes.compare(0, head.size(), head) != 0) fail("not a manifest of " + std::string(kind));
  end_ = bytes.size() - sizeof(uint64_t);
  uint64_t sum = 0;
  std::memcpy(&sum, bytes.data() + end_, sizeof sum);
  if (XXH64(bytes.data(), end_, 0) != sum) fail("checksum mismatch (changed since it was written)");
  at_ = head.size();
}

const char* ManifestReader::need(uint64_t bytes) {
  if (bytes > end_ - at_) fail("cut short");
  const char* p = bytes_->data() + at_;
  at_ += static_cast<size_t>(bytes);
  return p;
}

void ManifestReader::finish() {
  if (at_ != end_) fail("bytes past its last field");
}

void ManifestReader::fail(const std::string& why) const {
  throw Error(ErrorCategory::Input, path_.string() + ": " + why);
}

}  // namespace facetree
