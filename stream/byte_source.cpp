// The byte sources of the readers (byte_source.h): a file descriptor, standard input and zstd
// decompression, behind one buffered reader.
#include "byte_source.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "read_error.h"

namespace facetree::stream_detail {
namespace {
// Single read(2) calls are capped: Linux transfers at most ~2 GiB per call anyway.
constexpr size_t kMaxReadCall = size_t{1} << 30;
}  // namespace

std::unique_ptr<FdSource> FdSource::open(const std::string& path, const std::string& name) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throwReadError(name, Place::byte(0), "cannot open: " + systemErrorText(errno));
  auto source = std::make_unique<FdSource>(fd, name, true);
  struct stat st {};
  if (::fstat(fd, &st) != 0) throwReadError(name, Place::byte(0), "cannot stat: " + systemErrorText(errno));
  if (S_ISDIR(st.st_mode)) throwReadError(name, Place::byte(0), "is a directory");
  if (S_ISREG(st.st_mode)) {
    source->size_ = static_cast<uint64_t>(st.st_size);
    ::posix_fadvise(fd, 0, 0, POSIX_FADV_SEQUENTIAL);
  }
  return source;
}

FdSource::FdSource(int fd, std::string name, bool owned) : fd_(fd), owned_(owned), name_(std::move(name)) {}

FdSource::~FdSource() {
  if (owned_) ::close(fd_);
}

size_t FdSource::read(char* dst, size_t size) {
  size = std::min(size, kMaxReadCall);
  for (;;) {
    const ssize_t got = ::read(fd_, dst, size);
    if (got >= 0) {
      offset_ += static_cast<uint64_t>(got);
      return static_cast<size_t>(got);
    }
    if (errno != EINTR) throwReadError(name_, Place::byte(offset_), "read error: " + systemErrorText(errno));
  }
}

uint64_t FdSource::skip(uint64_t size) {
  // Only regular files opened by path seek; descriptors handed in (stdin) are read through.
  if (!size_ || offset_ >= *size_) return 0;
  const uint64_t target = offset_ + std::min(size, *size_ - offset_);
  if (::lseek(fd_, static_cast<off_t>(target), SEEK_SET) != static_cast<off_t>(target)) return 0;
  const uint64_t skipped = target - offset_;
  offset_ = target;
  return skipped;
}

InputBuffer::InputBuffer(std::unique_ptr<ByteSource> source, size_t capacity)
    : source_(std::move(source)),
      buffer_(std::make_unique_for_overwrite<char[]>(std::max<size_t>(capacity, 1))),
      capacity_(std::max<size_t>(capacity, 1)) {}

void InputBuffer::reserveContiguous(size_t count) {
  // Move the unread tail to the front, growing the buffer if `count` does not fit.
  const size_t unread = available();
  if (count > capacity_) {
    const size_t newCapacity = std::max(count, capacity_ * 2);
    auto grown = std::make_unique_for_overwrite<char[]>(newCapacity);
    std::memcpy(grown.get(), data(), unread);
    buffer_ = std::move(grown);
    capacity_ = newCapacity;
  } else if (begin_ > 0) {
    std::memmove(buffer_.get(), data(), unread);
  }
  bufferOffset_ += begin_;
  begin_ = 0;
  end_ = unread;
}

size_t InputBuffer::fill(size_t count) {
  if (available() >= count || sourceEnded_) return available();
  if (capacity_ - begin_ < count) reserveContiguous(count);
  // Read as much as fits to amortise calls, but return as soon as `count` bytes are there.
  while (available() < count) {
    const size_t got = source_->read(buffer_.get() + end_, capacity_ - end_);
    if (got == 0) {
      sourceEnded_ = true;
      break;
    }
    end_ += got;
  }
  return available();
}

uint64_t InputBuffer::skip(uint64_t count) {
  uint64_t skipped = std::min<uint64_t>(available(), count);
  consume(static_cast<size_t>(skipped));
  if (count - skipped > capacity_ && !sourceEnded_) {
    // Large skips (unused elements of huge files) seek instead of reading when possible.
    const uint64_t jumped = source_->skip(count - skipped);
    bufferOffset_ += end_ + jumped;
    begin_ = end_ = 0;
    skipped += jumped;
  }
  while (skipped < count) {
    if (available() == 0 && fill(1) == 0) break;
    const size_t step = static_cast<size_t>(std::min<uint64_t>(available(), count - skipped));
    consume(step);
    skipped += step;
  }
  return skipped;
}

bool InputBuffer::readLine(std::string_view& line, uint64_t& number, const std::string& name,
                           std::string_view what) {
  const auto tooLong = [&] {
    throwReadError(name, Place::line(number + 1),
                   std::string(what) + " longer than " + std::to_string(kMaxLineBytes) + " bytes");
  };
  size_t scanned = 0;
  for (;;) {
    const char* start = data();
    const auto* newline = static_cast<const char*>(std::memchr(start + scanned, '\n', available() - scanned));
    if (newline != nullptr) {
      size_t length = static_cast<size_t>(newline - start);
      if (length > kMaxLineBytes) tooLong();
      consume(length + 1);
      if (length > 0 && start[length - 1] == '\r') --length;
      line = std::string_view(start, length);
      ++number;
      return true;
    }
    scanned = available();
    if (scanned > kMaxLineBytes) tooLong();
    // Ask for one byte more than we have; the buffer grows at most to kMaxLineBytes + 2.
    if (fill(scanned + 1) == scanned) {
      if (scanned == 0) return false;
      line = std::string_view(data(), scanned);
      consume(scanned);
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
      ++number;
      return true;
    }
  }
}

}  // namespace facetree::stream_detail
