// Draco reader. Draco's bitstream cannot be decoded incrementally: the whole file is read
// into memory and decoded at open by draco::Decoder, then the decoded mesh's triangles are
// served in batches. Memory is therefore proportional to the mesh, unlike the other formats:
// the counts in the file's header (draco_header.h) give an estimate of the decoding's peak
// before anything else is read, held against ReadOptions::wholeMeshLimitBytes, and the decoded
// mesh's actual size is checked again after decoding (attributes other than positions, which
// the header does not count, are decoded too). Draco sizes its tables from those counts before
// it reads the data they describe, so counts no encoding of the file's size could hold are
// refused first, whatever the limit (a file of a few bytes can declare hundreds of millions of
// faces, which draco would allocate for).
// Vertex indices are Draco point indices (one position per point).
#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>

#include <algorithm>
#include <cstdio>
#include <optional>
#include <vector>

#include "draco_header.h"
#include "read_error.h"
#include "readers.h"
#include "vertex_store.h"

namespace facetree::stream_detail {
namespace {

constexpr int kPositionComponents = 3;
// The header's counts are within the first bytes unless the file carries large metadata.
constexpr size_t kHeaderPeekBytes = size_t{64} << 10;
// Peak bytes of draco's decoding per face and per point, over the encoded bytes, for positions
// only: the mesh's faces (12 B) and float positions (12 B per point), our copy of the positions
// (12 B), and the decoder's own tables: the sequential decoder's index symbols (12 B per face),
// the edgebreaker's corner tables (~36 B per face, ~12 B per point). Measured on generated
// terrains of 1M and 3M faces (facetree stats, peak RSS differences): sequential 25 B, edgebreaker
// 59 B per face and half a point; these give 36 B and 66 B.
constexpr uint64_t kSequentialBytesPerFace = 24, kSequentialBytesPerPoint = 24;
constexpr uint64_t kEdgebreakerBytesPerFace = 48, kEdgebreakerBytesPerPoint = 36;
constexpr uint64_t kMiB = uint64_t{1} << 20;
// Most faces or points one encoded byte can describe. The most compressible mesh we could make,
// a regular grid with positions quantised to 1 bit under the valence edgebreaker at speed 0,
// takes 9,608 bytes for 8M faces and 4M points (833 faces per byte, about 1000 per byte at the
// margin); ordinary encodings of that grid take 0.07 to 16. Eight times the extreme leaves real
// files alone.
constexpr uint64_t kMaxElementsPerEncodedByte = 8192;

class DracoReader final : public ReaderBase {
 public:
  DracoReader(std::unique_ptr<InputBuffer> input, MeshInfo info, uint64_t limit)
      : input_(std::move(input)), limit_(limit) {
    info_ = std::move(info);
    info_.format = MeshFormat::Draco;
    input_->fill(kHeaderPeekBytes);
    std::optional<DracoCounts> counts = parseDracoCounts({input_->data(), input_->available()});
    if (counts) {
      expectDecoding(*counts);
      // A corrupt file is named as such before the limit could ask for a larger cap.
      if (const std::optional<uint64_t> size = input_->size()) checkPlausible(*counts, *size);
    }
    const std::vector<char> encoded = readAll();
    if (!counts && (counts = parseDracoCounts(encoded))) {  // metadata longer than the peek
      expectDecoding(*counts);
      checkPlausible(*counts, encoded.size());
      checkLimit(encoded.capacity() + decodingBytes_, "need about");
    } else if (counts && !input_->size()) {
      checkPlausible(*counts, encoded.size());  // standard input, zstd: the size is known now
    }
    draco::DecoderBuffer buffer;
    buffer.Init(encoded.data(), encoded.size());
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
    if (!decoded.ok()) fail("draco decoding failed: " + lowerFirst(decoded.status().error_msg_string()));
    mesh_ = std::move(decoded).value();
    const draco::PointAttribute* positions = mesh_->GetNamedAttribute(draco::GeometryAttribute::POSITION);
    if (positions == nullptr) fail("draco mesh has no position attribute");
    // ConvertValue reads a DT_BOOL attribute as C++ bool: any byte but 0 and 1 is undefined.
    if (positions->data_type() < draco::DT_INT8 || positions->data_type() > draco::DT_FLOAT64)
      fail("draco position attribute has unsupported data type " + std::to_string(positions->data_type()));
    if (positions->num_components() != kPositionComponents)
      fail("draco position attribute has " + std::to_string(positions->num_components()) + " components");
    info_.declaredVertices = mesh_->num_points();
    info_.declaredFaces = mesh_->num_faces();
    if (mesh_->num_faces() == 0) fail("no faces");
    heldBytes_ = decodedBytes();
    checkLimit(encoded.capacity() + heldBytes_, "takes");
    vertices_.reserve(mesh_->num_points());
    for (uint32_t point = 0; point < mesh_->num_points(); ++point) {
      glm::vec3 position;
      positions->ConvertValue<float>(positions->mapped_index(draco::PointIndex(point)), kPositionComponents,
                                     &position.x);
      addVertex(position);
    }
  }

 protected:
  size_t produce(Triangle* out, size_t capacity) override {
    size_t count = 0;
    for (; count < capacity && next_ < mesh_->num_faces(); ++count, ++next_) {
      const draco::Mesh::Face& face = mesh_->face(draco::FaceIndex(next_));
      for (int corner = 0; corner < 3; ++corner) {
        // Draco's sequential decoder does not check stored (uncompressed) indices.
        const uint32_t index = face[corner].value();
        if (index >= mesh_->num_points())
          fail("face " + std::to_string(next_) + ": vertex index " + std::to_string(index) +
               " out of range (" + std::to_string(mesh_->num_points()) + " vertices)");
        out[count].vertex[corner] = index;
      }
      out[count].face = next_;
    }
    stats_.faces += count;
    return count;
  }

