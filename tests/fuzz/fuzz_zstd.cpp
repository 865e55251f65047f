// fuzz_zstd: a zstd stream around any mesh format, opened as openMesh does (stream.cpp
// openInput) except that the decompressed stream is cut after kMaxDecompressedBytes, so that
// a decompression bomb reads as a truncated mesh instead of timing out.
#include <cstddef>
#include <cstdint>

#include "fuzz_stream.h"
#include "stream/format_detect.h"
#include "stream/readers.h"

using namespace facetree;
using namespace facetree::stream_detail;

namespace {

std::unique_ptr<TriangleReader> openZstd(const uint8_t* data, size_t size, size_t bufferBytes) {
  auto raw = fuzz::memoryInput(data, size, true, bufferBytes);
  if (detectFormat(*raw, raw->size()) != DetectedFormat::Zstd) return nullptr;
  auto decompressed = std::make_unique<fuzz::CappedSource>(makeZstdSource(std::move(raw), "fuzz"),
                                                           fuzz::kMaxDecompressedBytes);
  auto input = std::make_unique<InputBuffer>(std::move(decompressed), bufferBytes);
  MeshInfo info;
  info.name = "fuzz";
  info.zstdCompressed = true;
  const DetectedFormat format = detectFormat(*input, std::nullopt);
  if (auto reader = makeReader(format, std::move(input), std::move(info), fuzz::kWholeMeshLimitBytes))
    return reader;
  // openInput rejects Empty, Unknown and zstd-in-zstd with a Error (Input) too.
  throw Error(ErrorCategory::Input, "fuzz: byte 0: no mesh format inside zstd");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // zstd error offsets depend on how much output was asked for: compare outcomes, not messages.
  fuzz::drainTwice([&](size_t bufferBytes) { return openZstd(data, size, bufferBytes); },
                   /*exactErrors=*/false);
  return 0;
}
