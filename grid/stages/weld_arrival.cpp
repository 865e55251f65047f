// The out-of-core build, read stage: welding corners at bit-identical positions with bounded memory.
//
// Why: STL has no vertex indices (its reader welds with a hash table as large as the mesh's
// distinct positions, past any cap on a large mesh), and --weld asks the
// same of indexed inputs. Here every corner of the arrival spill is sorted by position
// (ExternalSorter), each distinct position gets the next vertex id in that order, the ids are
// sorted back to arrival order, and the arrival spill is rewritten with them: two sorts of
// 24- and 16-byte records, each under a sixth of the cap, the same pattern as the position
// join of stages/read.cpp.
#include <stdexcept>
#include <string>

#include "facetree/storage.h"
#include "stages/stages.h"
#include "stages/weld_corner.h"

namespace facetree {
namespace {

struct CornerId {
  uint64_t slot;
  uint32_t vertex;
  uint32_t unused;
};
static_assert(sizeof(CornerId) == 16);
struct SlotOrder {
  bool operator()(const CornerId& a, const CornerId& b) const { return a.slot < b.slot; }
};

}  // namespace

void weldArrival(const StageContext& context, ArrivalFaces& arrival) {
  SpillCodec codec;
  arrival.spill->flushAll();
  const uint64_t sortBudget = std::max<uint64_t>(context.memoryCap / 6, uint64_t{4} << 20);
  std::vector<FaceRecord> records;

  ExternalSorter<CornerId, SlotOrder> bySlot(context.temp, "weld-slot", sortBudget);
  uint64_t vertices = 0, welded = 0;
  {
    CornersByPosition byPosition(context.temp, "weld-position", sortBudget);
    uint64_t slot = 0;
    arrival.spill->forEachBlock(0, codec, [&](std::span<const std::byte> bytes) {
      decodeRecords(bytes, records);
      for (const FaceRecord& r : records) {
        for (int k = 0; k < 3; ++k, ++slot) {
          byPosition.push({positionBits(r, k), r.vertex[k], slot});
        }
      }
      context.checkCancel("weld", slot / 3, arrival.extent.triangles);
    });
    byPosition.finish();
    // Input vertices sharing a position beyond the first are the welded ones (--weld's count,
    // over the vertices the triangles use).
    CornerByPosition previous{};
    uint64_t previousId = kNoVertex;
    vertices = numberPositions(byPosition, [&](const CornerByPosition& c, uint64_t id) {
      if (id == kNoVertex)
        throw Error(ErrorCategory::Input, context.report.info.name + ": more than " +
                                              std::to_string(kNoVertex) + " distinct vertex positions");
      if (id == previousId && c.input != previous.input && c.input != kNoVertex) ++welded;
      bySlot.push({c.slot, static_cast<uint32_t>(id), 0});
      previous = c;
      previousId = id;
    });
  }
  bySlot.finish();

  auto rewritten = std::make_unique<BucketSpill>(context.temp, "arrival-welded", 1, sizeof(FaceRecord),
                                                 kArrivalBufferBytes, kSpillLevel, /*discardable=*/true,
                                                 context.spillInBackground());
  std::vector<CornerId> ids(3);
  uint64_t slot = 0;
  arrival.spill->forEachBlock(0, codec, [&](std::span<const std::byte> bytes) {
    decodeRecords(bytes, records);
    for (FaceRecord& r : records) {
      if (bySlot.read(ids) != 3 || ids[0].slot != slot || ids[2].slot != slot + 2)
        throw std::logic_error("out-of-core build: the weld lost a corner");
      for (int k = 0; k < 3; ++k) r.vertex[k] = ids[k].vertex;
      slot += 3;
      rewritten->append(0, &r);
    }
    context.checkCancel("weld", slot / 3, arrival.extent.triangles);
  });
  arrival.spill = std::move(rewritten);
  arrival.spill->releaseBuffers();
  context.report.stats.vertices = vertices;
  context.report.weldedVertices = welded;
}

}  // namespace facetree
