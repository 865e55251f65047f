// The non-template parts of the external sort (facetree/storage.h): how a budget is split, and the
// storage of runs.
#include "facetree/storage.h"

namespace facetree {
namespace {

// Raw bytes per spilled block: large enough that zstd and pread run at full speed, small enough that a
// merge of budget / 64 KiB runs fits (127-way at 8 MiB, 4095-way at 256 MiB).
constexpr size_t kMaxBlockBytes = size_t{64} << 10;
// Small budgets get smaller blocks so that at least this many runs merge at once (fewer passes).
constexpr size_t kMinBlocksPerBudget = 16;
// Below this many records a budget is raised to it: the plan needs room for a 2-way merge of 1-record blocks.
constexpr size_t kMinBudgetRecords = 16;

}  // namespace

SortPlan sortPlan(size_t recordBytes, size_t budgetBytes) {
  SortPlan plan;
  plan.bufferRecords = std::max(budgetBytes / recordBytes, kMinBudgetRecords);
  const size_t budget = plan.bufferRecords * recordBytes;
  const size_t blockBytes = std::min(kMaxBlockBytes, budget / kMinBlocksPerBudget);
  plan.blockRecords = std::max<size_t>(1, blockBytes / recordBytes);
  // fanIn input blocks and one output block within the budget.
  plan.fanIn = std::max<size_t>(2, budget / (plan.blockRecords * recordBytes) - 1);
  return plan;
}

namespace sort_detail {

RunStore::RunStore(TempSpace& space, const std::string& stem)
    : file_(std::make_unique<SpillFile>(space, stem)) {}

}  // namespace sort_detail
}  // namespace facetree
