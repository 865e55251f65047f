// Binary STL read in face ranges (facetree/stream.h): the count from the preamble, then any range
// of the 50-byte triangle records read with pread. Nothing is welded: each corner keeps its
// position and the caller gives vertex ids to distinct positions.
#include <algorithm>
#include <bit>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "byte_source.h"
#include "format_detect.h"
#include "positioned_file.h"
#include "vertex_store.h"

namespace facetree {
namespace {

constexpr uint64_t kPreambleBytes = 84;  // 80 bytes of header, the uint32 triangle count
constexpr uint64_t kRecordBytes = 50;    // normal, 3 corners (12 floats), uint16 attribute
constexpr size_t kFirstCornerOffset = 12;

uint32_t loadLittleEndian32(const char* bytes) {
  uint32_t bits;
  std::memcpy(&bits, bytes, sizeof bits);
  if constexpr (std::endian::native == std::endian::big) bits = __builtin_bswap32(bits);
  return bits;
}

}  // namespace

std::optional<StlFaceRanges> stlFaceRanges(const std::filesystem::path& path) {
  using namespace stream_detail;
  const std::string name = path.string();
  auto source = FdSource::open(name, name);
  const std::optional<uint64_t> size = source->size();
  InputBuffer input(std::move(source), size_t{64} << 10);
  if (!size || detectFormat(input, size) != DetectedFormat::StlBinary) return std::nullopt;
  if (input.fill(kPreambleBytes) < kPreambleBytes) return std::nullopt;
  const uint64_t count = loadLittleEndian32(input.data() + 80);
  if (count == 0 || kPreambleBytes + count * kRecordBytes != *size) return std::nullopt;
  StlFaceRanges r;
  r.info.name = name;
  r.info.format = MeshFormat::StlBinary;
  r.info.declaredFaces = count;
  r.fileBytes = *size;
  r.faceCount = count;
  return r;
}

void readStlFaceRange(const StlFaceRanges& file, uint64_t first, uint64_t count, size_t chunkFaces,
                      const std::function<void(std::span<const Triangle>)>& sink, ReadStats& stats) {
  using namespace stream_detail;
  if (first > file.faceCount || count > file.faceCount - first)
    throw std::invalid_argument("readStlFaceRange: faces past the file's " + std::to_string(file.faceCount));
  const PositionedFile in(file.info.name);
  chunkFaces = std::max<size_t>(chunkFaces, 1);
  std::vector<char> records;
  std::vector<Triangle> triangles;
  for (uint64_t done = 0; done < count;) {
    const auto n = static_cast<size_t>(std::min<uint64_t>(chunkFaces, count - done));
    const uint64_t chunkFirst = first + done;
    records.resize(n * kRecordBytes);
    in.read(kPreambleBytes + chunkFirst * kRecordBytes, records.data(), records.size(),
            "triangle " + std::to_string(chunkFirst) + " of " + std::to_string(file.faceCount));
    triangles.resize(n);
    for (size_t f = 0; f < n; ++f) {
      Triangle& t = triangles[f];
      const char* corner = records.data() + f * kRecordBytes + kFirstCornerOffset;
      int finite = 0;
      for (int k = 0; k < 3; ++k, corner += 3 * sizeof(float)) {
        for (int axis = 0; axis < 3; ++axis)
          t.position[k][axis] = std::bit_cast<float>(loadLittleEndian32(corner + axis * sizeof(float)));
        t.vertex[k] = kNoVertex;
        finite += isFinite(t.position[k]);
      }
      t.face = chunkFirst + f;
      stats.nonFiniteVertices += 3 - finite;
      if (finite == 3 &&
          (samePosition(t.position[0], t.position[1]) || samePosition(t.position[1], t.position[2]) ||
           samePosition(t.position[0], t.position[2]) ||
           zeroArea(t.position[0], t.position[1], t.position[2])))
        ++stats.degenerateTriangles;
    }
    stats.faces += n;
    stats.triangles += n;
    sink(triangles);
    done += n;
  }
}

}  // namespace facetree
