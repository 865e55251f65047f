// Binary PLY read in face ranges (facetree/stream.h): the layout from the header, then any range
// of face records read with pread, its corners' positions fetched from the vertex records.
//
// A chunk's corners are bucketed by vertex block (a counting sort on the block number) and each
// block the chunk touches is read once: a coherent file reads the few blocks near its faces, a
// shuffled one reads its vertex records once per chunk, never once per corner (the sort join of
// external-memory algorithms, Vitter 2001, sec. 7, within one chunk's memory).
#include <algorithm>
#include <cmath>
#include <vector>

#include "byte_source.h"
#include "format_detect.h"
#include "ply_header.h"
#include "ply_scalar.h"
#include "positioned_file.h"
#include "read_error.h"
#include "vertex_store.h"

namespace facetree {
namespace {

using stream_detail::Place;
using stream_detail::PlyScalar;

constexpr uint64_t kVertexBlock = 1024;  // vertex records read at once

bool fixedSize(const stream_detail::PlyElement& element, uint64_t& bytes) {
  bytes = 0;
  for (const auto& property : element.properties) {
    if (property.isList) return false;
    bytes += stream_detail::scalarSize(property.type);
  }
  return true;
}

glm::vec3 loadPosition(const PlyFaceRanges& file, const char* record) {
  glm::vec3 p;
  for (int axis = 0; axis < 3; ++axis)
    p[axis] = static_cast<float>(stream_detail::loadReal(static_cast<PlyScalar>(file.coordinateType[axis]),
                                                         record + file.coordinateOffset[axis], file.swap));
  return p;
}

}  // namespace

std::optional<PlyFaceRanges> plyFaceRanges(const std::filesystem::path& path) {
  using namespace stream_detail;
  const std::string name = path.string();
  auto source = FdSource::open(name, name);
  const std::optional<uint64_t> size = source->size();
  InputBuffer input(std::move(source), size_t{64} << 10);
  if (!size || detectFormat(input, size) != DetectedFormat::Ply) return std::nullopt;
  const PlyHeader header = parsePlyHeader(input, name);
  if (header.encoding == PlyEncoding::Ascii) return std::nullopt;
  PlyFaceRanges r;
  r.info.name = name;
  r.info.format = header.encoding == PlyEncoding::BinaryBigEndian ? MeshFormat::PlyBinaryBigEndian
                                                                  : MeshFormat::PlyBinaryLittleEndian;
  r.swap = (header.encoding == PlyEncoding::BinaryBigEndian) != (std::endian::native == std::endian::big);
  r.fileBytes = *size;
  // The faces last, every element before them in records of one size, the vertices among them.
  const auto last = header.elements.size() - 1;
  const PlyElement& faces = header.elements[last];
  if (faces.role != PlyRole::Face || header.vertexElement < 0 || size_t(header.vertexElement) > last)
    return std::nullopt;
  uint64_t at = input.offset();
  for (size_t e = 0; e < last; ++e) {
    const PlyElement& element = header.elements[e];
    if (element.role == PlyRole::Face || element.role == PlyRole::TriStrips) return std::nullopt;
    uint64_t stride = 0, bytes = 0;
    if (!fixedSize(element, stride) || __builtin_mul_overflow(element.count, stride, &bytes) ||
        __builtin_add_overflow(at, bytes, &at))
      return std::nullopt;
    if (static_cast<int>(e) == header.vertexElement) {
      r.vertexStart = at - bytes;
      r.vertexStride = stride;
      r.vertexCount = element.count;
      for (int axis = 0; axis < 3; ++axis) {
        const auto index = static_cast<size_t>(element.coordinate[axis]);
        r.coordinateType[axis] = static_cast<uint8_t>(element.properties[index].type);
        uint64_t offset = 0;
        for (size_t i = 0; i < index; ++i) offset += scalarSize(element.properties[i].type);
        r.coordinateOffset[axis] = static_cast<uint32_t>(offset);
      }
    }
  }
  // Face records: scalars and the one index list, whose count says 3 in every record when the sizes add up.
  for (size_t i = 0; i < faces.properties.size(); ++i) {
    const PlyProperty& property = faces.properties[i];
    if (static_cast<int>(i) == faces.indexList) {
      r.indexListOffset = static_cast<uint32_t>(r.faceStride);
      r.countType = static_cast<uint8_t>(property.countType);
      r.indexType = static_cast<uint8_t>(property.type);
      r.faceStride += scalarSize(property.countType) + 3 * scalarSize(property.type);
    } else if (property.isList) {
      return std::nullopt;
    } else {
      r.faceStride += scalarSize(property.type);
    }
  }
  r.faceStart = at;
  r.faceCount = faces.count;
  uint64_t faceBytes = 0, end = 0;
  if (__builtin_mul_overflow(r.faceCount, r.faceStride, &faceBytes) ||
      __builtin_add_overflow(r.faceStart, faceBytes, &end) || end != r.fileBytes ||
      r.vertexCount > kMaxVertices)
    return std::nullopt;  // the whole-file reader says what is wrong, if anything
  r.info.declaredVertices = r.vertexCount;
  r.info.declaredFaces = r.faceCount;
  return r;
}

void readPlyFaceRange(const PlyFaceRanges& file, uint64_t first, uint64_t count, size_t chunkFaces,
                      const std::function<void(std::span<const Triangle>)>& sink, ReadStats& stats) {
  if (first > file.faceCount || count > file.faceCount - first)
    throw std::invalid_argument("readPlyFaceRange: faces past the file's " + std::to_string(file.faceCount));
  const stream_detail::PositionedFile in(file.info.name);
  chunkFaces = std::max<size_t>(chunkFaces, 1);
  const auto countType = static_cast<PlyScalar>(file.countType);
  const auto indexType = static_cast<PlyScalar>(file.indexType);
  const size_t countBytes = stream_detail::scalarSize(countType);
  const size_t indexBytes = stream_detail::scalarSize(indexType);
  const uint64_t blocks = (file.vertexCount + kVertexBlock - 1) / kVertexBlock;
  std::vector<char> records, vertexRecords;
  std::vector<Triangle> triangles;
  std::vector<uint32_t> blockStart(blocks + 1), order;
  for (uint64_t done = 0; done < count;) {
    const auto n = static_cast<size_t>(std::min<uint64_t>(chunkFaces, count - done));
    const uint64_t chunkFirst = first + done;
    records.resize(n * file.faceStride);
    in.read(file.faceStart + chunkFirst * file.faceStride, records.data(), records.size(),
            "face " + std::to_string(chunkFirst) + " of " + std::to_string(file.faceCount));
    triangles.resize(n);
    std::fill(blockStart.begin(), blockStart.end(), 0u);
    for (size_t f = 0; f < n; ++f) {
      const uint64_t face = chunkFirst + f;
      const char* list = records.data() + f * file.faceStride + file.indexListOffset;
      // The messages of the whole-file reader (ply_reader.cpp) at the record's first byte.
      const auto fail = [&](const std::string& reason) {
        stream_detail::throwReadError(file.info.name, Place::byte(file.faceStart + face * file.faceStride),
                                      "face " + std::to_string(face) + reason);
      };
      const int64_t length = stream_detail::loadInteger(countType, list, file.swap);
      if (length < 0) fail(" has negative vertex count " + std::to_string(length));
      if (length < 3) fail(" has " + std::to_string(length) + " vertices");
      if (length > 3)
        fail(" has " + std::to_string(length) + " vertices; faces read in ranges must be triangles");
      Triangle& t = triangles[f];
      t.face = face;
      for (int k = 0; k < 3; ++k) {
        const int64_t v =
            stream_detail::loadInteger(indexType, list + countBytes + k * indexBytes, file.swap);
        if (v < 0) fail(": negative vertex index " + std::to_string(v));
        if (static_cast<uint64_t>(v) >= file.vertexCount)
          fail(": vertex index " + std::to_string(v) + " out of range (" + std::to_string(file.vertexCount) +
               " vertices)");
        t.vertex[k] = static_cast<uint32_t>(v);
        ++blockStart[t.vertex[k] / kVertexBlock + 1];
      }
      if (t.vertex[0] == t.vertex[1] || t.vertex[1] == t.vertex[2] || t.vertex[0] == t.vertex[2])
        ++stats.degenerateTriangles;
    }
    // Corners by vertex block, then each block read once.
    for (uint64_t b = 0; b < blocks; ++b) blockStart[b + 1] += blockStart[b];
    order.resize(3 * n);
    {
      std::vector<uint32_t> next(blockStart.begin(), blockStart.end() - 1);
      for (size_t c = 0; c < 3 * n; ++c)
        order[next[triangles[c / 3].vertex[c % 3] / kVertexBlock]++] = uint32_t(c);
    }
    for (uint64_t b = 0; b < blocks; ++b) {
      if (blockStart[b] == blockStart[b + 1]) continue;
      const uint64_t firstVertex = b * kVertexBlock;
      const uint64_t vertices = std::min(kVertexBlock, file.vertexCount - firstVertex);
      vertexRecords.resize(vertices * file.vertexStride);
      in.read(file.vertexStart + firstVertex * file.vertexStride, vertexRecords.data(), vertexRecords.size(),
              "vertex " + std::to_string(firstVertex) + " of " + std::to_string(file.vertexCount));
      for (uint32_t i = blockStart[b]; i < blockStart[b + 1]; ++i) {
        Triangle& t = triangles[order[i] / 3];
        const int k = static_cast<int>(order[i] % 3);
        t.position[k] =
            loadPosition(file, vertexRecords.data() + (t.vertex[k] - firstVertex) * file.vertexStride);
      }
    }
    stats.faces += n;
    stats.triangles += n;
    sink(triangles);
    done += n;
  }
}

uint64_t countNonFiniteVertices(const PlyFaceRanges& file, uint64_t first, uint64_t count) {
  if (first > file.vertexCount || count > file.vertexCount - first)
    throw std::invalid_argument("countNonFiniteVertices: vertices past the file's " +
                                std::to_string(file.vertexCount));
  const stream_detail::PositionedFile in(file.info.name);
  constexpr uint64_t kChunk = 64 * kVertexBlock;
  std::vector<char> records;
  uint64_t nonFinite = 0;
  for (uint64_t done = 0; done < count;) {
    const uint64_t n = std::min(kChunk, count - done);
    records.resize(n * file.vertexStride);
    in.read(file.vertexStart + (first + done) * file.vertexStride, records.data(), records.size(),
            "vertex " + std::to_string(first + done) + " of " + std::to_string(file.vertexCount));
    for (uint64_t v = 0; v < n; ++v) {
      const glm::vec3 p = loadPosition(file, records.data() + v * file.vertexStride);
      nonFinite += !(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
    }
    done += n;
  }
  return nonFinite;
}

}  // namespace facetree
