// zstd decompression as a ByteSource: ZSTD_decompressStream over a raw InputBuffer, so the
// compressed file is never held whole. Concatenated frames and skippable frames are accepted;
// anything else after a complete frame, or a stream ending inside a frame, is an error.
#include <zstd.h>

#include <cstring>

#include "byte_source.h"
#include "read_error.h"

namespace facetree::stream_detail {
namespace {

constexpr uint32_t kZstdFrameMagic = 0xFD2FB528u;
constexpr uint32_t kSkippableMagicMask = 0xFFFFFFF0u;
constexpr uint32_t kSkippableMagic = 0x184D2A50u;
constexpr size_t kMagicBytes = 4;

struct DctxDeleter {
  void operator()(ZSTD_DCtx* context) const { ZSTD_freeDCtx(context); }
};

class ZstdSource final : public ByteSource {
 public:
  ZstdSource(std::unique_ptr<InputBuffer> raw, std::string name)
      : raw_(std::move(raw)), name_(std::move(name)), context_(ZSTD_createDCtx()) {
    if (!context_) throw std::bad_alloc();
  }

  size_t read(char* dst, size_t size) override {
    ZSTD_outBuffer out{dst, size, 0};
    while (out.pos < out.size) {
      if (raw_->available() == 0) raw_->fill(1);
      if (frameComplete_) {
        if (raw_->available() == 0) break;  // clean end after the last frame
        checkNextFrameMagic();
      }
      ZSTD_inBuffer in{raw_->data(), raw_->available(), 0};
      const size_t producedBefore = out.pos;
      const size_t result = ZSTD_decompressStream(context_.get(), &out, &in);
      raw_->consume(in.pos);
      if (ZSTD_isError(result)) fail(std::string("zstd: ") + lowerCase(ZSTD_getErrorName(result)));
      frameComplete_ = result == 0;
      produced_ += out.pos - producedBefore;
      // No progress with all input consumed: the stream ended inside a frame.
      if (!frameComplete_ && in.pos == 0 && out.pos == producedBefore && raw_->available() == 0)
        fail("truncated zstd stream");
    }
    return out.pos;
  }

  std::optional<uint64_t> size() const override { return std::nullopt; }
  uint64_t compressedBytesRead() const override { return raw_->offset(); }

 private:
  [[noreturn]] void fail(const std::string& reason) const {
    throwReadError(name_, Place::byte(produced_), reason);
  }

  static std::string lowerCase(std::string text) {
    for (char& c : text) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
    return text;
  }

  void checkNextFrameMagic() {
    uint32_t magic = 0;
    if (raw_->fill(kMagicBytes) >= kMagicBytes) {
      unsigned char bytes[kMagicBytes];
      std::memcpy(bytes, raw_->data(), kMagicBytes);
      magic =
          uint32_t{bytes[0]} | uint32_t{bytes[1]} << 8 | uint32_t{bytes[2]} << 16 | uint32_t{bytes[3]} << 24;
    }
    if (magic != kZstdFrameMagic && (magic & kSkippableMagicMask) != kSkippableMagic)
      fail("unexpected data after zstd frame (compressed byte " + std::to_string(raw_->offset()) + ")");
  }

  std::unique_ptr<InputBuffer> raw_;
  std::string name_;
  std::unique_ptr<ZSTD_DCtx, DctxDeleter> context_;
  bool frameComplete_ = false;
  uint64_t produced_ = 0;
};

}  // namespace

std::unique_ptr<ByteSource> makeZstdSource(std::unique_ptr<InputBuffer> raw, std::string name) {
  return std::make_unique<ZstdSource>(std::move(raw), std::move(name));
}

}  // namespace facetree::stream_detail
