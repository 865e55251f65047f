// The write as tasks of the stages (job/work_directory.h): after the cells, the upper step joins them
// (leaf graph, merge above) and writes the node order and a write plan; each geometry task writes
// the frames of a range of triangles and vertices as a piece and, with exact boxes, accumulates its
// part of the upper nodes' boxes, which the boxes step merges; each node task writes the frames of
// a range of node positions as a piece, its upper nodes from the plan and its leaves' runs read in
// place from the cells tasks' spills; the layout, place and finish steps assemble the pieces. One
// process runs the same geometry and node tasks in file order into one writer of the output itself
// (writeFileHere): no pieces, no layout, no place. Node frames are self-contained (docs/FORMAT.md),
// so the file is the same bytes either way: the same records, cut into the same frames.
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <optional>
#include <random>
#include <type_traits>
#include <utility>

#include "facetree/grid.h"
#include "job/one_process_tasks.h"
#include "job/work_directory.h"
#include "stages/node_order.h"
#include "stages/stages.h"
#include "stages/upper_boxes.h"

namespace facetree {
namespace {

constexpr std::string_view kWriteKind = "write plan";
constexpr std::string_view kNodeTablesKind = "write node tables";
constexpr std::string_view kGeometryTablesKind = "write geometry tables";
// Node frames per node task: 2^20 nodes of 4,096-node frames, as many tasks as read tasks. A task's
// fixed cost (a process, the write plan loaded) is about that of writing 2^18 nodes.
constexpr uint64_t kFramesPerNodeTask = 256;
constexpr std::string_view kBoxesKind = "upper boxes";

std::filesystem::path nodeTablesPath(const WorkDirectory& work) {
  return work / "write-node-tables.manifest";
}
std::filesystem::path geometryTablesPath(const WorkDirectory& work) {
  return work / "write-geometry-tables.manifest";
}

std::filesystem::path writePlanPath(const WorkDirectory& work) {
  return work / "write.manifest";
}
std::filesystem::path nodesPiecePath(const WorkDirectory& work, uint32_t task) {
  return work / ("nodes-" + std::to_string(task) + ".piece");
}
std::filesystem::path geometryPiecePath(const WorkDirectory& work, uint32_t task) {
  return work / ("geometry-" + std::to_string(task) + ".piece");
}

// What the upper step reports beyond the plan's part (the finish prints it all).
template <class Manifest, class Report>
void upperReportFields(Manifest& m, Report& r) {
  reportFields(m, r);
  for (auto* v :
       {&r.nodes, &r.components, &r.leaves, &r.crossEdges, &r.upperComponents, &r.temporaryBytesPeak})
    m.field(*v);
  for (auto* v : {&r.height, &r.balancedHeight}) m.field(*v);
  for (auto* v : {&r.secondsCells, &r.secondsMerge, &r.secondsWrite}) m.field(*v);
}

struct LoadedWrite {
  JobReport report;
  uint32_t cellsTasks = 0;
  std::vector<uint64_t> bounds;  // node task t: positions [bounds[t], bounds[t + 1])
  // Geometry task t: triangles [triangleBounds[t], + 1) and vertices [vertexBounds[t], + 1).
  std::vector<uint64_t> triangleBounds, vertexBounds;
  WritePlan plan;
};

// The write plan's head, listed once for the manifest that stores it and the one that reads it:
// the report, the tasks' bounds, the file's header and options, and the upper boxes' frames.
template <class Manifest>
void headFields(Manifest& m, LoadedWrite& w) {
  upperReportFields(m, w.report);
  m.field(w.cellsTasks);
  for (auto* v : {&w.bounds, &w.triangleBounds, &w.vertexBounds}) m.field(*v);
  WritePlan& p = w.plan;
  m.field(p.info.header);
  m.field(p.info.maxOriginalFace);
  m.field(p.options.zstdLevel);
  for (auto* v : {&p.options.nodesPerFrame, &p.options.geometryPerFrame}) m.field(*v);
  m.field(p.records);
  for (auto* v : {&p.compactNodes, &p.boxesInTasks}) m.field(*v);
  m.tables(p.upperOrientation, p.upperOrigin, p.upperHasOrigin, p.upperWorldAxes);
}

// The tables of the geometry tasks and of the node tasks, listed once for the manifests that store
// them (each table leaving the plan as it goes in) and those that read them back. Both hold the
// leaves' order: the geometry's copy it, the node tables' take it, so the geometry's are stored first.
template <class Manifest>
void geometryTables(Manifest& m, WritePlan& p) {
  m.field(p.leafOrder);
  m.tables(p.geometry, p.leafFirstGeometry, p.leafGeometryCount, p.leafVertices, p.leafFaces, p.upperParent,
           p.leafUpperParent);
}
template <class Manifest>
void nodeTables(Manifest& m, WritePlan& p) {
  m.tables(p.orderBlocks, p.orderFirst, p.runPosition, p.runFirst, p.leafOrder, p.leafFirstBlock,
           p.leafBlockCount, p.upperNodes, p.upperPosition, p.upperParentBox, p.upperParentPosition);
}

void saveWritePlan(const WorkDirectory& work, const JobReport& report, uint32_t cellsTasks,
                   uint32_t nodeTasks, WritePlan&& p) {
  // Node tasks on frame boundaries: nodeTasks of them, or one per kFramesPerNodeTask frames.
  const uint64_t nodes = p.info.header.nodeCount, perFrame = p.options.nodesPerFrame;
  const uint64_t frames = (nodes + perFrame - 1) / perFrame;
  const uint64_t nodeTaskCount =
      std::clamp<uint64_t>(nodeTasks ? nodeTasks : (frames + kFramesPerNodeTask - 1) / kFramesPerNodeTask, 1,
                           std::max<uint64_t>(frames, 1));
  std::vector<uint64_t> bounds;
  for (uint64_t t = 0; t <= nodeTaskCount; ++t)
    bounds.push_back(std::min(nodes, frames * t / nodeTaskCount * perFrame));
  // Geometry tasks on frame boundaries of both sections: the triangles of a part of the upper
  // boxes each (WritePlan::boxPart), and as many tasks' worth of vertex frames.
  const uint64_t triangles = p.info.header.triangleCount, vertices = p.info.header.vertexCount;
  const uint64_t frame = p.options.geometryPerFrame;
  const uint64_t part = p.boxPart;
  if (part == 0 || part % frame != 0)
    throw std::invalid_argument("box parts of " + std::to_string(part) +
                                " triangles: not whole geometry frames");
  const uint64_t geometryTasks = std::max<uint64_t>(1, (triangles + part - 1) / part);
  const uint64_t vertexFrames = (vertices + frame - 1) / frame;
  std::vector<uint64_t> triangleBounds, vertexBounds;
  for (uint64_t t = 0; t <= geometryTasks; ++t) {
    triangleBounds.push_back(std::min(triangles, t * part));
    vertexBounds.push_back(std::min(vertices, vertexFrames * t / geometryTasks * frame));
  }
  triangleBounds.back() = triangles;
  vertexBounds.back() = vertices;
  // The tables first, the head (the step's done marker) last: the steps of one task and the
  // layout read the head alone, the node and geometry tasks their own tables.
  ManifestWriter geometryManifest;
  geometryTables(geometryManifest, p);
  work.commit(geometryManifest, geometryTablesPath(work), kGeometryTablesKind);
  ManifestWriter nodeManifest;
  nodeTables(nodeManifest, p);
  work.commit(nodeManifest, nodeTablesPath(work), kNodeTablesKind);
  ManifestWriter out;
  LoadedWrite head{
      report,      cellsTasks, std::move(bounds), std::move(triangleBounds), std::move(vertexBounds),
      std::move(p)};
  headFields(out, head);
  work.commit(out, writePlanPath(work), kWriteKind);
}

// The head of the write plan: the report, the tasks' bounds, the file's header and options, and
// the upper boxes' frames (no tables).
LoadedWrite loadWriteHead(const WorkDirectory& work) {
  ManifestReader in = work.read(writePlanPath(work), kWriteKind);
  LoadedWrite w;
  headFields(in, w);
  in.finish();
  const WritePlan& p = w.plan;
  const auto ascendingNodes = [&](const std::vector<uint32_t>& v) {
    for (size_t k = 0; k < v.size(); ++k)
      if (v[k] >= p.upperOrientation.size() || (k > 0 && v[k] <= v[k - 1])) return false;
    return true;
  };
  if (w.bounds.size() < 2 || w.triangleBounds.size() != w.vertexBounds.size() ||
      w.triangleBounds.size() < 2 || p.upperOrigin.size() != p.upperOrientation.size() ||
      p.upperHasOrigin.size() != p.upperOrientation.size() || !ascendingNodes(p.upperWorldAxes))
    throw Error(ErrorCategory::Input, writePlanPath(work).string() + ": tables that do not fit together");
  return w;
}

// The write plan's head and the tables of the node tasks.
LoadedWrite decodeNodesPlan(const WorkDirectory& work) {
  LoadedWrite w = loadWriteHead(work);
  WritePlan& p = w.plan;
  ManifestReader in = work.read(nodeTablesPath(work), kNodeTablesKind);
  nodeTables(in, p);
  in.finish();
  if (p.orderBlocks.size() != p.orderFirst.size() || p.runPosition.size() != p.runFirst.size() ||
      p.leafFirstBlock.size() != p.leafBlockCount.size() || p.upperNodes.size() != p.upperPosition.size() ||
      (p.boxesInTasks && p.upperOrientation.size() != p.upperNodes.size()))
    throw Error(ErrorCategory::Input, nodeTablesPath(work).string() + ": tables that do not fit together");
  return w;
}

// The write plan's head and the tables of the geometry tasks.
LoadedWrite decodeGeometryPlan(const WorkDirectory& work) {
  LoadedWrite w = loadWriteHead(work);
  WritePlan& p = w.plan;
  ManifestReader in = work.read(geometryTablesPath(work), kGeometryTablesKind);
  geometryTables(in, p);
  in.finish();
  const size_t leaves = p.leafFirstGeometry.size();
  if (p.leafGeometryCount.size() != leaves || p.leafVertices.size() != leaves ||
      p.leafFaces.size() != leaves ||
      (p.boxesInTasks &&
       (p.upperParent.size() != p.upperOrientation.size() || p.leafUpperParent.size() != leaves)))
    throw Error(ErrorCategory::Input,
                geometryTablesPath(work).string() + ": tables that do not fit together");
  return w;
}

// The same, decoded once for every task of a process whose manifests are on a shelf (each task
// of its own decodes its own).
std::shared_ptr<const LoadedWrite> loadNodesPlan(const WorkDirectory& work) {
  return work.decoded<LoadedWrite>(nodeTablesPath(work), [&] { return decodeNodesPlan(work); });
}
std::shared_ptr<const LoadedWrite> loadGeometryPlan(const WorkDirectory& work) {
  return work.decoded<LoadedWrite>(geometryTablesPath(work), [&] { return decodeGeometryPlan(work); });
}

}  // namespace

bool runUpperStep(const ClusterJob& job, const WorkDirectory& work, TempSpace* runSpace, JobReport* live,
                  const std::function<void()>& recordsRead) {
  if (work.has(writePlanPath(work))) return false;
  // The grid's owner table (8 MiB) and the binned spills' indexes serve the cells tasks only.
  PlanState state = loadPlan(work, /*owners=*/false);
  if (state.inCore) throw std::invalid_argument("no upper step in " + work.string() + ": built in core");
  std::exchange(state.facesIndex, {});
  std::exchange(state.ghostsIndex, {});
  JobReport own;
  if (!live) {
    own = std::move(state.report);
    own.outOfCore = true;
  }
  JobReport& report = live ? *live : own;
  const auto tasks = static_cast<uint32_t>(state.bounds.size() - 1);
  std::optional<TaskContext> context;
  if (runSpace)
    context.emplace(job, state.memoryCap, work, report, TaskContext::RunSpace{*runSpace});
  else
    context.emplace(job, state.memoryCap, work, report);
  const TaskContext& run = *context;
  CellsOutput cells = loadCellTasks(run.temp, work, state);
  WritePlan plan = finishUpper(run.stage, state.extent, std::move(cells), recordsRead);
  report.temporaryBytesPeak = std::max(report.temporaryBytesPeak, run.temp.peakBytes());
  saveWritePlan(work, report, tasks, job.nodeTasks, std::move(plan));
  return true;
}

std::vector<StageStep> stepsAfterUpper(const WorkDirectory& work) {
  const LoadedWrite w = loadWriteHead(work);
  const auto geometry = static_cast<uint32_t>(w.triangleBounds.size() - 1);
  if (w.plan.boxesInTasks) return {{"geometry", geometry}, {"boxes", 1}};
  return {{"geometry", geometry}, {"nodes", static_cast<uint32_t>(w.bounds.size() - 1)}, {"layout", 1}};
}

std::vector<StageStep> stepsAfterBoxes(const WorkDirectory& work) {
  const LoadedWrite w = loadWriteHead(work);
  return {{"nodes", static_cast<uint32_t>(w.bounds.size() - 1)}, {"layout", 1}};
}

namespace {

std::filesystem::path boxesPath(const WorkDirectory& work) {
  return work / "boxes.manifest";
}

// The boxes step's manifest: the upper nodes' boxes, their parts merged, by file index.
void commitBoxes(const WorkDirectory& work, const WritePlan& p, const std::vector<BoxAccumulator>& boxes) {
  ManifestWriter manifest;
  manifest.putVector(upperBoxesByFileIndex(boxes, p.upperWorldAxes));
  work.commit(manifest, boxesPath(work), kBoxesKind);
}

}  // namespace

bool runBoxesStep(const ClusterJob&, const WorkDirectory& work) {
  if (work.has(boxesPath(work))) return false;
  const LoadedWrite w = loadWriteHead(work);
  const WritePlan& p = w.plan;
  if (!p.boxesInTasks) throw std::invalid_argument("no boxes step in " + work.string() + ": compact boxes");
  // The geometry tasks' parts in task order: the single process's merge (UpperBoxes), the same bits.
  std::vector<BoxAccumulator> boxes = upperFrames(p);
  const auto upperCount = static_cast<uint32_t>(p.upperOrientation.size());
  // A part's accumulator is a node's (below upperCount) or one along the world axes of a node.
  const auto hasOrigin = [&](uint32_t a) {
    return a < upperCount ? p.upperHasOrigin[a] != 0
                          : a < boxes.size() && p.upperHasOrigin[p.upperWorldAxes[a - upperCount]] != 0;
  };
  for (uint32_t t = 0; t + 1 < w.triangleBounds.size(); ++t) {
    const std::filesystem::path path = taskManifestPath(work, "geometry", t);
    ManifestReader in = work.read(path, taskKind("geometry"));
    const auto nodes = in.takeVector<uint32_t>();
    const auto sums = in.takeVector<BoxAccumulator::Sums>();
    in.finish();
    if (nodes.size() != sums.size())
      throw Error(ErrorCategory::Input, path.string() + ": box parts that do not fit together");
    for (size_t k = 0; k < nodes.size(); ++k) {
      if (!hasOrigin(nodes[k]))
        throw Error(ErrorCategory::Input, path.string() + ": a box part of node " + std::to_string(nodes[k]));
      boxes[nodes[k]].addSums(sums[k]);
    }
  }
  commitBoxes(work, p, boxes);
  return true;
}

bool runNodesTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task, ClusterFileWriter* into) {
  const std::filesystem::path piece = nodesPiecePath(work, task);
  if (!into && std::filesystem::exists(piece)) return false;
  const std::shared_ptr<const LoadedWrite> loaded = loadNodesPlan(work);
  const LoadedWrite& w = *loaded;
  if (task + 1 >= w.bounds.size())
    throw std::invalid_argument("no nodes task " + std::to_string(task) + " in " + work.string());
  const WritePlan& p = w.plan;
  const uint64_t first = w.bounds[task], end = w.bounds[task + 1];
  TempSpace temp(job.tmpDir, job.maxTemporaryBytes, job.temporaryDirectory);
  std::unique_ptr<SpillFile> runs;
  if (p.compactNodes) {
    runs = SpillFile::open(temp, work / kWriteNodesFile);
  } else {
    std::vector<std::filesystem::path> paths;
    for (uint32_t t = 0; t < w.cellsTasks; ++t)
      paths.push_back(cellTaskFile(work.path(), CellSpill::Nodes, t));
    runs = SpillFile::open(temp, paths);
  }
  std::unique_ptr<SpillFile> order = SpillFile::open(temp, work / kWriteOrderFile, sizeof(NodeRef));

  std::optional<ClusterFileWriter> pieceWriter;
  if (!into) {
    WriteOptions options = p.options;
    options.threads = job.threads;
    options.piece = PieceRange{first, end, 0, 0, 0, 0};
    pieceWriter.emplace(piece, p.info, options, temp.path());
  }
  ClusterFileWriter& writer = into ? *into : *pieceWriter;
  const auto upperCount = static_cast<uint32_t>(p.upperNodes.size());
  // Exact boxes: the boxes step's, by file index, decoded once for every task of a process whose
  // manifests are on a shelf.
  std::shared_ptr<const std::vector<NodeBox>> upperBoxes;
  if (p.boxesInTasks) {
    upperBoxes = work.decoded<std::vector<NodeBox>>(boxesPath(work), [&] {
      ManifestReader in = work.read(boxesPath(work), kBoxesKind);
      std::vector<NodeBox> boxes = in.takeVector<NodeBox>();
      in.finish();
      return boxes;
    });
    if (upperBoxes->size() != upperCount)
      throw Error(ErrorCategory::Input, boxesPath(work).string() + ": boxes of another plan");
  }
  // Parents in earlier pieces; one writer of the whole file has kept their boxes.
  if (pieceWriter && !p.upperParentBox.empty())
    for (uint32_t j = 0; j < upperCount; ++j)
      if (p.upperPosition[j] >= first && p.upperPosition[j] < end && p.upperParentPosition[j] < first)
        writer.addParentBox(p.upperPosition[j], p.upperParentBox[j]);
  writeNodeRange(
      p, *order, *runs, first, end, writer,
      [&](uint32_t j) {
        FchNode node = p.upperNodes[j];
        if (upperBoxes) node.box = (*upperBoxes)[j];
        return node;
      },
      [&](uint64_t done) { checkJobProgress(job, "write", done, end - first); });
  if (pieceWriter) pieceWriter->finish();
  return true;
}

