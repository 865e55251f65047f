// The read, count, grid and bin tasks of a binary PLY or STL read in ranges (job/work_directory.h).
// Face records have one size, so task i reads its faces straight from the input, and every step
// reads its range again rather than spilling it. The tasks of a step depend only on the steps
// before, and the binned segments in range order are what the single process's one pass makes.
#include <algorithm>
#include <limits>
#include <optional>

#include "facetree/grid.h"
#include "facetree/stream.h"
#include "job/work_directory.h"
#include "stages/stages.h"

namespace facetree {
namespace {

// Faces a read task takes when the job does not say. A task's fixed cost (a process, the plan
// loaded, buffers of a quarter of the cap first touched) is about that of reading 2^18 faces.
constexpr uint64_t kFacesPerReadTask = uint64_t{1} << 20;
// A range is read in chunks of about this many bytes of the cap per face (readPlyFaceRange's
// buffers and the records made of them), a quarter of the cap at most.
constexpr uint64_t kChunkBytesPerFace = 160;
// An STL's bin task holds a vertex id per corner of its range: 12 bytes a face, an eighth of the cap.
constexpr uint64_t kSoupRangeShare = 8;

size_t chunkFaces(uint64_t cap) {
  return static_cast<size_t>(std::clamp<uint64_t>(cap / 4 / kChunkBytesPerFace, 4096, uint64_t{1} << 20));
}

// The input of a plan read in ranges: a binary PLY, or a binary STL (plan.soup).
struct RangeInput {
  std::optional<PlyFaceRanges> ply;
  std::optional<StlFaceRanges> stl;
};
RangeInput reopen(const ClusterJob& job, const RangePlan& plan) {
  RangeInput input;
  if (plan.soup)
    input.stl = stlFaceRanges(job.input);
  else
    input.ply = plyFaceRanges(job.input);
  if (!input.ply && !input.stl)
    throw Error(ErrorCategory::Input, job.input.string() + ": no longer a binary " +
                                          (plan.soup ? "STL" : "PLY") +
                                          " read in ranges (changed since the plan)");
  return input;
}

}  // namespace

unsigned rangeTasksAtOnce(uint64_t cap, bool stl) {
  if (stl) return 1;
  const uint64_t taskFixedBytes = CellGrid::kBins * sizeof(uint32_t) + (uint64_t{4} << 20);
  return static_cast<unsigned>(std::clamp<uint64_t>(cap / 2 / taskFixedBytes, 1, 1024));
}

unsigned binTasksSharingGrid(uint64_t cap) {
  const uint64_t grid = CellGrid::kBins * sizeof(uint32_t), taskFixedBytes = uint64_t{4} << 20;
  if (cap / 2 <= grid) return 1;
  return static_cast<unsigned>(std::clamp<uint64_t>((cap / 2 - grid) / taskFixedBytes, 1, 1024));
}

unsigned rangeTasksAtOnce(const PlanState& plan) {
  return rangeTasksAtOnce(plan.memoryCap, plan.rangePlan.weldTasks > 0);
}

namespace {

struct RangeTask {
  PlanState plan;
  uint64_t firstFace = 0, faces = 0, firstVertex = 0, vertices = 0;
};
RangeTask rangeTask(const WorkDirectory& work, std::string_view step, uint32_t task, unsigned sharing) {
  RangeTask t{loadPlanManifest(work)};
  const RangePlan& r = t.plan.rangePlan;
  if (!t.plan.ranges || task + 1 >= r.faceBounds.size())
    throw std::invalid_argument("no " + std::string(step) + " task " + std::to_string(task) + " in " +
                                work.string());
  t.plan.memoryCap /= std::max(1u, sharing);  // the task's share, for its buffers; the plan is the plan's
  t.firstFace = r.faceBounds[task];
  t.faces = r.faceBounds[task + 1] - t.firstFace;
  t.firstVertex = r.vertexBounds[task];
  t.vertices = r.vertexBounds[task + 1] - t.firstVertex;
  return t;
}

// The range's triangles as the single process's read makes them (FaceRecord: corner positions,
// vertex ids, face id), those touching a non-finite vertex left out and counted. Returns that count.
uint64_t forEachRecord(const ClusterJob& job, const char* phase, const RangeInput& file, const RangeTask& t,
                       ReadStats& stats, const std::function<void(std::span<const FaceRecord>)>& take) {
  std::vector<FaceRecord> records;
  uint64_t skipped = 0, done = 0;
  const auto read = [&](const std::function<void(std::span<const Triangle>)>& sink) {
    if (file.stl)
      readStlFaceRange(*file.stl, t.firstFace, t.faces, chunkFaces(t.plan.memoryCap), sink, stats);
    else
      readPlyFaceRange(*file.ply, t.firstFace, t.faces, chunkFaces(t.plan.memoryCap), sink, stats);
  };
  read([&](std::span<const Triangle> triangles) {
    records.clear();
    for (const Triangle& tri : triangles) {
      FaceRecord r{};
      if (makeFaceRecord(tri.vertex, tri.face, tri.position, r))
        records.push_back(r);
      else
        ++skipped;
    }
    take(records);
    done += triangles.size();
    checkJobProgress(job, phase, done, t.faces);
  });
  return skipped;
}

// A read task's results.
struct RangeRead {
  glm::vec3 min, max;
  uint64_t triangles = 0, maxFace = 0;
  ReadStats stats;  // faces, triangles handed on, degenerate and skipped ones, non-finite vertices
};
static_assert(std::is_trivially_copyable_v<RangeRead>);

// Every read task's results, summed: the mesh's extent (framed) and the read's report; their
// samples of an STL's corners in `sample`, when given.
MeshExtent readExtent(const WorkDirectory& work, const PlanState& plan, JobReport& report,
                      std::vector<PositionBits>* sample = nullptr) {
  const auto tasks = static_cast<uint32_t>(plan.rangePlan.faceBounds.size() - 1);
  MeshExtent extent;
  extent.min = glm::vec3(std::numeric_limits<float>::infinity());
  extent.max = -extent.min;
  report = plan.report;
  for (uint32_t i = 0; i < tasks; ++i) {
    ManifestReader in = work.read(taskManifestPath(work, "read", i), taskKind("read"));
    const auto r = in.take<RangeRead>();
    const std::vector<PositionBits> taken = in.takeVector<PositionBits>();
    in.finish();
    if (sample) sample->insert(sample->end(), taken.begin(), taken.end());
    extent.min = glm::min(extent.min, r.min);
    extent.max = glm::max(extent.max, r.max);
    extent.triangles += r.triangles;
    extent.maxFace = std::max(extent.maxFace, r.maxFace);
    report.stats.faces += r.stats.faces;
    report.stats.triangles += r.stats.triangles;
    report.stats.degenerateTriangles += r.stats.degenerateTriangles;
    report.stats.skippedTriangles += r.stats.skippedTriangles;
    report.stats.nonFiniteVertices += r.stats.nonFiniteVertices;
  }
  return extent;
}

// A count task's nonzero bins and their faces.
struct RangeCounts {
  std::vector<uint32_t> bins, faces;
};
RangeCounts loadCounts(const WorkDirectory& work, uint32_t task) {
  ManifestReader in = work.read(taskManifestPath(work, "count", task), taskKind("count"));
  RangeCounts c{in.takeVector<uint32_t>(), in.takeVector<uint32_t>()};
  in.finish();
  if (c.bins.size() != c.faces.size() ||
      std::any_of(c.bins.begin(), c.bins.end(), [](uint32_t b) { return b >= CellGrid::kBins; }))
    throw Error(ErrorCategory::Input, taskManifestPath(work, "count", task).string() + ": bins out of range");
  return c;
}

std::filesystem::path binFacesPath(const WorkDirectory& work, uint32_t task) {
  return work / binnedFile(binTaskStem(task) + "cell-faces");
}
std::filesystem::path binGhostsPath(const WorkDirectory& work, uint32_t task) {
  return work / binnedFile(binTaskStem(task) + "ghosts");
}

// The grid manifest's fields, in order; the bin tasks' indexes when `bins`.
void loadGridManifest(const WorkDirectory& work, PlanState& s, bool bins, bool owners) {
  ManifestReader in = work.read(gridPath(work), kGridKind);
  reportFields(in, s.report);
  s.extent = in.take<MeshExtent>();
  s.plan = in.take<OutOfCorePlan>();
  s.cellCount = in.take<uint32_t>();
  s.owners = owners ? takeOwners(in, work, gridPath(work)) : (in.takeView(), nullptr);
  s.splitBins = in.takeVector<CellGrid::SplitBin>();
  s.splitSeen = in.takeVector<uint64_t>();
  s.bounds = in.takeVector<uint32_t>();
  in.finish();
  const size_t tasks = s.rangePlan.faceBounds.size() - 1;
  if (s.splitSeen.size() != tasks * s.splitBins.size())
    throw Error(ErrorCategory::Input, gridPath(work).string() + ": split bins of another plan");
  if (!bins) return;
  // The binned spills' files; their indexes stay in the bin tasks' manifests until a cells task
  // reads its own cells' part of them (BucketSpill::openSegments).
  for (uint32_t i = 0; i < tasks; ++i) {
    s.facesFiles.push_back(binFacesPath(work, i));
    s.ghostsFiles.push_back(binGhostsPath(work, i));
  }
}

// The input when `job` reads it in ranges: a binary PLY or STL that the single process's read would
// take out of core (runJob): positions over their budget, or the in-core estimate over the cap. An
// STL's vertices are its distinct positions, unknown until welded: when its triangles alone do not
// pass the cap, the mesh is read whole and the cap decided as the single process decides it.
std::optional<RangeInput> rangedInput(const ClusterJob& job) {
  if (job.input == "-" || job.load.weldPositions) return std::nullopt;
  RangeInput file;
  file.ply = plyFaceRanges(job.input);
  if (!file.ply) file.stl = stlFaceRanges(job.input);
  if (!file.ply && !file.stl) return std::nullopt;
  const uint64_t cap = jobMemoryCap(job);
  const uint64_t faces = file.stl ? file.stl->faceCount : file.ply->faceCount;
  const uint64_t vertices = file.stl ? 0 : file.ply->vertexCount;
  if (!(job.forceCellFaces > 0 || vertices * sizeof(glm::vec3) > positionsBudget(cap) ||
        inCoreEstimate(faces, vertices) > cap))
    return std::nullopt;
  return file;
}

}  // namespace

RangedInput readsInRanges(const ClusterJob& job) {
  const std::optional<RangeInput> input = rangedInput(job);
  return !input ? RangedInput::None : input->stl ? RangedInput::Stl : RangedInput::Ply;
}

bool planRanges(const ClusterJob& job, const WorkDirectory& work, StagePlan& result) {
  const std::optional<RangeInput> input = rangedInput(job);
  if (!input) return false;
  const RangeInput& file = *input;
  const bool soup = file.stl.has_value();
  const uint64_t cap = jobMemoryCap(job);
  const uint64_t faces = soup ? file.stl->faceCount : file.ply->faceCount;
  const uint64_t vertices = soup ? 0 : file.ply->vertexCount;
  checkOutputWritable(job.output);
  const ClusterJob effective = effectiveJob(job);
  const OutOfCorePlan plan = planCells(effective, cap);
  uint64_t tasks = job.readTasks ? job.readTasks : (faces + kFacesPerReadTask - 1) / kFacesPerReadTask;
  if (soup) {  // a bin task's vertex ids within its share of the cap, its corners numbered in 32 bits
    const uint64_t rangeFaces =
        std::clamp<uint64_t>(cap / kSoupRangeShare / (3 * sizeof(uint32_t)), 1, uint64_t{UINT32_MAX} / 3);
    tasks = std::max(tasks, (faces + rangeFaces - 1) / rangeFaces);
  }
  tasks = std::clamp<uint64_t>(tasks, 1, std::max<uint64_t>(faces, 1));
  std::vector<uint64_t> faceBounds, vertexBounds;
  for (uint64_t i = 0; i <= tasks; ++i) {
    faceBounds.push_back(faces * i / tasks);
    vertexBounds.push_back(vertices * i / tasks);
  }
  JobReport& report = result.report;
  report.outOfCore = true;
  report.memoryCap = cap;
  report.info = soup ? file.stl->info : file.ply->info;
  report.stats.vertices = vertices;
  report.stats.inputBytes = soup ? file.stl->fileBytes : file.ply->fileBytes;
  report.cellFaceLimit = plan.cellFaceLimit;
  ManifestWriter out;
  out.putBytes(jobFingerprint(job));
  out.put(false);
  reportFields(out, report);
  out.put(true);  // read in ranges
  out.put(cap);
  out.put(plan);
  out.putVector(faceBounds);
  out.putVector(vertexBounds);
  out.put(soup);
  out.put(soup ? static_cast<uint32_t>(tasks) : uint32_t{0});  // weld tasks: one per range
  work.commit(out, planPath(work), kPlanKind);
  result.next = stepsAfterPlan(loadPlanManifest(work));
  result.rangeTasksAtOnce = rangeTasksAtOnce(cap, soup);
  return true;
}

bool runReadTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task, unsigned sharing) {
  const std::filesystem::path path = taskManifestPath(work, "read", task);
  if (work.has(path)) return false;
  const RangeTask t = rangeTask(work, "read", task, sharing);
  const RangeInput file = reopen(job, t.plan.rangePlan);
  std::optional<WeldSampler> sampler;
  if (file.stl) sampler.emplace(t.plan.rangePlan, t.faces);
  RangeRead r;
  r.min = glm::vec3(std::numeric_limits<float>::infinity());
  r.max = -r.min;
  r.stats.skippedTriangles =
      forEachRecord(job, "read", file, t, r.stats, [&](std::span<const FaceRecord> records) {
        for (const FaceRecord& f : records) {
          for (int i = 0; i < 9; ++i) {
            r.min[i % 3] = std::min(r.min[i % 3], f.position[i]);
            r.max[i % 3] = std::max(r.max[i % 3], f.position[i]);
          }
          r.maxFace = std::max(r.maxFace, f.face);
        }
        r.triangles += records.size();
        if (sampler) sampler->add(records);
      });
  r.stats.triangles -= r.stats.skippedTriangles;
  if (file.ply) r.stats.nonFiniteVertices = countNonFiniteVertices(*file.ply, t.firstVertex, t.vertices);
  ManifestWriter out;
  out.put(r);
  out.putVector(sampler ? sampler->sample() : std::vector<PositionBits>{});
  work.commit(out, path, taskKind("read"));
  return true;
}

