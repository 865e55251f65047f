// verifyAgainstMesh over a ClusterFileReader: the file's triangles and the mesh's, each keyed by
// original id and corners (fch::TriangleKey), compared in the order of one sort of each side, as in
// memory. Both sides go into buckets by windows of original ids, so that the sort is one window at
// a time and the pass holds two windows; the keys of a window that one side lacks carry over to the
// next, which keeps the comparison that of the whole sort.
#include <deque>

#include "verify_node.h"
#include "window_buckets.h"

namespace facetree {

VerifyResult verifyAgainstMesh(ClusterFileReader& reader, const MeshTriangleSource& mesh) {
  const uint64_t faces = reader.header().triangleCount;
  const uint64_t budget = std::max<uint64_t>(reader.memoryBytes() / 8, 4096);
  const uint64_t window = std::max<uint64_t>(budget / (2 * sizeof(fch::TriangleKey)), 16);
  const uint64_t runBytes =
      std::clamp<uint64_t>(budget / std::max<uint64_t>(faces / window, 1), 4096, 256 << 10);
  fch::WindowBuckets<fch::TriangleKey> fromFile(budget, runBytes, reader.temporaryDirectory());
  fch::WindowBuckets<fch::TriangleKey> fromMesh(budget, runBytes, reader.temporaryDirectory());

  uint64_t meshTriangles = 0;
  mesh([&](std::span<const MeshTriangle> batch) {
    for (const MeshTriangle& t : batch) {
      fromMesh.add(t.id / window, fch::TriangleKey(t.id, t.position, t.corner[0], t.corner[1], t.corner[2]));
      ++meshTriangles;
    }
  });
  if (meshTriangles != faces)
    return {false,
            "mesh: " + std::to_string(meshTriangles) + " triangles, the file has " + std::to_string(faces),
            0};
  const CutCluster all[1] = {{reader.size() > 0 ? 0 : kNoNode, 0, faces}};
  reader.forEachCutPiece(std::span<const CutCluster>(all, faces > 0 ? 1 : 0), [&](const FaceRangeMesh& piece,
                                                                                  std::span<const uint32_t>) {
    for (size_t t = 0; t < piece.originalFace.size(); ++t) {
      const uint64_t id = piece.originalFace[t];
      fromFile.add(id / window, fch::TriangleKey(id, piece.first + t, piece.vertices[piece.indices[3 * t]],
                                                 piece.vertices[piece.indices[3 * t + 1]],
                                                 piece.vertices[piece.indices[3 * t + 2]]));
    }
  });

  std::deque<fch::TriangleKey> fileQueue, meshQueue;
  std::vector<fch::TriangleKey> taken;
  const auto load = [&](fch::WindowBuckets<fch::TriangleKey>& side, uint64_t w,
                        std::deque<fch::TriangleKey>& queue) {
    side.take(w, taken);
    std::sort(taken.begin(), taken.end());
    queue.insert(queue.end(), taken.begin(), taken.end());
  };
  while (!fromFile.empty() || !fromMesh.empty()) {
    const uint64_t w = fromFile.empty()   ? fromMesh.firstWindow()
                       : fromMesh.empty() ? fromFile.firstWindow()
                                          : std::min(fromFile.firstWindow(), fromMesh.firstWindow());
    load(fromFile, w, fileQueue);
    load(fromMesh, w, meshQueue);
    for (; !fileQueue.empty() && !meshQueue.empty(); fileQueue.pop_front(), meshQueue.pop_front())
      if (!fileQueue.front().sameKey(meshQueue.front()))
        return {false, fch::triangleMismatch(fileQueue.front(), meshQueue.front()), 0};
  }
  return {true, "", reader.size()};
}

}  // namespace facetree
