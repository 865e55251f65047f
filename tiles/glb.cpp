// Binary glTF (glb.h): a 12-byte header, a JSON chunk padded with spaces and a binary chunk
// padded with zeros, both to 4 bytes (glTF 2.0, sec. "GLB File Format Specification").
#include "glb.h"

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>

#include <cstdio>
#include <cstring>
#include <vector>

#include "facetree/error.h"

namespace facetree::tiles {

std::string jsonNumber(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.17g", v);
  return text;
}
std::string jsonNumber(float v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.9g", double(v));
  return text;
}

namespace {

constexpr uint32_t kFloat = 5126, kUnsignedShort = 5123, kUnsignedInt = 5125;

void append32(std::string& out, uint32_t v) {
  char bytes[4];
  std::memcpy(bytes, &v, 4);
  out.append(bytes, 4);
}

// glTF's y up from the model's z up: (x, y, z) -> (x, z, -y), which 3D Tiles turns back.
glm::dvec3 yUp(const glm::dvec3& p) {
  return {p.x, p.z, -p.y};
}

std::string dracoBytes(const std::vector<glm::vec3>& local, const std::vector<uint32_t>& indices,
                       const glm::vec3& origin, float range, int bits, uint32_t& decodedPoints) {
  draco::Mesh mesh;
  mesh.set_num_points(static_cast<uint32_t>(local.size()));
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false, sizeof(glm::vec3),
                0);
  const int attribute = mesh.AddAttribute(position, true, static_cast<uint32_t>(local.size()));
  for (uint32_t i = 0; i < local.size(); ++i)
    mesh.attribute(attribute)->SetAttributeValue(draco::AttributeValueIndex(i), &local[i].x);
  mesh.SetNumFaces(indices.size() / 3);
  for (uint32_t t = 0; 3 * size_t{t} < indices.size(); ++t)
    mesh.SetFace(draco::FaceIndex(t),
                 {draco::PointIndex(indices[3 * t]), draco::PointIndex(indices[3 * t + 1]),
                  draco::PointIndex(indices[3 * t + 2])});
  draco::Encoder encoder;
  encoder.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
  encoder.SetSpeedOptions(5, 5);
  encoder.SetAttributeExplicitQuantization(draco::GeometryAttribute::POSITION, bits, 3, &origin.x, range);
  draco::EncoderBuffer buffer;
  if (const draco::Status status = encoder.EncodeMeshToBuffer(mesh, &buffer); !status.ok())
    throw Error(ErrorCategory::Output, "Draco encoding of a tile failed: " + status.error_msg_string());
  // Edgebreaker splits non-manifold vertices: the accessor counts what a decoder gives back.
  draco::DecoderBuffer in;
  in.Init(buffer.data(), buffer.size());
  auto decoded = draco::Decoder().DecodeMeshFromBuffer(&in);
  if (!decoded.ok())
    throw Error(ErrorCategory::Output,
                "a Draco tile does not decode: " + decoded.status().error_msg_string());
  decodedPoints = decoded.value()->num_points();
  return std::string(buffer.data(), buffer.size());
}

}  // namespace