bool runGeometryTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task,
                     const GeometryHere* here) {
  const std::filesystem::path piece = geometryPiecePath(work, task);
  if (!here && std::filesystem::exists(piece)) return false;
  const std::shared_ptr<const LoadedWrite> loaded = loadGeometryPlan(work);
  const LoadedWrite& w = *loaded;
  if (task + 1 >= w.triangleBounds.size())
    throw std::invalid_argument("no geometry task " + std::to_string(task) + " in " + work.string());
  const WritePlan& p = w.plan;
  const uint64_t firstTriangle = w.triangleBounds[task], endTriangle = w.triangleBounds[task + 1];
  const uint64_t firstVertex = w.vertexBounds[task], endVertex = w.vertexBounds[task + 1];
  const std::function<void(uint64_t)> progress = [&](uint64_t done) {
    checkJobProgress(job, "write", done, endTriangle - firstTriangle);
  };
  const GeometryRange range{firstTriangle, endTriangle, firstVertex, endVertex};
  if (here) {
    // Into the file itself, each leaf's blocks given back once the last range that reads them has:
    // the process's own, read in order.
    writeGeometryRange(p, here->geometry, range, &here->writer, here->boxes, /*discard=*/true,
                       writePlanPath(work).string(), progress);
    if (here->boxes) here->boxes->endPart();  // a task's triangles are one part
    return true;
  }
  TempSpace temp(job.tmpDir, job.maxTemporaryBytes, job.temporaryDirectory);
  std::vector<std::filesystem::path> paths;
  for (uint32_t t = 0; t < w.cellsTasks; ++t)
    paths.push_back(cellTaskFile(work.path(), CellSpill::Geometry, t));
  const std::unique_ptr<SpillFile> geometry = SpillFile::open(temp, paths, 4);
  WriteOptions options = p.options;
  options.threads = job.threads;
  options.piece = PieceRange{0, 0, firstVertex, endVertex, firstTriangle, endTriangle};
  ClusterFileWriter writer(piece, p.info, options, temp.path());
  // Exact boxes: this task's part of the upper nodes' boxes, the blocks that start in its
  // triangles.
  const std::vector<BoxAccumulator> frames = p.boxesInTasks ? upperFrames(p) : std::vector<BoxAccumulator>{};
  std::vector<uint32_t> partNodes;
  std::vector<BoxAccumulator::Sums> partSums;
  std::optional<UpperBoxes> boxes;
  if (p.boxesInTasks)
    boxes.emplace(frames, p.upperWorldAxes, job.threads > 1,
                  [&](std::span<const uint32_t> nodes, std::span<const BoxAccumulator> parts) {
                    for (size_t i = 0; i < nodes.size(); ++i) {
                      partNodes.push_back(nodes[i]);
                      partSums.push_back(parts[i].sums());
                    }
                  });
  writeGeometryRange(p, *geometry, range, &writer, boxes ? &*boxes : nullptr, /*discard=*/false,
                     writePlanPath(work).string(), progress);
  if (boxes) {  // the part before the piece: a task whose piece exists has both
    boxes->finish();
    ManifestWriter out;
    out.putVector(partNodes);
    out.putVector(partSums);
    work.commit(out, taskManifestPath(work, "geometry", task), taskKind("geometry"));
  }
  writer.finish();
  return true;
}

