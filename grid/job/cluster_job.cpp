// runClusterJob: reads the input, in memory while the in-core build's estimated peak fits the
// cap, and hands over to the out-of-core build (with what was read so far) as soon as it does not.
#include <chrono>
#include <cmath>

#include "facetree/grid.h"
#include "facetree/io.h"
#include "job/job.h"
#include "stages/stages.h"

namespace facetree {

void JobReport::recordInCoreBuild(const Hierarchy& hierarchy, const BranchingStats& file) {
  inCore = hierarchy.stats;
  nodes = file.internalNodes;
  height = file.height;
  balancedHeight = file.balancedHeight;
  components = hierarchy.stats.components;
  cells = 1;
  leaves = 1;
}

ClusterJob effectiveJob(const ClusterJob& job) {
  ClusterJob effective = job;
  effective.file.build = job.build;
  effective.file.memoryCapBytes = job.memoryCap;
  return effective;
}

uint64_t jobMemoryCap(const ClusterJob& job) {
  return job.memoryCap ? job.memoryCap : defaultMemoryCap();
}

JobReport runClusterJob(const ClusterJob& job) {
  return runJob(job, nullptr);
}

JobReport runJob(const ClusterJob& job, const std::filesystem::path* work) {
  const auto start = std::chrono::steady_clock::now();
  JobReport report;
  const uint64_t cap = jobMemoryCap(job);
  report.memoryCap = cap;
  const ClusterJob effective = effectiveJob(job);
  const auto check = [&](const char* phase, uint64_t done, uint64_t total) {
    checkJobProgress(job, phase, done, total);
  };
  // Outputs that cannot be created fail now, not after the build.
  if (!job.output.empty()) checkOutputWritable(job.output);
  if (!job.meshOut.empty()) checkOutputWritable(job.meshOut);

  // Positions of PLY and OBJ inputs go through VertexPositions, which spills them past a quarter
  // of the cap (the reader would hold them all).
  TempSpace temp(job.tmpDir, job.maxTemporaryBytes, job.temporaryDirectory);
  // A mesh read in ranges runs the stages' own tasks, here on a pool of threads.
  if (!work && !job.output.empty() && job.meshOut.empty() && runRangesHere(job, temp, report)) {
    report.memoryCap = cap;
    report.seconds = secondsSince(start);
    report.secondsBuilt = report.seconds - report.secondsWrite;
    return report;
  }
  VertexPositions positions(temp, positionsBudget(cap));
  ReadOptions readOptions;
  readOptions.vertexSink = [&positions](std::span<const glm::vec3> p) { positions.append(p); };
  // Draco is decoded whole: refused before decoding when that alone would pass the cap.
  readOptions.wholeMeshLimitBytes = cap > kBaseBytes ? cap - kBaseBytes : 1;
  std::unique_ptr<TriangleReader> reader =
      job.input == "-" ? openStandardInput(readOptions) : openMesh(job.input, readOptions);
  const bool deferred = reader->positionsDeferred();
  PendingTriangles pending;
  bool outOfCore = job.forceCellFaces > 0;
  if (!outOfCore) {
    // The header's count, where the cap would hold that many: a hint, never trusted further.
    const uint64_t declared = reader->info().declaredFaces;
    if (declared > 0 && cap > kBaseBytes && declared <= (cap - kBaseBytes) / kInCoreBytesPerTriangle) {
      pending.indices.reserve(3 * declared);
      pending.originalFace.reserve(declared);
    }
    std::vector<Triangle> batch(kReadBatchTriangles);
    for (size_t got; (got = reader->read(batch)) > 0;) {
      for (size_t i = 0; i < got; ++i) {
        const Triangle& t = batch[i];
        pending.indices.insert(pending.indices.end(), {t.vertex[0], t.vertex[1], t.vertex[2]});
        pending.originalFace.push_back(t.face);
      }
      if (inCoreEstimate(pending.originalFace.size(), reader->vertices().size()) > cap ||
          (deferred && !positions.inMemory())) {
        outOfCore = true;
        break;
      }
      check("read", reader->stats().inputBytes, 0);
    }
  }
  if (outOfCore) {
    if (job.output.empty() || !job.meshOut.empty()) {
      constexpr uint64_t kMiB = uint64_t{1} << 20;
      throw Error(ErrorCategory::Resource,
                  reader->info().name + ": the mesh does not fit --memory " + std::to_string(cap / kMiB) +
                      " MiB in core, and " +
                      (job.output.empty() ? "without -o it cannot be built out of core"
                                          : "--mesh-out needs it in core") +
                      ": raise --memory" + (job.output.empty() ? " or give -o" : " or drop --mesh-out"));
    }
    // A reader that holds the whole mesh (Draco) keeps it through the out-of-core read and bin
    // passes: the build gets the rest of the cap (its cells are sized from that).
    const uint64_t held = reader->heldBytes();
    const uint64_t left = cap > held ? cap - held : 0;
    if (held > 0 && left < outOfCoreMinimumBytes()) {
      constexpr uint64_t kMiB = uint64_t{1} << 20;
      throw Error(ErrorCategory::Resource,
                  reader->info().name + ": the " + formatName(reader->info().format) +
                      " mesh is decoded whole (the format cannot be streamed) and holds " +
                      std::to_string((held + kMiB - 1) / kMiB) + " MiB of --memory " +
                      std::to_string(cap / kMiB) + " MiB; the out-of-core build needs " +
                      std::to_string((outOfCoreMinimumBytes() + kMiB - 1) / kMiB) +
                      " MiB beside it: raise --memory or convert the mesh to PLY, which streams");
    }
    runOutOfCore(effective, temp, deferred ? &positions : nullptr, std::move(reader), std::move(pending),
                 left, report, work);
    report.seconds = secondsSince(start);
    report.secondsBuilt = report.seconds - report.secondsWrite;
    return report;
  }

  // In core: the whole mesh in memory.
  IndexedMesh mesh;
  mesh.info = reader->info();
  mesh.stats = reader->stats();
  if (deferred) {
    mesh.positions = positions.take();
    // The reader left non-finite vertices to us: drop the triangles touching them.
    size_t kept = 0;
    const size_t n = pending.originalFace.size();
    for (size_t t = 0; t < n; ++t) {
      bool finite = true;
      for (int k = 0; k < 3; ++k) {
        const glm::vec3& p = mesh.positions[pending.indices[3 * t + k]];
        finite &= std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
      }
      if (!finite) continue;
      for (int k = 0; k < 3; ++k) pending.indices[3 * kept + k] = pending.indices[3 * t + k];
      pending.originalFace[kept++] = pending.originalFace[t];
    }
    mesh.stats.skippedTriangles += n - kept;
    mesh.stats.triangles -= n - kept;
    pending.indices.resize(3 * kept);
    pending.originalFace.resize(kept);
  } else {
    const VertexSource& vertices = reader->vertices();
    mesh.positions.resize(vertices.size());
    for (uint64_t i = 0; i < vertices.size(); ++i) mesh.positions[i] = vertices.position(i);
  }
  mesh.indices = std::move(pending.indices);
  mesh.originalFace = std::move(pending.originalFace);
  reader.reset();
  if (job.load.weldPositions) mesh.weldedVertices = weldPositions(mesh.positions, mesh.indices);
  report.weldedVertices = mesh.weldedVertices;
  report.info = mesh.info;
  report.stats = mesh.stats;
  report.triangles = mesh.originalFace.size();
  report.secondsRead = secondsSince(start);
  if (report.triangles == 0) throw Error(ErrorCategory::Input, mesh.info.name + ": no triangles to cluster");
  check("merge", 0, report.triangles);

  auto phase = std::chrono::steady_clock::now();
  const Hierarchy hierarchy = buildHierarchy(mesh.view(), effective.build);
  report.secondsMerge = secondsSince(phase);
  report.secondsBuilt = secondsSince(start);
  check("write", 0, report.triangles);

  phase = std::chrono::steady_clock::now();
  BranchingStats shape;
  if (!job.output.empty())
    report.fileBytes = writeClusterFile(
        job.output, mesh.view(), mesh.originalFace, hierarchy, effective.file,
        WriteOptions{.zstdLevel = job.zstdLevel ? job.zstdLevel : 3, .threads = job.threads}, &shape);
  else
    shape = branchingStats(hierarchy, effective.file);
  report.recordInCoreBuild(hierarchy, shape);
  if (!job.meshOut.empty()) writeReorderedMesh(mesh.view(), hierarchy, job.meshOut, job.meshOutOptions);
  report.secondsWrite = secondsSince(phase);
  report.seconds = secondsSince(start);
  return report;
}

}  // namespace facetree
