// Binary STL read in face ranges (facetree/stream.h): the count from the preamble, then any range
// of the 50-byte triangle records read with pread. Nothing is welded: each corner keeps its
// position and the caller gives vertex ids to distinct positions.
#include <algorithm>
#include <stdexcept>
#include <vector>

#include "byte_source.h"
#include "format_detect.h"
#include "positioned_file.h"
#include "position_welder.h"
#include "stl_layout.h"
#include "vertex_store.h"

namespace facetree {
std::optional<StlFaceRanges> stlFaceRanges(const std::filesystem::path& path) {
  using namespace stream_detail;
  const std::string name = path.string();
  auto source = FdSource::open(name, name);
  const std::optional<uint64_t> size = source->size();
  InputBuffer input(std::move(source), size_t{64} << 10);
  if (!size || detectFormat(input, size) != DetectedFormat::StlBinary) return std::nullopt;
  if (input.fill(kStlPreambleBytes) < kStlPreambleBytes) return std::nullopt;
  const uint64_t count = loadLittleEndian32(input.data() + kStlHeaderBytes);
  if (count == 0 || kStlPreambleBytes + count * kStlTriangleBytes != *size) return std::nullopt;
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
    records.resize(n * kStlTriangleBytes);
    in.read(kStlPreambleBytes + chunkFirst * kStlTriangleBytes, records.data(), records.size(),
            "triangle " + std::to_string(chunkFirst) + " of " + std::to_string(file.faceCount));
    triangles.resize(n);
    for (size_t f = 0; f < n; ++f) {
      Triangle& t = triangles[f];
      const char* corner = records.data() + f * kStlTriangleBytes + kStlFirstCornerOffset;
      int finite = 0;
      for (int k = 0; k < 3; ++k, corner += 3 * sizeof(float)) {
        for (int axis = 0; axis < 3; ++axis)
          t.position[k][axis] = loadLittleEndianFloat(corner + axis * sizeof(float));
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
