// Internal: raw byte sources (file descriptor, zstd decompression) and the buffered reader
// every format parser reads from. Offsets are 64-bit throughout (files over 4 GiB).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

namespace facetree::stream_detail {

// Longest accepted text line (OBJ, ASCII STL/PLY, PLY header).
inline constexpr size_t kMaxLineBytes = size_t{1} << 20;

// A forward-only stream of bytes. read() returns 0 only at the end; failures throw Error (Input).
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  // Reads up to `size` bytes into `dst`; returns 0 only at the end of the stream.
  virtual size_t read(char* dst, size_t size) = 0;
  // Total length of the stream when known in advance (regular files), else nullopt.
  virtual std::optional<uint64_t> size() const = 0;
  // Bytes taken from the underlying file when this source decompresses, else 0.
  virtual uint64_t compressedBytesRead() const { return 0; }
  // Skips up to `size` bytes without reading them if the source can (seekable files);
  // returns how many were skipped, 0 when the caller has to read through instead.
  virtual uint64_t skip(uint64_t /*size*/) { return 0; }
};

// Reads a file descriptor with read(2). Owns (closes) it unless it is standard input.
class FdSource final : public ByteSource {
 public:
  // Opens `path` read-only; throws Error (Input) "NAME: byte 0: cannot open: ..." on failure.
  static std::unique_ptr<FdSource> open(const std::string& path, const std::string& name);
  // Wraps an already open descriptor; the size is never used (treated like a pipe).
  FdSource(int fd, std::string name, bool owned);
  ~FdSource() override;
  FdSource(const FdSource&) = delete;
  FdSource& operator=(const FdSource&) = delete;

  size_t read(char* dst, size_t size) override;
  std::optional<uint64_t> size() const override { return size_; }
  uint64_t skip(uint64_t size) override;

 private:
  int fd_;
  bool owned_;
  std::string name_;
  uint64_t offset_ = 0;
  std::optional<uint64_t> size_;
};

// A buffer in front of a ByteSource. Parsers look at data()/available() and consume();
// fill(n) refills so that n bytes are contiguous. The buffer holds at least `capacity`
// bytes and grows only when a caller asks for a larger contiguous run (bounded by callers).
class InputBuffer {
 public:
  InputBuffer(std::unique_ptr<ByteSource> source, size_t capacity);

  const char* data() const { return buffer_.get() + begin_; }
  size_t available() const { return end_ - begin_; }
  void consume(size_t count) { begin_ += count; }
  // Absolute offset of data() in the stream.
  uint64_t offset() const { return bufferOffset_ + begin_; }
  // Makes at least `count` bytes available unless the stream ends first; returns available().
  size_t fill(size_t count);
  // Reads and drops `count` bytes; returns how many were skipped (less only at the end).
  uint64_t skip(uint64_t count);
  // True when nothing is buffered and the source is exhausted.
  bool atEnd() { return fill(1) == 0; }

  // The next line without its terminator ("\n" or "\r\n"; a lone "\r" is kept), counted in
  // `number`. Returns false at the end of the stream. The view lives until the next call on this
  // buffer. A line longer than kMaxLineBytes is an error of `name` there: "WHAT longer than N bytes".
  bool readLine(std::string_view& line, uint64_t& number, const std::string& name,
                std::string_view what = "line");

  const ByteSource& source() const { return *source_; }
  std::optional<uint64_t> size() const { return source_->size(); }

 private:
  void reserveContiguous(size_t count);

  std::unique_ptr<ByteSource> source_;
  std::unique_ptr<char[]> buffer_;
  size_t capacity_;
  size_t begin_ = 0;
  size_t end_ = 0;
  uint64_t bufferOffset_ = 0;
  bool sourceEnded_ = false;
};

// Decompresses a zstd stream (one or more concatenated frames, skippable frames allowed)
// read from `raw`. Errors name the offset in the decompressed output.
std::unique_ptr<ByteSource> makeZstdSource(std::unique_ptr<InputBuffer> raw, std::string name);

}  // namespace facetree::stream_detail