uint64_t writeFileHere(const ClusterJob& job, const WorkDirectory& work, TempSpace& temp) {
  const LoadedWrite w = loadWriteHead(work);
  const WritePlan& p = w.plan;
  const uint64_t triangles = p.info.header.triangleCount, total = triangles + p.info.header.nodeCount;
  WriteOptions options = p.options;
  options.threads = job.threads;
  ClusterFileWriter writer(job.output, p.info, options, temp.path());
  writer.setTemporaryBytesHook([&temp](int64_t delta) {
    if (delta > 0)
      temp.reserve(static_cast<uint64_t>(delta));
    else
      temp.release(static_cast<uint64_t>(-delta));
  });
  // The write's progress over the tasks, one after the other: each reports its own range's.
  PhaseHooks hooks(job, "write", total, 1);
  const auto taskJob = [&](uint64_t base) { return hooks.taskJob(0, job.threads, base); };
  // The cells' geometry, opened once for every geometry task: this run's alone, so each leaf's
  // blocks are given back once the last range that reads them has (every block counted first).
  std::vector<std::filesystem::path> geometryPaths;
  for (uint32_t t = 0; t < w.cellsTasks; ++t)
    geometryPaths.push_back(cellTaskFile(work.path(), CellSpill::Geometry, t));
  {
    const std::unique_ptr<SpillFile> geometry = SpillFile::open(temp, geometryPaths, 4);
    geometry->ownOpened();
    for (const SpillBlock& block : loadGeometryPlan(work)->plan.geometry) geometry->countBlock(block);
    // Exact boxes: the tasks' parts summed as they end, in the boxes step's order; the boxes
    // step's manifest from the totals.
    std::vector<BoxAccumulator> totals;
    std::optional<UpperBoxes> boxes;
    if (p.boxesInTasks) {
      totals = upperFrames(p);
      boxes.emplace(totals, p.upperWorldAxes, job.threads > 1);
    }
    const GeometryHere here{writer, *geometry, boxes ? &*boxes : nullptr};
    for (uint32_t t = 0; t + 1 < w.triangleBounds.size(); ++t)
      runGeometryTask(taskJob(w.triangleBounds[t]), work, t, &here);
    if (boxes) {
      boxes->finish();
      commitBoxes(work, p, totals);
    }
  }
  // Spent: the geometry and its tables (their decoded copy with them).
  for (const auto& path : geometryPaths) std::filesystem::remove(path);
  work.remove(geometryTablesPath(work));
  releaseFreeMemory();  // the geometry tables, before the node tasks take theirs
  for (uint32_t t = 0; t + 1 < w.bounds.size(); ++t)
    runNodesTask(taskJob(triangles + w.bounds[t]), work, t, &writer);
  return writer.finish();
}

