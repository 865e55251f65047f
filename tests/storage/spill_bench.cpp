// Micro benchmark of the spill infrastructure (Google Benchmark; not a ctest test): external sort
// throughput in records/s for 16- and 24-byte records, in memory and spilled, and BucketSpill appends.
// Run: spill_bench [--benchmark_filter=...]; temporary files go to $TMPDIR.
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "facetree/storage.h"

namespace facetree {
namespace {

constexpr size_t kRecords = size_t{1} << 21;  // 2M: 32 MiB of 16-byte records, 48 MiB of 24-byte ones

// Half-edge-like: a vertex-pair key with repeats (each edge twice), a face id as the tie-break.
struct Edge16 {
  uint64_t vertexPair;
  uint64_t face;
  auto operator<=>(const Edge16&) const = default;
};
struct Edge24 {
  uint64_t vertexPair;
  uint64_t face;
  uint32_t cell;
  uint32_t corner;
  auto operator<=>(const Edge24&) const = default;
};

template <class Record>
std::vector<Record> makeEdges() {
  std::mt19937_64 rng(1);
  std::vector<Record> records(kRecords);
  for (size_t i = 0; i < kRecords; ++i) {
    Record& r = records[i];
    r = Record{};
    r.vertexPair = (rng() % (kRecords / 2)) << 20 | (rng() % 1024);
    r.face = i;
  }
  return records;
}

// budgetShift: the budget is the data size >> budgetShift (0: everything in memory).
template <class Record>
void sortEdges(benchmark::State& state) {
  const std::vector<Record> input = makeEdges<Record>();
  const size_t budget = (kRecords * sizeof(Record)) >> state.range(0);
  TempSpace space;
  std::vector<Record> out(4096);
  size_t runs = 0;
  uint64_t tempBytes = 0;
  for (auto _ : state) {
    ExternalSorter<Record> sorter(space, "bench", budget);
    for (const Record& r : input) sorter.push(r);
    sorter.finish();
    uint64_t checksum = 0;
    for (size_t n; (n = sorter.read(out)) > 0;) checksum += out[n - 1].face;
    benchmark::DoNotOptimize(checksum);
    runs = sorter.runs();
    tempBytes = space.peakBytes();
  }
  state.SetItemsProcessed(state.iterations() * kRecords);
  state.SetBytesProcessed(state.iterations() * kRecords * sizeof(Record));
  state.counters["runs"] = static_cast<double>(runs);
  state.counters["temp_ratio"] =
      static_cast<double>(tempBytes) / static_cast<double>(kRecords * sizeof(Record));
}
BENCHMARK_TEMPLATE(sortEdges, Edge16)->Arg(0)->Arg(4)->ArgName("budget_shift")->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(sortEdges, Edge24)->Arg(0)->Arg(4)->ArgName("budget_shift")->Unit(benchmark::kMillisecond);

// The face spill pattern: records scattered over many cells, each with a 64 KiB buffer, then read back.
void bucketSpill(benchmark::State& state) {
  const size_t buckets = static_cast<size_t>(state.range(0));
  const std::vector<Edge24> input = makeEdges<Edge24>();
  std::vector<uint32_t> bucketOf(kRecords);
  std::mt19937_64 rng(2);
  for (uint32_t& b : bucketOf) b = static_cast<uint32_t>(rng() % buckets);
  TempSpace space;
  SpillCodec codec;
  for (auto _ : state) {
    BucketSpill spill(space, "bench", buckets, sizeof(Edge24), 64 << 10);
    for (size_t i = 0; i < kRecords; ++i) spill.append(bucketOf[i], &input[i]);
    spill.flushAll();
    std::vector<std::byte> back;
    for (size_t b = 0; b < buckets; ++b) {
      back.clear();
      spill.readBucket(b, back, codec);
    }
    benchmark::DoNotOptimize(back.data());
  }
  state.SetItemsProcessed(state.iterations() * kRecords);
  state.SetBytesProcessed(state.iterations() * kRecords * sizeof(Edge24));
}
BENCHMARK(bucketSpill)->Arg(16)->Arg(256)->ArgName("buckets")->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace facetree

BENCHMARK_MAIN();
