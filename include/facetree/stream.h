// facetree/stream: streaming triangle readers (PLY ascii/binary, OBJ, STL, Draco; any of
// them zstd-compressed). Public header of the module: std and glm only.
//
// A reader yields triangles in batches with memory bounded by the batch size; the face list
// of the file is never held whole. Polygons are fan-triangulated and keep their original
// face index. Vertex positions of indexed formats are served through VertexSource (held in
// memory for now; a bounded cache can be put behind the same interface).
//
// Errors: functions of this header throw facetree::Error of category Input (facetree/error.h) for
// malformed or unreadable input; what() is one line "FILE: PLACE: REASON", where PLACE is
// "byte N" or "line N". Nothing else is thrown except std::bad_alloc.
#pragma once

#include <bit>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>

#include <glm/vec3.hpp>

#include "facetree/error.h"

namespace facetree {

// A vertex id that names no vertex.
inline constexpr uint32_t kNoVertex = 0xFFFFFFFFu;

// A coordinate as bits that are equal exactly when welding makes two floats one: bit-identical
// positions weld, and -0.0 welds with 0.0.
inline uint32_t weldBits(float f) {
  return f == 0.0f ? 0u : std::bit_cast<uint32_t>(f);
}
// Points every index at the lowest-numbered vertex at the same position (weldBits), with the hash
// table the STL reader welds its corners with; returns how many vertices were replaced. Positions
// are left in place (unreferenced duplicates stay).
uint64_t weldPositions(std::span<const glm::vec3> positions, std::span<uint32_t> indices);

// One triangle as the reader hands it on. `face` is the index of the face in the file
// (before fan triangulation); `vertex` are indices into the reader's VertexSource.
struct Triangle {
  glm::vec3 position[3];  // of its corners
  uint32_t vertex[3];     // the corners' indices in the reader's VertexSource
  uint64_t face;          // the file's face it comes from
};

// The formats the readers detect from a stream's content.
enum class MeshFormat {
  PlyAscii,
  PlyBinaryLittleEndian,
  PlyBinaryBigEndian,
  Obj,
  StlAscii,
  StlBinary,
  Draco
};
// The format's name as messages and reports give it ("PLY", "OBJ", ...).
const char* formatName(MeshFormat format);

// What a reader knows of its input before and while reading.
struct MeshInfo {
  std::string name;               // file name as given, "-" for standard input
  MeshFormat format{};            // as detected from the content
  bool zstdCompressed = false;    // read through zstd
  uint64_t declaredVertices = 0;  // from the header where the format has one, else 0
  uint64_t declaredFaces = 0;     // likewise
};

// Counts gathered while reading; final once read() returned 0.
struct ReadStats {
  uint64_t vertices = 0;             // vertices in the VertexSource
  uint64_t faces = 0;                // faces in the file (polygons, strips count as one each)
  uint64_t triangles = 0;            // triangles handed on
  uint64_t degenerateTriangles = 0;  // repeated vertex index or zero area: handed on, counted
  uint64_t skippedTriangles = 0;     // touching a NaN/Inf vertex: not handed on
  uint64_t nonFiniteVertices = 0;    // vertices with a NaN or infinite coordinate
  uint64_t inputBytes = 0;           // bytes of the (decompressed) mesh file consumed
  uint64_t compressedBytes = 0;      // bytes read from disk when zstd-compressed, else 0
};

// Positions of an indexed mesh, by vertex index.
class VertexSource {
 public:
  virtual ~VertexSource() = default;
  virtual uint64_t size() const = 0;
  virtual glm::vec3 position(uint64_t index) const = 0;
};

// A streaming reader of one mesh: triangles in batches, vertices, statistics.
class TriangleReader {
 public:
  virtual ~TriangleReader() = default;
  // Fills `out` from the front; returns how many triangles were written, 0 at the end.
  virtual size_t read(std::span<Triangle> out) = 0;
  virtual const MeshInfo& info() const = 0;
  virtual const ReadStats& stats() const = 0;
  // All vertices are known once the first read() returned (formats whose vertices follow
  // the faces are read to the end first); valid for the reader's lifetime. Exception: OBJ,
  // which may interleave vertices and faces, holds the vertices read so far (every index
  // handed on is valid) and is complete once read() returned 0.
  virtual const VertexSource& vertices() const = 0;
  // True when ReadOptions::vertexSink took the positions (see there).
  virtual bool positionsDeferred() const { return false; }
  // STL only (the other formats return false and change nothing): stops welding corners into
  // vertices, whose table grows with the mesh, and frees the vertices welded so far. Triangles
  // read afterwards carry their positions with every vertex index kNoVertex (a triangle soup),
  // and vertices() is empty; a non-finite corner counts as one non-finite vertex, coincident
  // corners as a degenerate triangle. The caller welds (out-of-core builds: by an external sort).
  virtual bool stopWelding() { return false; }
  // Bytes the reader holds for the whole mesh until it is destroyed: Draco's decoded mesh
  // (see ReadOptions::wholeMeshLimitBytes); 0 for the streaming formats.
  virtual uint64_t heldBytes() const { return 0; }
};

// How a reader reads: buffer size, the vertex sink, the whole-mesh limit.
struct ReadOptions {
  // Bytes of input buffered at once (decompressed and raw).
  size_t bufferBytes = size_t{1} << 20;
  // Bounded memory for PLY and OBJ (out-of-core builds): the reader does not keep vertex
  // positions but hands them to this sink in index order, in batches, every batch before any
  // triangle using its vertices is returned. Triangles then carry vertex indices and face ids
  // only (positions zero; positionsDeferred() is true): the caller resolves positions, drops
  // triangles touching non-finite vertices (ReadStats::nonFiniteVertices still counts those
  // vertices) and finds zero-area triangles (only repeated indices count as degenerate here).
  // vertices() then has the right size() but no positions. STL (positions per triangle, welded
  // in memory) and Draco (decoded whole) ignore the sink.
  std::function<void(std::span<const glm::vec3>)> vertexSink = {};
  // Draco has no streaming decoder: its reader decodes the whole mesh at open. With a limit, it
  // first estimates the decoding's peak from the counts in the file's header (and the encoded
  // bytes as they are read) and fails with a Error (Input), before decoding, when it is over the
  // limit; after decoding it checks the decoded mesh's actual size again (attributes the
  // header does not count). 0: no limit. The streaming formats ignore it.
  uint64_t wholeMeshLimitBytes = 0;
};

// Opens a mesh file; the format is detected from the content, not the name
// (".zst" framing, PLY/OBJ/STL/Draco signatures).
std::unique_ptr<TriangleReader> openMesh(const std::filesystem::path& path, const ReadOptions& options = {});
// Reads a mesh from standard input ("-"), format detected from the content.
std::unique_ptr<TriangleReader> openStandardInput(const ReadOptions& options = {});

// --- Binary PLY read in face ranges ---
//
// A binary PLY file whose face element comes last and holds only triangles, in records of one
// size, after a vertex element of fixed-size records, can be read in pieces by independent
// processes: faces [first, first + count) by one of them, each corner's position fetched from its
// vertex record by its place in the file. Together the pieces hand on what openMesh with a
// ReadOptions::vertexSink would, in file order, with the positions filled in: the same triangles,
// vertex ids and face ids.
struct PlyFaceRanges {
  MeshInfo info;
  uint64_t fileBytes = 0;
  uint64_t vertexCount = 0, faceCount = 0;
  // Where the records are and how to read them (the header's layout).
  uint64_t vertexStart = 0, vertexStride = 0;
  uint32_t coordinateOffset[3] = {0, 0, 0};
  uint8_t coordinateType[3] = {0, 0, 0};
  uint64_t faceStart = 0, faceStride = 0;
  uint32_t indexListOffset = 0;  // of the vertex_indices list's count within a face record
  uint8_t countType = 0, indexType = 0;
  bool swap = false;  // big-endian file on a little-endian machine or the reverse
};
// The layout of `path` when it is such a file; std::nullopt for any other mesh (other formats,
// zstd, ascii, a face element with lists besides vertex_indices, a size that says not every face
// is a triangle), which openMesh reads whole. Throws Error (Input) for a header openMesh rejects.
std::optional<PlyFaceRanges> plyFaceRanges(const std::filesystem::path& path);
// Faces [first, first + count) of `file` (opened again by its name) in chunks of at most
// `chunkFaces`: `sink` gets each chunk's triangles in file order, positions filled in, non-finite
// ones included. `stats` gains their faces, triangles and degenerate triangles (repeated vertex
// ids, as the deferred readers count them). Throws Error (Input) "NAME: byte N: face F: ..." for a
// record that is not a triangle or a vertex index out of range. Memory: about 80 bytes per chunk
// face and one block of vertex records.
void readPlyFaceRange(const PlyFaceRanges& file, uint64_t first, uint64_t count, size_t chunkFaces,
                      const std::function<void(std::span<const Triangle>)>& sink, ReadStats& stats);
// Vertices among [first, first + count) with a NaN or infinite coordinate.
uint64_t countNonFiniteVertices(const PlyFaceRanges& file, uint64_t first, uint64_t count);

// --- Binary STL read in face ranges ---
//
// An uncompressed binary STL file holds its triangles in records of 50 bytes, each with its three
// corners' positions, so any range of them can be read by a process of its own. The triangles
// carry kNoVertex for every vertex id (a soup: the caller welds positions), their positions and
// their face ids, in file order.
struct StlFaceRanges {
  MeshInfo info;
  uint64_t fileBytes = 0, faceCount = 0;
};
// The layout of `path` when it is such a file; std::nullopt for any other mesh, and for a binary
// STL whose size disagrees with its count or that has no triangles (openMesh names the fault).
std::optional<StlFaceRanges> stlFaceRanges(const std::filesystem::path& path);
// Triangles [first, first + count) of `file` (opened again by its name) in chunks of at most
// `chunkFaces`, non-finite ones included. `stats` gains their faces and triangles, the
// non-finite corners, and the degenerate triangles among the finite ones (two corners at one
// position, or no area, as the STL reader counts them). Memory: about 90 bytes per chunk face.
void readStlFaceRange(const StlFaceRanges& file, uint64_t first, uint64_t count, size_t chunkFaces,
                      const std::function<void(std::span<const Triangle>)>& sink, ReadStats& stats);

}  // namespace facetree
