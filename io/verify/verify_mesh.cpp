// verifyAgainstMesh: the file's triangles and the mesh's, each keyed by original id and corners
// (fch::TriangleKey), compared in the order of one sort of each side. The file's side goes into buckets by
// windows of original ids, so that the sort is one window at a time; a mesh read in order is already sorted
// and is compared as it comes, any other is bucketed the same way, and the keys of a window that one side
// lacks carry over to the next, which keeps the comparison that of the whole sort.
#include <deque>
#include <optional>
#include <string>

#include "read/cluster_source.h"
#include "verify/verify_node.h"
#include "verify/window_buckets.h"

namespace facetree {

namespace {

using TriangleQueue = std::deque<fch::TriangleKey>;

VerifyResult countMismatch(uint64_t meshTriangles, uint64_t faces) {
  return {false,
          "mesh: " + std::to_string(meshTriangles) + " triangles, the file has " + std::to_string(faces), 0};
}

// Window `w` of `side`, sorted, onto the end of `queue` (`taken`: scratch).
void takeWindow(fch::WindowBuckets<fch::TriangleKey>& side, uint64_t w, std::vector<fch::TriangleKey>& taken,
                TriangleQueue& queue) {
  side.take(w, taken);
  std::sort(taken.begin(), taken.end());
  queue.insert(queue.end(), taken.begin(), taken.end());
}

// The file's triangles keyed and bucketed by original id.
void bucketFileTriangles(fch::ClusterSource& reader, fch::WindowBuckets<fch::TriangleKey>& out) {
  reader.forEachFacePiece([&](const fch::FacePiece& piece) {
    for (size_t t = 0; t < piece.originalFace.size(); ++t) {
      const uint64_t id = piece.originalFace[t];
      out.add(id, fch::TriangleKey(id, piece.first + t, piece.vertices[piece.indices[3 * t]],
                                   piece.vertices[piece.indices[3 * t + 1]],
                                   piece.vertices[piece.indices[3 * t + 2]]));
    }
  });
}

// Both sides bucketed and each window sorted: for a mesh whose triangles come in any order.
VerifyResult compareInWindows(fch::ClusterSource& reader, const MeshTriangleSource& mesh) {
  const uint64_t faces = reader.header().triangleCount;
  const uint64_t budget = std::max<uint64_t>(reader.memoryBytes() / 8, 4096);
  const uint64_t window = std::max<uint64_t>(budget / (2 * sizeof(fch::TriangleKey)), 16);
  fch::WindowBuckets<fch::TriangleKey> fromFile(budget, faces, window, reader.temporaryDirectory());
  fch::WindowBuckets<fch::TriangleKey> fromMesh(budget, faces, window, reader.temporaryDirectory());

  uint64_t meshTriangles = 0;
  mesh([&](std::span<const MeshTriangle> batch) {
    for (const MeshTriangle& t : batch) {
      fromMesh.add(t.id, fch::TriangleKey(t.id, t.position, t.corner[0], t.corner[1], t.corner[2]));
      ++meshTriangles;
    }
  });
  if (meshTriangles != faces) return countMismatch(meshTriangles, faces);
  bucketFileTriangles(reader, fromFile);

  TriangleQueue fileQueue, meshQueue;
  std::vector<fch::TriangleKey> taken;
  for (uint64_t w = 0; w < fromFile.windows(); ++w) {
    takeWindow(fromFile, w, taken, fileQueue);
    takeWindow(fromMesh, w, taken, meshQueue);
    for (; !fileQueue.empty() && !meshQueue.empty(); fileQueue.pop_front(), meshQueue.pop_front())
      if (!fileQueue.front().sameKey(meshQueue.front()))
        return {false, fch::triangleMismatch(fileQueue.front(), meshQueue.front()), 0};
  }
  return {true, "", reader.nodeCount()};
}

VerifyResult againstMesh(fch::ClusterSource& reader, const MeshTriangleSource& mesh) {
  // A mesh read in order hands its triangles over by increasing id, which is the order of the sort:
  // only the file's side is bucketed, and the mesh's is compared as it comes. The first pair that
  // differs is kept while the mesh's triangles are counted, since a count that differs is the
  // verdict first. Ids out of order send the check to the windows of both sides.
  const uint64_t faces = reader.header().triangleCount;
  const uint64_t budget = std::max<uint64_t>(reader.memoryBytes() / 8, 4096);
  const uint64_t window = std::max<uint64_t>(budget / sizeof(fch::TriangleKey), 16);
  fch::WindowBuckets<fch::TriangleKey> fromFile(budget, faces, window, reader.temporaryDirectory());
  bucketFileTriangles(reader, fromFile);
  TriangleQueue fileQueue;
  std::vector<fch::TriangleKey> taken;
  std::optional<std::string> mismatch;
  uint64_t meshTriangles = 0, lastId = 0, nextWindow = 0;
  bool inOrder = true;
  mesh([&](std::span<const MeshTriangle> batch) {
    for (const MeshTriangle& t : batch) {
      ++meshTriangles;
      if (!inOrder) continue;
      if (meshTriangles > 1 && t.id <= lastId) {
        inOrder = false;
        continue;
      }
      lastId = t.id;
      if (mismatch) continue;
      while (fileQueue.empty() && nextWindow < fromFile.windows())
        takeWindow(fromFile, nextWindow++, taken, fileQueue);
      if (fileQueue.empty()) continue;  // more triangles than the file: the count says so
      const fch::TriangleKey key(t.id, t.position, t.corner[0], t.corner[1], t.corner[2]);
      if (!fileQueue.front().sameKey(key)) mismatch = fch::triangleMismatch(fileQueue.front(), key);
      fileQueue.pop_front();
    }
  });
  if (!inOrder) return compareInWindows(reader, mesh);
  if (meshTriangles != faces) return countMismatch(meshTriangles, faces);
  if (mismatch) return {false, *mismatch, 0};
  return {true, "", reader.nodeCount()};
}

}  // namespace

VerifyResult verifyAgainstMesh(ClusterFileReader& reader, const MeshTriangleSource& mesh) {
  fch::ReaderSource source(reader);
  return againstMesh(source, mesh);
}

VerifyResult verifyAgainstMesh(const ClusterFile& file, const MeshView& mesh,
                               std::span<const uint64_t> meshOriginalFace) {
  const size_t faces = file.indices.size() / 3;
  if (mesh.triangleCount() != faces) return countMismatch(mesh.triangleCount(), faces);
  if (!meshOriginalFace.empty() && meshOriginalFace.size() != faces)
    return {false, "mesh: original ids do not match its triangles", 0};
  for (const uint32_t v : mesh.indices)
    if (v >= mesh.positions.size()) return {false, "mesh: vertex index out of range", 0};
  fch::MemorySource source(file);
  return againstMesh(source, [&](const std::function<void(std::span<const MeshTriangle>)>& take) {
    std::vector<MeshTriangle> batch;
    for (size_t t = 0; t < faces; ++t) {
      const uint32_t* v = &mesh.indices[3 * t];
      batch.push_back({meshOriginalFace.empty() ? t : meshOriginalFace[t],
                       t,
                       {mesh.positions[v[0]], mesh.positions[v[1]], mesh.positions[v[2]]}});
      if (batch.size() == 4096 || t + 1 == faces) take(batch), batch.clear();
    }
  });
}

}  // namespace facetree
