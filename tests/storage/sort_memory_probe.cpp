// Peak memory of one external sort in a fresh process (external_sort_test runs it; a forked child of the
// test would inherit the test's heap and peak RSS). Usage: sort_memory_probe RECORDS BUDGET_BYTES TMP_PARENT
// Sorts RECORDS generated 16-byte records (never held in memory) and prints one line:
//   peak_rss_growth_kib records out_of_order_pairs is_permutation runs merge_passes peak_temp_bytes
#include <sys/resource.h>

#include <cstdio>
#include <exception>
#include <fstream>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "facetree/storage.h"

namespace {

struct Record16 {
  uint64_t key;
  uint64_t payload;
};
struct Less16 {
  bool operator()(const Record16& a, const Record16& b) const {
    return std::tie(a.key, a.payload) < std::tie(b.key, b.payload);
  }
};

long residentKiB() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  throw std::runtime_error("no VmRSS in /proc/self/status");
}

uint64_t mix(const Record16& r) {
  return (r.key * 0x9E3779B97F4A7C15ull) ^ r.payload;
}

}  // namespace

int main(int argc, char** argv) try {
  if (argc != 4) {
    std::fprintf(stderr, "usage: sort_memory_probe RECORDS BUDGET_BYTES TMP_PARENT\n");
    return 2;
  }
  const uint64_t records = std::stoull(argv[1]);
  const size_t budget = std::stoull(argv[2]);
  // The peak so far is the loader's and the runtime's; start the measurement here.
  std::ofstream("/proc/self/clear_refs") << "5";
  const long before = residentKiB();

  facetree::TempSpace space(argv[3]);
  facetree::ExternalSorter<Record16, Less16> sorter(space, "edges", budget);
  std::mt19937_64 rng(5);
  uint64_t hashIn = 0;
  for (uint64_t i = 0; i < records; ++i) {
    const Record16 r{rng() % (records / 2 + 1), i};
    hashIn += mix(r);
    sorter.push(r);
  }
  sorter.finish();
  uint64_t hashOut = 0, count = 0, disorder = 0;
  std::vector<Record16> buffer(4096);
  Record16 previous{0, 0};
  for (size_t n; (n = sorter.read(buffer)) > 0;) {
    for (size_t i = 0; i < n; ++i) {
      disorder += count > 0 && !Less16{}(previous, buffer[i]);
      hashOut += mix(buffer[i]);
      previous = buffer[i];
      ++count;
    }
  }
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  std::printf("%ld %llu %llu %d %zu %zu %llu\n", usage.ru_maxrss - before,
              static_cast<unsigned long long>(count), static_cast<unsigned long long>(disorder),
              hashIn == hashOut ? 1 : 0, sorter.runs(), sorter.mergePasses(),
              static_cast<unsigned long long>(space.peakBytes()));
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "sort_memory_probe: %s\n", e.what());
  return 1;
}
