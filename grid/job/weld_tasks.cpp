// The weld of a binary STL read in ranges (job/work_directory.h): each distinct position gets the
// vertex id the single process's weld gives it (stages/weld_arrival.cpp), its rank among the mesh's
// distinct positions, through a sample sort (Blelloch et al. 1991): the read samples each range's
// corners, the count files them into buckets at the sample's splitters, a weld task numbers its
// bucket's distinct positions, and the bin adds the bucket's first id.
#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

#include "facetree/storage.h"
#include "job/work_directory.h"
#include "stages/weld_corner.h"

namespace facetree {
namespace {

// Sampled corners per weld bucket: a bucket's share of the corners then varies by a few percent.
constexpr uint64_t kSamplesPerBucket = 256;

// A corner's number within its weld bucket, filed under its range.
struct WeldedCorner {
  uint32_t slot;  // 3 * its triangle's place in the range + corner
  uint32_t id;    // its position's rank among the bucket's distinct positions
};
static_assert(sizeof(WeldedCorner) == 8);

std::filesystem::path cornersPath(const WorkDirectory& work, uint32_t countTask) {
  return work / ("count-" + std::to_string(countTask) + "-corners.spill");
}
// Its index, apart from the count task's bins: every weld task reads every one of them.
std::filesystem::path cornersIndexPath(const WorkDirectory& work, uint32_t countTask) {
  return work / ("count-" + std::to_string(countTask) + "-corners.manifest");
}
constexpr std::string_view kCornersKind = "weld corners";
std::filesystem::path weldedPath(const WorkDirectory& work, uint32_t weldTask) {
  return work / ("weld-" + std::to_string(weldTask) + "-ids.spill");
}

// Each bucket's buffer when `buckets` share an eighth of the cap.
size_t bucketBuffer(uint64_t cap, size_t buckets, size_t record) {
  const uint64_t bytes =
      std::clamp<uint64_t>(cap / 8 / std::max<size_t>(buckets, 1), 64 * record, uint64_t{1} << 20);
  return static_cast<size_t>(bytes / record * record);
}

uint32_t rangeCount(const RangePlan& plan) {
  return static_cast<uint32_t>(plan.faceBounds.size() - 1);
}

struct WeldTaskResult {
  uint64_t distinct = 0;
  std::string index;
};
WeldTaskResult loadWeldTask(const WorkDirectory& work, uint32_t task) {
  ManifestReader in = work.read(taskManifestPath(work, "weld", task), taskKind("weld"));
  WeldTaskResult r;
  r.distinct = in.take<uint64_t>();
  r.index = in.takeBytes();
  in.finish();
  return r;
}

}  // namespace

WeldSampler::WeldSampler(const RangePlan& plan, uint64_t faces) {
  const uint64_t want = (kSamplesPerBucket * plan.weldTasks + rangeCount(plan) - 1) / rangeCount(plan);
  stride_ = std::max<uint64_t>(1, 3 * faces / std::max<uint64_t>(want, 1));
}

void WeldSampler::add(std::span<const FaceRecord> records) {
  for (const FaceRecord& r : records)
    for (int k = 0; k < 3; ++k, ++seen_)
      if (seen_ % stride_ == 0) sample_.push_back(positionBits(r, k));
}

std::vector<PositionBits> weldSplitters(std::vector<PositionBits> sample, uint32_t buckets) {
  std::sort(sample.begin(), sample.end());
  std::vector<PositionBits> splitters;
  if (sample.empty()) return splitters;
  for (uint64_t b = 1; b < buckets; ++b) splitters.push_back(sample[b * sample.size() / buckets]);
  return splitters;
}

WeldPartition::WeldPartition(const StageContext& context, const WorkDirectory& work, uint32_t task,
                             const RangePlan& plan, std::vector<PositionBits> splitters)
    : work_(work), task_(task), firstFace_(plan.faceBounds[task]), splitters_(std::move(splitters)) {
  spill_ = std::make_unique<BucketSpill>(
      context.temp, SpillFile::Named{cornersPath(work, task)}, plan.weldTasks, sizeof(CornerByPosition),
      bucketBuffer(context.memoryCap, plan.weldTasks, sizeof(CornerByPosition)), kSpillLevel,
      context.spillInBackground());
}

WeldPartition::~WeldPartition() = default;

void WeldPartition::add(std::span<const FaceRecord> records) {
  for (const FaceRecord& r : records)
    for (int k = 0; k < 3; ++k) {
      const CornerByPosition c{positionBits(r, k), task_, 3 * (r.face - firstFace_) + uint64_t(k)};
      const auto bucket =
          size_t(std::upper_bound(splitters_.begin(), splitters_.end(), c.position) - splitters_.begin());
      spill_->append(bucket, &c);
    }
}

void WeldPartition::commit() {
  spill_->commit();
  ManifestWriter out;
  out.putBytes(spill_->index());
  work_.commit(out, cornersIndexPath(work_, task_), kCornersKind);
}

bool runWeldTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task, TempSpace* accountTo) {
  const std::filesystem::path path = taskManifestPath(work, "weld", task);
  if (work.has(path)) return false;
  const PlanState state = loadPlanManifest(work);
  const RangePlan& plan = state.rangePlan;
  if (!state.ranges || !plan.soup || task >= plan.weldTasks)
    throw std::invalid_argument("no weld task " + std::to_string(task) + " in " + work.string());
  const uint32_t ranges = rangeCount(plan);
  JobReport report;
  TaskContext run(job, state.memoryCap, work, report, accountTo);
  const StageContext& context = run.stage;
  const uint64_t cap = state.memoryCap;

  // Bucket `task` of every count task's spill, sorted.
  std::vector<std::filesystem::path> paths;
  for (uint32_t i = 0; i < ranges; ++i) paths.push_back(cornersPath(work, i));
  BucketSpill::SegmentReader segments(run.temp, paths, task, task + 1);
  for (uint32_t i = 0; i < ranges; ++i) {
    ManifestReader in = work.read(cornersIndexPath(work, i), kCornersKind);
    segments.add(in.takeView());
    in.finish();
  }
  std::vector<uint32_t> records;
  const std::unique_ptr<BucketSpill> corners = segments.finish(records);
  const uint64_t total = corners->records(task);
  CornersByPosition sorted(run.temp, "weld-position", std::max<uint64_t>(cap / 6, uint64_t{4} << 20));
  SpillCodec codec;
  uint64_t done = 0;
  corners->forEachBlock(task, codec, [&](std::span<const std::byte> bytes) {
    const auto* c = reinterpret_cast<const CornerByPosition*>(bytes.data());
    const size_t n = bytes.size() / sizeof(CornerByPosition);
    for (size_t i = 0; i < n; ++i) {
      CornerByPosition corner;
      std::memcpy(&corner, c + i, sizeof corner);
      if (corner.input >= ranges)
        throw Error(ErrorCategory::Input, work.string() + ": weld bucket " + std::to_string(task) +
                                              " holds a corner of no range of the plan");
      sorted.push(corner);
    }
    done += n;
    context.checkCancel("weld", done / 2, total);
  });
  sorted.finish();

  // Numbered in order, filed by range.
  BucketSpill out(run.temp, SpillFile::Named{weldedPath(work, task)}, ranges, sizeof(WeldedCorner),
                  bucketBuffer(cap, ranges, sizeof(WeldedCorner)), kSpillLevel, context.spillInBackground());
  uint64_t numbered = 0;
  const uint64_t distinct = numberPositions(sorted, [&](const CornerByPosition& c, uint64_t id) {
    const WeldedCorner w{static_cast<uint32_t>(c.slot), static_cast<uint32_t>(id)};
    out.append(c.input, &w);
    if (++numbered % 4096 == 0) context.checkCancel("weld", total / 2 + numbered / 2, total);
  });
  out.commit();
  ManifestWriter manifest;
  manifest.put(distinct);
  manifest.putBytes(out.index());
  work.commit(manifest, path, taskKind("weld"));
  return true;
}