namespace {

constexpr std::string_view kLayoutKind = "layout";

std::filesystem::path layoutPath(const WorkDirectory& work) {
  return work / "layout.manifest";
}

// Every piece of the file, geometry tasks' first.
std::vector<std::filesystem::path> piecePaths(const WorkDirectory& work, const LoadedWrite& w) {
  std::vector<std::filesystem::path> pieces;
  for (uint32_t t = 0; t + 1 < w.triangleBounds.size(); ++t) pieces.push_back(geometryPiecePath(work, t));
  for (uint32_t t = 0; t + 1 < w.bounds.size(); ++t) pieces.push_back(nodesPiecePath(work, t));
  return pieces;
}

// The file being assembled: in the work directory when it shares the output's file system (the
// finish renames it into place; a failed build leaves nothing beside the output), else beside the
// output.
std::filesystem::path partialPath(const WorkDirectory& work, const std::filesystem::path& out) {
  struct stat a {
  }, b{};
  const std::filesystem::path dir = out.has_parent_path() ? out.parent_path() : std::filesystem::path(".");
  if (::stat(work.path().c_str(), &a) == 0 && ::stat(dir.c_str(), &b) == 0 && a.st_dev == b.st_dev)
    return work / "output.fch.partial";
  return std::filesystem::path(out.string() + ".partial");
}

// The layout manifest: the file being placed, its copies, and the upper step's report for the finish.
// Its id is new at every layout: a place task's record and the finish's name the layout they were
// made for, so that a layout made again (its manifest lost, or its placed file renamed into the
// output and the output removed since) is placed again rather than taken for done.
struct Layout {
  uint64_t id = 0;
  std::string partial;
  uint64_t fileBytes = 0;
  uint32_t pieces = 0, geometryPieces = 0;  // piecePaths' order: the geometry tasks' first
  std::vector<PieceCopy> copies;
  JobReport report;
};
Layout loadLayout(const WorkDirectory& work) {
  ManifestReader in = work.read(layoutPath(work), kLayoutKind);
  Layout l;
  l.id = in.take<uint64_t>();
  l.partial = in.takeBytes();
  l.fileBytes = in.take<uint64_t>();
  l.pieces = in.take<uint32_t>();
  l.geometryPieces = in.take<uint32_t>();
  l.copies = in.takeVector<PieceCopy>();
  upperReportFields(in, l.report);
  in.finish();
  return l;
}

constexpr std::string_view kFinishedKind = "finished";
std::filesystem::path finishedPath(const WorkDirectory& work) {
  return work / "finished.manifest";
}

// Whether the finish renamed layout `l`'s placed file into `output`, and `output` is still that
// size.
bool finishedAs(const WorkDirectory& work, const Layout& l, const std::filesystem::path& output) {
  if (!work.has(finishedPath(work))) return false;
  ManifestReader in = work.read(finishedPath(work), kFinishedKind);
  const auto id = in.take<uint64_t>();
  in.finish();
  std::error_code error;
  return id == l.id && std::filesystem::file_size(output, error) == l.fileBytes && !error;
}

// The id of a layout: another at every run of the step, whatever the work directory holds.
uint64_t newLayoutId() {
  std::random_device random;
  return (uint64_t{random()} << 32) ^ random() ^
         static_cast<uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
}

// The place task's record: its task and the layout it placed its piece into.
uint64_t placedLayout(const WorkDirectory& work, const std::filesystem::path& manifest, uint32_t task) {
  ManifestReader placed = work.read(manifest, taskKind("place"));
  if (placed.take<uint32_t>() != task)
    throw Error(ErrorCategory::Input, manifest.string() + ": another task's");
  const auto id = placed.take<uint64_t>();
  placed.finish();
  return id;
}

}  // namespace