bool runCountTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task, unsigned sharing,
                  TempSpace* accountTo) {
  const std::filesystem::path path = taskManifestPath(work, "count", task);
  if (work.has(path)) return false;
  const RangeTask t = rangeTask(work, "count", task, sharing);
  JobReport report;
  std::vector<PositionBits> sample;
  const MeshExtent extent = readExtent(work, t.plan, report, &sample);
  const RangeInput file = reopen(job, t.plan.rangePlan);
  CellGrid grid(extent.min, extent.max);
  // An STL's corners go to their weld buckets on the way.
  TaskContext run(job, t.plan.memoryCap, work, report, accountTo);
  const StageContext& context = run.stage;
  std::optional<WeldPartition> weld;
  if (file.stl)
    weld.emplace(context, work, task, t.plan.rangePlan,
                 weldSplitters(std::move(sample), t.plan.rangePlan.weldTasks));
  ReadStats stats;
  forEachRecord(job, "count", file, t, stats, [&](std::span<const FaceRecord> records) {
    for (const FaceRecord& r : records) grid.count(grid.faceBin(r.corner(0), r.corner(1), r.corner(2)));
    if (weld) weld->add(records);
  });
  RangeCounts counts;
  const std::span<const uint32_t> table = grid.ownerTable();  // the counts, before any partition
  for (uint32_t b = 0; b < table.size(); ++b)
    if (table[b] != 0) {
      counts.bins.push_back(b);
      counts.faces.push_back(table[b]);
    }
  ManifestWriter out;
  out.putVector(counts.bins);
  out.putVector(counts.faces);
  if (weld) weld->commit();  // before the count manifest, which marks the task done
  work.commit(out, path, taskKind("count"));
  return true;
}

