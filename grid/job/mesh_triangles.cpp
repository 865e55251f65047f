// meshTriangleSource: a mesh file's triangles as a build reads them, under a cap, for checks that
// compare a cluster file with its mesh (verifyAgainstMesh). The out-of-core read gives them: the
// positions of an indexed mesh spill past a quarter of the cap, and the triangles, with their
// corners resolved, wait in an arrival spill that is then read block by block.
#include "facetree/grid.h"
#include "stages/memory_plan.h"
#include "stages/stages.h"
#include "stages/vertex_positions.h"

namespace facetree {

MeshTriangleSource meshTriangleSource(const std::filesystem::path& mesh, uint64_t memoryCap,
                                      const std::filesystem::path& tmp) {
  return [mesh, memoryCap, tmp](const std::function<void(std::span<const MeshTriangle>)>& visit) {
    ClusterJob job;
    job.input = mesh;
    job.memoryCap = memoryCap;
    job.tmpDir = tmp;
    job.threads = 1;
    JobReport report;
    TempSpace temp(tmp);
    VertexPositions positions(temp, positionsBudget(memoryCap));
    ReadOptions readOptions;
    readOptions.vertexSink = [&positions](std::span<const glm::vec3> p) { positions.append(p); };
    readOptions.wholeMeshLimitBytes = memoryCap;
    std::unique_ptr<TriangleReader> reader = openMesh(mesh, readOptions);
    const bool deferred = reader->positionsDeferred();
    const StageContext context{job, temp, memoryCap, report, nullptr};
    ArrivalFaces arrival = readArrival(context, std::move(reader), deferred ? &positions : nullptr, {});
    SpillCodec codec;
    std::vector<FaceRecord> records;
    std::vector<MeshTriangle> batch;
    uint64_t position = 0;
    arrival.spill->drainBucket(0, codec, [&](std::span<const std::byte> bytes) {
      decodeRecords(bytes, records);
      batch.resize(records.size());
      for (size_t i = 0; i < records.size(); ++i)
        batch[i] = {
            records[i].face, position++, {records[i].corner(0), records[i].corner(1), records[i].corner(2)}};
      visit(batch);
    });
  };
}

}  // namespace facetree