bool runLayoutStep(const ClusterJob& job, const WorkDirectory& work) {
  // Done while its placed file waits for the finish, or the finish gave it the output's name.
  if (work.has(layoutPath(work))) {
    const Layout l = loadLayout(work);
    if (std::filesystem::exists(l.partial) || finishedAs(work, l, job.output)) return false;
  }
  const LoadedWrite w = loadWriteHead(work);
  checkOutputWritable(job.output);
  const std::vector<std::filesystem::path> pieces = piecePaths(work, w);
  const std::filesystem::path partial = partialPath(work, job.output);
  const ClusterFileAssembly assembly = beginClusterFile(partial, w.plan.info, w.plan.options, pieces);
  ManifestWriter out;
  out.put(newLayoutId());
  out.putBytes(partial.string());
  out.put(assembly.fileBytes);
  out.put(static_cast<uint32_t>(pieces.size()));
  out.put(static_cast<uint32_t>(w.triangleBounds.size() - 1));
  out.putVector(assembly.copies);
  upperReportFields(out, w.report);
  work.commit(out, layoutPath(work), kLayoutKind);
  return true;
}

std::vector<StageStep> stepsAfterLayout(const WorkDirectory& work) {
  return {{"place", loadLayout(work).pieces}, {"finish", 1}};
}