  uint64_t heldBytes() const override { return heldBytes_; }
  uint64_t inputOffset() const override { return input_->offset(); }
  uint64_t compressedOffset() const override { return input_->source().compressedBytesRead(); }

 private:
  [[noreturn]] void fail(const std::string& reason) const {
    throwReadError(info_.name, Place::byte(0), reason);
  }

  static std::string lowerFirst(std::string text) {
    if (!text.empty() && text[0] >= 'A' && text[0] <= 'Z') text[0] = static_cast<char>(text[0] - 'A' + 'a');
    return text;
  }

  // The header's counts, and the decoding's peak estimated from them.
  void expectDecoding(const DracoCounts& counts) {
    info_.declaredFaces = counts.faces;
    info_.declaredVertices = counts.points;
    decodingBytes_ = counts.edgebreaker
                         ? kEdgebreakerBytesPerFace * counts.faces + kEdgebreakerBytesPerPoint * counts.points
                         : kSequentialBytesPerFace * counts.faces + kSequentialBytesPerPoint * counts.points;
    const uint64_t most = std::max(counts.faces, counts.points);
    plausibleBytes_ = (most + kMaxElementsPerEncodedByte - 1) / kMaxElementsPerEncodedByte;
  }

  // Fails when the counts are more than `encodedBytes` could describe.
  void checkPlausible(const DracoCounts& counts, uint64_t encodedBytes) const {
    if (std::max(counts.faces, counts.points) <= kMaxElementsPerEncodedByte * encodedBytes) return;
    fail("the header declares " + std::to_string(counts.faces) + " faces and " +
         std::to_string(counts.points) + " points in " + std::to_string(encodedBytes) +
         " bytes, more than any draco encoding holds (" + std::to_string(kMaxElementsPerEncodedByte) +
         " per byte at most): the file is corrupt");
  }

  // Fails when `bytes` pass the limit; `verb` says whether they are an estimate ("need about").
  void checkLimit(uint64_t bytes, const char* verb) const {
    if (limit_ == 0 || bytes <= limit_) return;
    const std::string counts = info_.declaredFaces ? std::to_string(info_.declaredFaces) + " faces and " +
                                                         std::to_string(info_.declaredVertices) + " points"
                                                   : std::string("it");
    fail("a draco mesh is decoded whole (the format cannot be streamed): " + counts + " " + verb + " " +
         mebibytes(bytes) + ", over the " + mebibytes(limit_) +
         " allowed to the reader; raise the memory cap or convert the mesh to PLY, which streams");
  }

  static std::string mebibytes(uint64_t bytes) {
    char text[32];
    std::snprintf(text, sizeof text, "%.1f MiB", double(bytes) / double(kMiB));
    return text;
  }

  // The decoded mesh as draco holds it (faces, every attribute's values, point maps) and our
  // copy of its positions.
  uint64_t decodedBytes() const {
    uint64_t bytes = uint64_t{12} * mesh_->num_faces() + uint64_t{12} * mesh_->num_points();
    for (int32_t i = 0; i < mesh_->num_attributes(); ++i) {
      const draco::PointAttribute* attribute = mesh_->attribute(i);
      if (attribute == nullptr) continue;
      if (attribute->buffer() != nullptr) bytes += attribute->buffer()->data_size();
      if (!attribute->is_mapping_identity()) bytes += uint64_t{4} * mesh_->num_points();
    }
    return bytes;
  }

  // The encoded file, checked against the limit as it arrives (with the decoding's estimate):
  // when its size is unknown (standard input, zstd) the vector grows by doubling, so up to three
  // times its bytes are counted. The estimate counts only once the bytes read could hold the
  // header's counts (plausibleBytes_, at most 512 KiB): a stream that ends before is corrupt, and
  // the constructor says so rather than asking for a larger cap.
  std::vector<char> readAll() {
    std::vector<char> data;
    const std::optional<uint64_t> size = input_->size();
    const auto decoding = [&] { return size || data.size() >= plausibleBytes_ ? decodingBytes_ : 0; };
    // First on its own, so that the refusal of a mesh whose decoding alone passes the limit does
    // not depend on how much of the file has arrived.
    checkLimit(size.value_or(0) + decoding(), "need about");
    if (size) data.reserve(*size);
    while (input_->fill(1) > 0) {
      data.insert(data.end(), input_->data(), input_->data() + input_->available());
      input_->consume(input_->available());
      checkLimit((size ? data.capacity() : 3 * data.size()) + decoding(), "need about");
    }
    return data;
  }

  std::unique_ptr<InputBuffer> input_;
  uint64_t limit_;               // ReadOptions::wholeMeshLimitBytes, 0 for none
  uint64_t decodingBytes_ = 0;   // estimated from the header's counts, over the encoded bytes
  uint64_t plausibleBytes_ = 0;  // the fewest encoded bytes that could hold the header's counts
  uint64_t heldBytes_ = 0;       // the decoded mesh, once decoded
  std::unique_ptr<draco::Mesh> mesh_;
  uint32_t next_ = 0;
};

}  // namespace

std::unique_ptr<TriangleReader> makeDracoReader(std::unique_ptr<InputBuffer> input, MeshInfo info,
                                                uint64_t wholeMeshLimitBytes) {
  return std::make_unique<DracoReader>(std::move(input), std::move(info), wholeMeshLimitBytes);
}

}  // namespace facetree::stream_detail
