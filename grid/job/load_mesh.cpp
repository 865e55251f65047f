// Reads a whole mesh into memory for the in-core path.
#include "facetree/grid.h"

#include <limits>
#include <stdexcept>

#include "stages/stages.h"

namespace facetree {

IndexedMesh loadMesh(TriangleReader& reader, const LoadOptions& options) {
  IndexedMesh mesh;
  std::vector<Triangle> batch(kReadBatchTriangles);
  if (reader.info().declaredFaces > 0) {
    // A hint only: never trust a header count beyond what a reasonable reserve allows.
    const uint64_t hint = std::min<uint64_t>(reader.info().declaredFaces, uint64_t{1} << 26);
    mesh.indices.reserve(hint * 3);
    mesh.originalFace.reserve(hint);
  }
  for (size_t got; (got = reader.read(batch)) > 0;) {
    if (options.cancelled && options.cancelled()) throw cancelledError();
    for (size_t i = 0; i < got; ++i) {
      const Triangle& t = batch[i];
      mesh.indices.insert(mesh.indices.end(), {t.vertex[0], t.vertex[1], t.vertex[2]});
      mesh.originalFace.push_back(t.face);
    }
  }
  const VertexSource& vertices = reader.vertices();
  if (vertices.size() > std::numeric_limits<uint32_t>::max())
    throw std::invalid_argument(reader.info().name + ": more than 2^32 vertices do not fit in memory mode");
  mesh.positions.resize(vertices.size());
  for (uint64_t i = 0; i < vertices.size(); ++i) mesh.positions[i] = vertices.position(i);
  if (options.weldPositions) mesh.weldedVertices = weldPositions(mesh.positions, mesh.indices);
  mesh.info = reader.info();
  mesh.stats = reader.stats();
  return mesh;
}

}  // namespace facetree