uint64_t weldVertices(const WorkDirectory& work, const RangePlan& plan, const std::string& name) {
  uint64_t vertices = 0;
  for (uint32_t b = 0; b < plan.weldTasks; ++b) vertices += loadWeldTask(work, b).distinct;
  if (vertices > kNoVertex)
    throw Error(ErrorCategory::Input,
                name + ": more than " + std::to_string(kNoVertex) + " distinct vertex positions");
  return vertices;
}

std::vector<uint32_t> weldIds(TempSpace& temp, const WorkDirectory& work, const RangePlan& plan,
                              uint32_t range) {
  const uint32_t ranges = rangeCount(plan);
  const uint64_t faces = plan.faceBounds[range + 1] - plan.faceBounds[range];
  std::vector<uint32_t> ids(3 * faces, kNoVertex);
  std::vector<std::filesystem::path> paths;
  for (uint32_t b = 0; b < plan.weldTasks; ++b) paths.push_back(weldedPath(work, b));
  BucketSpill::SegmentReader segments(temp, paths, range, range + 1);
  std::vector<uint64_t> first(plan.weldTasks, 0);  // each bucket's first id
  uint64_t next = 0;
  for (uint32_t b = 0; b < plan.weldTasks; ++b) {
    const WeldTaskResult r = loadWeldTask(work, b);
    first[b] = next;
    next += r.distinct;
    segments.add(r.index);
  }
  std::vector<uint32_t> records;  // records[b * ranges + range]: bucket b's corners of this range
  const std::unique_ptr<BucketSpill> welded = segments.finish(records);
  SpillCodec codec;
  uint32_t bucket = 0;
  uint64_t left = plan.weldTasks ? records[range] : 0;
  welded->forEachBlock(range, codec, [&](std::span<const std::byte> bytes) {
    const size_t n = bytes.size() / sizeof(WeldedCorner);
    for (size_t i = 0; i < n; ++i) {
      while (left == 0 && bucket + 1 < plan.weldTasks) left = records[size_t{++bucket} * ranges + range];
      WeldedCorner w;
      std::memcpy(&w, bytes.data() + i * sizeof w, sizeof w);
      if (left == 0 || w.slot >= ids.size())
        throw Error(ErrorCategory::Input, weldedPath(work, bucket).string() + ": a corner past range " +
                                              std::to_string(range) + "'s triangles");
      ids[w.slot] = static_cast<uint32_t>(first[bucket] + w.id);
      --left;
    }
  });
  return ids;
}

void removeWeldCorners(const WorkDirectory& work, const RangePlan& plan) {
  for (uint32_t i = 0; i < rangeCount(plan); ++i) {
    std::filesystem::remove(cornersPath(work, i));
    work.remove(cornersIndexPath(work, i));
  }
}

void removeWeldIds(const WorkDirectory& work, const RangePlan& plan) {
  for (uint32_t b = 0; b < plan.weldTasks; ++b) {
    std::filesystem::remove(weldedPath(work, b));
    work.remove(taskManifestPath(work, "weld", b));
  }
}

}  // namespace facetree