bool runGridStep(const ClusterJob& job, const WorkDirectory& work) {
  if (work.has(gridPath(work))) return false;
  PlanState state = loadPlanManifest(work);
  if (!state.ranges)
    throw std::invalid_argument("no grid step in " + work.string() + ": the plan binned the mesh");
  const auto tasks = static_cast<uint32_t>(state.rangePlan.faceBounds.size() - 1);
  JobReport report;
  MeshExtent extent = readExtent(work, state, report);
  if (state.rangePlan.soup) report.stats.vertices = weldVertices(work, state.rangePlan, report.info.name);
  TaskContext run(job, state.memoryCap, work, report);
  const StageContext& context = run.stage;
  frameExtent(context, extent);

  CellGrid grid(extent.min, extent.max);
  for (uint32_t i = 0; i < tasks; ++i) {
    const RangeCounts counts = loadCounts(work, i);
    for (size_t k = 0; k < counts.bins.size(); ++k) grid.count(counts.bins[k], counts.faces[k]);
  }
  const std::vector<uint32_t> binFaces(grid.ownerTable().begin(), grid.ownerTable().end());
  OutOfCorePlan plan = state.plan;
  grid.partition(plan.cellFaceLimit);
  planLeaves(plan, extent.triangles);
  const uint32_t cells = grid.cellCount();
  report.cells = cells;
  report.cellFaceLimit = plan.cellFaceLimit;

  // The faces of each cell, and of each split bin those of the ranges before each range.
  std::vector<CellGrid::SplitBin> split = grid.splitBins();
  std::vector<uint64_t> cellFaces(cells, 0);
  const std::span<const uint32_t> owners = grid.ownerTable();
  for (uint32_t b = 0; b < CellGrid::kBins; ++b) cellFaces[owners[b]] += binFaces[b];
  const uint64_t limit = std::max<uint64_t>(plan.cellFaceLimit, 1);
  for (const CellGrid::SplitBin& s : split) {
    cellFaces[s.firstCell] -= binFaces[s.bin];
    for (uint64_t left = binFaces[s.bin], c = s.firstCell; left > 0; ++c) {
      cellFaces[c] += std::min(left, limit);
      left -= std::min(left, limit);
    }
  }
  std::vector<uint64_t> seen(size_t{tasks} * split.size(), 0);
  if (!split.empty()) {
    std::vector<uint64_t> sum(split.size(), 0);
    for (uint32_t i = 0; i < tasks; ++i) {
      const RangeCounts counts = loadCounts(work, i);
      for (size_t k = 0; k < split.size(); ++k) {
        seen[size_t{i} * split.size() + k] = sum[k];
        const auto at = std::lower_bound(counts.bins.begin(), counts.bins.end(), split[k].bin);
        if (at != counts.bins.end() && *at == split[k].bin)
          sum[k] += counts.faces[size_t(at - counts.bins.begin())];
      }
    }
  }
  ManifestWriter out;
  reportFields(out, report);
  out.put(extent);
  out.put(plan);
  out.put(cells);
  putOwners(out, owners);
  out.putVector(split);
  out.putVector(seen);
  out.putVector(cellTaskBounds(cellFaces, cellsTaskCount(job, cells)));
  work.commit(out, gridPath(work), kGridKind);
  return true;
}