std::string glbBytes(const TileMesh& mesh, const glm::dvec3& centre, const GlbOptions& options) {
  std::vector<glm::vec3> local(mesh.positions.size());
  glm::vec3 lo(0.0f), hi(0.0f);
  for (size_t i = 0; i < local.size(); ++i) {
    local[i] = glm::vec3(yUp(glm::dvec3(mesh.positions[i]) - centre));
    lo = i ? glm::min(lo, local[i]) : local[i];
    hi = i ? glm::max(hi, local[i]) : local[i];
  }
  const uint32_t vertices = static_cast<uint32_t>(local.size());
  // Draco's edgebreaker leaves out a triangle with two corners on one vertex, and cannot encode a
  // mesh of nothing else: the accessor counts the triangles it keeps, and a tile of only such
  // triangles goes uncompressed.
  std::vector<uint32_t> kept;
  if (options.draco) {
    kept.reserve(mesh.indices.size());
    for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
      const uint32_t a = mesh.indices[t], b = mesh.indices[t + 1], c = mesh.indices[t + 2];
      if (a != b && b != c && a != c) kept.insert(kept.end(), {a, b, c});
    }
  }
  const bool draco = !kept.empty();
  const size_t indexCount = draco ? kept.size() : mesh.indices.size();
  const bool shortIndices = vertices <= 65535;
  std::string bin;
  std::string accessors, views, primitive;
  const std::string minMax = "\"min\":[" + jsonNumber(lo.x) + "," + jsonNumber(lo.y) + "," +
                             jsonNumber(lo.z) + "],\"max\":[" + jsonNumber(hi.x) + "," + jsonNumber(hi.y) +
                             "," + jsonNumber(hi.z) + "]";
  if (draco) {
    // The grid in the tile's own coordinates: the model's cube moved by the tile's centre, in y up.
    const glm::dvec3 gridMax = options.gridMin + glm::dvec3(options.gridSize);
    const glm::dvec3 a = yUp(options.gridMin - centre), b = yUp(gridMax - centre);
    const glm::vec3 origin(glm::min(a, b));
    uint32_t points = 0;
    bin = dracoBytes(local, kept, origin, static_cast<float>(options.gridSize), options.positionBits, points);
    accessors = "{\"componentType\":" + std::to_string(kFloat) + ",\"count\":" + std::to_string(points) +
                ",\"type\":\"VEC3\"," + minMax +
                "},{\"componentType\":" + std::to_string(points <= 65535 ? kUnsignedShort : kUnsignedInt) +
                ",\"count\":" + std::to_string(indexCount) + ",\"type\":\"SCALAR\"}";
    views = "{\"buffer\":0,\"byteOffset\":0,\"byteLength\":" + std::to_string(bin.size()) + "}";
    primitive =
        "\"extensions\":{\"KHR_draco_mesh_compression\":{\"bufferView\":0,\"attributes\":{\"POSITION\":0}}},";
  } else {
    bin.append(reinterpret_cast<const char*>(local.data()), local.size() * sizeof(glm::vec3));
    const size_t indexOffset = bin.size();
    if (shortIndices) {
      for (const uint32_t v : mesh.indices) {
        const uint16_t s = static_cast<uint16_t>(v);
        bin.append(reinterpret_cast<const char*>(&s), 2);
      }
    } else {
      bin.append(reinterpret_cast<const char*>(mesh.indices.data()), indexCount * 4);
    }
    accessors = "{\"bufferView\":0,\"componentType\":" + std::to_string(kFloat) +
                ",\"count\":" + std::to_string(vertices) + ",\"type\":\"VEC3\"," + minMax +
                "},{\"bufferView\":1,\"componentType\":" +
                std::to_string(shortIndices ? kUnsignedShort : kUnsignedInt) +
                ",\"count\":" + std::to_string(indexCount) + ",\"type\":\"SCALAR\"}";
    views = "{\"buffer\":0,\"byteOffset\":0,\"byteLength\":" + std::to_string(indexOffset) +
            ",\"target\":34962},{\"buffer\":0,\"byteOffset\":" + std::to_string(indexOffset) +
            ",\"byteLength\":" + std::to_string(bin.size() - indexOffset) + ",\"target\":34963}";
  }
  const size_t binLength = bin.size();
  bin.resize((bin.size() + 3) & ~size_t{3}, '\0');
  const glm::dvec3 t = yUp(centre);
  std::string json = "{\"asset\":{\"version\":\"2.0\",\"generator\":\"facetree\"},";
  if (draco)
    json +=
        "\"extensionsUsed\":[\"KHR_draco_mesh_compression\"],\"extensionsRequired\":[\"KHR_draco_mesh_"
        "compression\"],";
  json +=
      "\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0,\"translation\":[" + jsonNumber(t.x) +
      "," + jsonNumber(t.y) + "," + jsonNumber(t.z) + "]}],\"meshes\":[{\"primitives\":[{" + primitive +
      "\"attributes\":{\"POSITION\":0},\"indices\":1,\"material\":0,\"mode\":4}]}],"
      "\"materials\":[{\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.8,0.8,0.8,1],\"metallicFactor\":0,"
      "\"roughnessFactor\":1},\"doubleSided\":true}],\"accessors\":[" +
      accessors + "],\"bufferViews\":[" + views +
      "],\"buffers\":[{\"byteLength\":" + std::to_string(binLength) + "}]}";
  json.resize((json.size() + 3) & ~size_t{3}, ' ');
  std::string out;
  out.reserve(12 + 8 + json.size() + 8 + bin.size());
  append32(out, 0x46546C67u);  // "glTF"
  append32(out, 2);
  append32(out, static_cast<uint32_t>(12 + 8 + json.size() + 8 + bin.size()));
  append32(out, static_cast<uint32_t>(json.size()));
  append32(out, 0x4E4F534Au);  // "JSON"
  out += json;
  append32(out, static_cast<uint32_t>(bin.size()));
  append32(out, 0x004E4942u);  // "BIN\0"
  out += bin;
  return out;
}

}  // namespace facetree::tiles