bool runPlaceTask(const ClusterJob&, const WorkDirectory& work, uint32_t task) {
  const std::filesystem::path manifest = taskManifestPath(work, "place", task);
  const Layout l = loadLayout(work);
  if (task >= l.pieces)
    throw std::invalid_argument("no place task " + std::to_string(task) + " in " + work.string());
  if (work.has(manifest) && placedLayout(work, manifest, task) == l.id) return false;
  // Its one piece, named from the layout alone (the write plan is tens of MB at 56M faces).
  const std::filesystem::path piece =
      task < l.geometryPieces ? geometryPiecePath(work, task) : nodesPiecePath(work, task - l.geometryPieces);
  std::vector<PieceCopy> mine;
  for (const PieceCopy& c : l.copies)
    if (c.piece == task) mine.push_back({0, c.from, c.to, c.bytes});
  placePieces(l.partial, std::span(&piece, 1), mine);
  ManifestWriter out;
  out.put(task);
  out.put(l.id);
  work.commit(out, manifest, taskKind("place"));
  return true;
}

JobReport finishStages(const ClusterJob& job, const std::filesystem::path& directory) {
  const WorkDirectory work(directory);  // tasks in processes of their own: manifests as files
  const auto start = std::chrono::steady_clock::now();
  PlanState state = loadPlanManifest(work);
  if (state.inCore) return std::move(state.report);
  Layout l = loadLayout(work);
  for (uint32_t t = 0; t < l.pieces; ++t)
    if (placedLayout(work, taskManifestPath(work, "place", t), t) != l.id)
      throw Error(ErrorCategory::Input, taskManifestPath(work, "place", t).string() +
                                            ": placed into an earlier layout of the file; run place task " +
                                            std::to_string(t) + " again");
  JobReport report = std::move(l.report);
  report.outOfCore = true;
  if (!finishedAs(work, l, job.output)) {
    if (!std::filesystem::exists(l.partial))
      throw Error(ErrorCategory::Input, l.partial + ": the placed file is gone; run the layout step again");
    commitClusterFile(l.partial, job.output);
    ManifestWriter finished;
    finished.put(l.id);
    work.commit(finished, finishedPath(work), kFinishedKind);
  }
  report.fileBytes = l.fileBytes;
  recordStageTime(work, "finish", 0, secondsSince(start));
  addStageTimes(work, report);
  return report;
}

}  // namespace facetree