bool runBinTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task, unsigned sharing,
                TempSpace* accountTo) {
  const std::filesystem::path path = taskManifestPath(work, "bin", task);
  if (work.has(path)) return false;
  RangeTask t = rangeTask(work, "bin", task, sharing);
  loadGridManifest(work, t.plan, /*bins=*/false, /*owners=*/true);
  PlanState& state = t.plan;
  JobReport report;
  TaskContext run(job, state.memoryCap, work, report, accountTo);
  const StageContext& context = run.stage;
  BinnedFaces binned = restoredBins(state, work);
  std::vector<CellGrid::SplitBin> split = state.splitBins;
  for (size_t k = 0; k < split.size(); ++k) split[k].seen = state.splitSeen[size_t{task} * split.size() + k];
  try {
    binned.grid->resumeSplitBins(split, state.plan.cellFaceLimit);
  } catch (const std::invalid_argument& e) {
    throw Error(ErrorCategory::Input, gridPath(work).string() + ": " + e.what());
  }
  const RangeInput file = reopen(job, state.rangePlan);
  // An STL's corners take the ids the weld tasks gave their positions.
  std::vector<uint32_t> ids;
  if (file.stl) ids = weldIds(run.temp, work, state.rangePlan, task);
  std::vector<FaceRecord> welded;
  ReadStats stats;
  distributeFaces(context, binned, binTaskStem(task), t.faces, [&](const auto& take) {
    forEachRecord(job, "bin", file, t, stats, [&](std::span<const FaceRecord> records) {
      if (!file.stl) return take(records);
      welded.assign(records.begin(), records.end());
      for (FaceRecord& r : welded)
        for (int k = 0; k < 3; ++k) {
          r.vertex[k] = ids[3 * (r.face - t.firstFace) + uint64_t(k)];
          if (r.vertex[k] == kNoVertex)
            throw Error(ErrorCategory::Input, work.string() + ": face " + std::to_string(r.face) +
                                                  " has a corner no weld task numbered");
        }
      take(welded);
    });
  });
  ManifestWriter out;
  out.putBytes(binned.faces.front()->index());
  out.putBytes(binned.ghosts.front()->index());
  work.commit(out, path, taskKind("bin"));
  return true;
}

void loadGrid(const WorkDirectory& work, PlanState& state, bool bins, bool owners) {
  loadGridManifest(work, state, bins, owners);
}

std::vector<StageStep> stepsAfterGrid(const PlanState& state) {
  return {{"bin", static_cast<uint32_t>(state.rangePlan.faceBounds.size() - 1)},
          {"cells", static_cast<uint32_t>(state.bounds.size() - 1)},
          {"upper", 1}};
}

}  // namespace facetree
