// One libFuzzer target per mesh format (fuzz_ply, fuzz_obj, fuzz_stl, fuzz_draco), chosen at
// compile time by FUZZ_FORMAT. The input is detected exactly as openMesh does (as a regular
// file of known size, and as a pipe without one); inputs detected as another format are
// left to that format's target, the rest is read to the end by fuzz_stream.h's drainTwice.
#include <cstddef>
#include <cstdint>

#include "fuzz_stream.h"
#include "stream/format_detect.h"
#include "stream/readers.h"

using namespace facetree;
using namespace facetree::stream_detail;

namespace {

#define FUZZ_PLY 1
#define FUZZ_OBJ 2
#define FUZZ_STL 3
#define FUZZ_DRACO 4

bool wanted(DetectedFormat format) {
#if FUZZ_FORMAT == FUZZ_PLY
  return format == DetectedFormat::Ply;
#elif FUZZ_FORMAT == FUZZ_OBJ
  return format == DetectedFormat::Obj;
#elif FUZZ_FORMAT == FUZZ_STL
  return format == DetectedFormat::StlAscii || format == DetectedFormat::StlBinary;
#elif FUZZ_FORMAT == FUZZ_DRACO
  return format == DetectedFormat::Draco;
#else
#error "FUZZ_FORMAT must be one of FUZZ_PLY, FUZZ_OBJ, FUZZ_STL, FUZZ_DRACO"
#endif
}

std::unique_ptr<TriangleReader> openDetected(std::unique_ptr<InputBuffer> input, DetectedFormat format) {
  MeshInfo info;
  info.name = "fuzz";
  return makeReader(format, std::move(input), std::move(info), fuzz::kWholeMeshLimitBytes);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  for (const bool sizeKnown : {true, false}) {
    // Detection only looks at the first 4 KiB and the size, not at the buffer size.
    auto probe = fuzz::memoryInput(data, size, sizeKnown, fuzz::kLargeBuffer);
    const DetectedFormat format = detectFormat(*probe, probe->size());
    if (!wanted(format)) continue;
    fuzz::drainTwice([&](size_t bufferBytes) {
      auto input = fuzz::memoryInput(data, size, sizeKnown, bufferBytes);
      // As openInput: detection peeks (fills 4 KiB) before the reader starts. Skipped for the
      // tiny buffer, which detection would grow to 4 KiB, so that the reader sees 7 bytes.
      if (bufferBytes == fuzz::kLargeBuffer && detectFormat(*input, input->size()) != format)
        fuzz::fail("detection is not repeatable");
      return openDetected(std::move(input), format);
    });
  }
  return 0;
}
