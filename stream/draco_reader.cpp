// Draco reader. Draco's bitstream cannot be decoded incrementally: the whole file is read
// into memory and decoded at open by draco::Decoder, then the decoded mesh's triangles are
// served in batches. Memory is therefore proportional to the mesh, unlike the other formats.
// Vertex indices are Draco point indices (one position per point).
#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>

#include <vector>

#include "stream/read_error.h"
#include "stream/readers.h"
#include "stream/vertex_store.h"

namespace facetree::stream_detail {
namespace {

constexpr int kPositionComponents = 3;

class DracoReader final : public ReaderBase {
 public:
  DracoReader(std::unique_ptr<InputBuffer> input, MeshInfo info) : input_(std::move(input)) {
    info_ = std::move(info);
    info_.format = MeshFormat::Draco;
    const std::vector<char> encoded = readAll();
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

  std::vector<char> readAll() {
    std::vector<char> data;
    if (const std::optional<uint64_t> size = input_->size()) data.reserve(*size);
    while (input_->fill(1) > 0) {
      data.insert(data.end(), input_->data(), input_->data() + input_->available());
      input_->consume(input_->available());
    }
    return data;
  }

  std::unique_ptr<InputBuffer> input_;
  std::unique_ptr<draco::Mesh> mesh_;
  uint32_t next_ = 0;
};

}  // namespace

std::unique_ptr<TriangleReader> makeDracoReader(std::unique_ptr<InputBuffer> input, MeshInfo info) {
  return std::make_unique<DracoReader>(std::move(input), std::move(info));
}

}  // namespace facetree::stream_detail
