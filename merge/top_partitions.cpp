// lastMergesByPartitions: the order of the top's last merges, chosen over every order at once
// rather than one merge at a time.
//
// A truncated file's coarsest cuts are the top's last merges (Willmott 2000, sec. 5.5.3: the file
// keeps nodes by decreasing cost, so its cut of k clusters is the state k merges before the root).
// One merge at a time, the least increase of the fit can leave a cut of 2 or 3 clusters whose
// boxes overlap far more than a spatial split's; holding each merge to the boxes' limit instead
// can leave a later cut with several times the fit another order reaches. With n <= 8 clusters
// left, every order is a chain of set partitions, n singletons to one block, each the one before
// with two blocks joined: Bell(8) = 4,140 partitions and some 30,000 joins, over the fit
// (area x eFit, eq. 84) and box area of each of the 2^n unions. Each cut of k clusters, 1 < k < n,
// has two terms:
//  - its box areas over the limit for k (the Morton runs', morton_runs.cpp);
//  - its fit over the fit of the cut the merges one at a time reach (the least increase of the
//    fit, along the clusters' edges first, as the top merges above), so that the search departs
//    from that order only to lower its worst term.
// A chain's terms, each at least 1 (within a limit is within it), compare worst first, and then
// by the sum of the raw terms: the chain kept is the one whose worst excess on either measure is
// least, and so on down, with neither measure paid for the other. Costs O(Bell(n) x n^2) with
// partitions as sorted bytes packed in 64 bits, under a millisecond.
#include "top_partitions.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

namespace facetree {

namespace {

constexpr double kScoreTolerance = 1e-9;

// A partition: its blocks as subset masks, sorted descending, packed a byte each (0 ends it).
using Packed = uint64_t;

Packed pack(std::vector<uint8_t> blocks) {
  std::sort(blocks.begin(), blocks.end(), std::greater<>());
  Packed p = 0;
  for (size_t i = 0; i < blocks.size(); ++i) p |= Packed{blocks[i]} << (8 * i);
  return p;
}

uint8_t block(Packed p, int i) {
  return static_cast<uint8_t>(p >> (8 * i));
}

int blockCount(Packed p) {
  int k = 0;
  while (k < 8 && block(p, k) != 0) ++k;
  return k;
}

// Every partition of n elements, by restricted growth strings.
void enumerate(int n, int i, std::vector<uint8_t>& blocks, std::vector<Packed>& out) {
  if (i == n) {
    out.push_back(pack(blocks));
    return;
  }
  for (size_t b = 0; b < blocks.size(); ++b) {
    blocks[b] |= uint8_t(1u << i);
    enumerate(n, i + 1, blocks, out);
    blocks[b] &= uint8_t(~(1u << i));
  }
  blocks.push_back(uint8_t(1u << i));
  enumerate(n, i + 1, blocks, out);
  blocks.pop_back();
}

// A chain's terms (see the top of the file), each at least 1, worst first, and the sum of the raw
// terms. Chains compare by their worst term, then the next, then the sum.
struct Score {
  std::array<double, 2 * kMaxPartitionClusters> terms{};
  int count = 0;
  double sum = 0;
  void add(double raw) {
    sum += raw;
    insert(std::max(raw, 1.0));
  }
  void insert(double t) {
    int i = count++;
    while (i > 0 && terms[i - 1] < t) terms[i] = terms[i - 1], --i;
    terms[i] = t;
  }
  Score with(const Score& o) const {
    Score s = *this;
    for (int i = 0; i < o.count; ++i) s.insert(o.terms[i]);
    s.sum = sum + o.sum;
    return s;
  }
  // Terms within kScoreTolerance of each other tie: sums of the same areas in another order
  // differ in their last bits, and the order they come from decides no cut.
  static bool less(double a, double b) {
    return a < b - kScoreTolerance * std::max(std::abs(a), std::abs(b));
  }
  bool operator<(const Score& o) const {
    for (int i = 0; i < std::min(count, o.count); ++i) {
      if (less(terms[i], o.terms[i])) return true;
      if (less(o.terms[i], terms[i])) return false;
    }
    return less(sum, o.sum);
  }
};

// The merges one at a time by the least increase of the fit, a pair that shares an edge before
// any that does not, as the top's edges come before its proximity candidates, and among equal
// increases (coplanar pieces) the least growth of the boxes: each cut's partition, by k.
std::vector<Packed> greedyChain(int n, std::span<const double> fit, std::span<const double> boxArea,
                                std::span<const uint8_t> adjacent) {
  std::vector<Packed> chain(size_t(n) + 1, 0);
  std::vector<uint8_t> live, touch;
  for (int i = 0; i < n; ++i) {
    live.push_back(uint8_t(1u << i));
    touch.push_back(adjacent[i]);
  }
  chain[n] = pack(live);
  while (live.size() > 1) {
    size_t bi = 0, bj = 1;
    double least = std::numeric_limits<double>::infinity(), leastGrowth = least;
    bool near = false;
    for (size_t i = 0; i < live.size(); ++i) {
      for (size_t j = i + 1; j < live.size(); ++j) {
        const uint8_t u = live[i] | live[j];
        const bool joined = (touch[i] & live[j]) != 0;
        const double up = std::max(0.0, fit[u] - fit[live[i]] - fit[live[j]]);
        const double growth = boxArea[u] - boxArea[live[i]] - boxArea[live[j]];
        if ((joined && !near) || (joined == near && (up < least || (up == least && growth < leastGrowth))))
          least = up, leastGrowth = growth, bi = i, bj = j, near = joined;
      }
    }
    live[bi] |= live[bj];
    touch[bi] |= touch[bj];
    live.erase(live.begin() + std::ptrdiff_t(bj));
    touch.erase(touch.begin() + std::ptrdiff_t(bj));
    chain[live.size()] = pack(live);
  }
  return chain;
}

}  // namespace

std::vector<std::pair<uint8_t, uint8_t>> lastMergesByPartitions(int n, std::span<const double> fit,
                                                                std::span<const double> boxArea,
                                                                std::span<const double> boxLimit,
                                                                std::span<const uint8_t> adjacent) {
  if (n < 1 || n > kMaxPartitionClusters || fit.size() != (size_t{1} << n) || boxArea.size() != fit.size() ||
      boxLimit.size() < size_t(n) + 1 || adjacent.size() != size_t(n))
    throw std::invalid_argument("lastMergesByPartitions: bad sizes");
  std::vector<Packed> parts;
  std::vector<uint8_t> scratch;
  enumerate(n, 0, scratch, parts);
  std::sort(parts.begin(), parts.end());
  const size_t count = parts.size();
  std::vector<int> k(count);
  std::vector<double> fitSum(count, 0.0), boxSum(count, 0.0);
  for (size_t p = 0; p < count; ++p) {
    k[p] = blockCount(parts[p]);
    for (int i = 0; i < k[p]; ++i)
      fitSum[p] += fit[block(parts[p], i)], boxSum[p] += boxArea[block(parts[p], i)];
  }
  const auto indexOf = [&](Packed packed) {
    return size_t(std::lower_bound(parts.begin(), parts.end(), packed) - parts.begin());
  };
  const std::vector<Packed> greedy = greedyChain(n, fit, boxArea, adjacent);
  std::vector<double> reference(size_t(n) + 1);
  for (int c = 1; c <= n; ++c) reference[c] = fitSum[indexOf(greedy[c])];
  // The cut's own terms: the first and last partitions (n and 1 blocks) are fixed and free.
  const auto own = [&](size_t p) {
    Score s;
    if (k[p] == n || k[p] == 1) return s;
    const double limit = boxLimit[k[p]];
    if (limit > 0 && std::isfinite(limit)) s.add(boxSum[p] / limit);
    const double least = reference[k[p]];
    s.add(least > 0 ? fitSum[p] / least : (fitSum[p] > 0 ? std::numeric_limits<double>::max() : 1.0));
    return s;
  };
  // best[p]: the best chain from p to one block; next[p]: its next partition. Partitions by
  // block count ascending, so each one's coarsenings are scored before it.
  std::vector<size_t> order(count);
  for (size_t p = 0; p < count; ++p) order[p] = p;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return k[a] < k[b]; });
  std::vector<Score> best(count);
  std::vector<size_t> next(count, count);
  std::vector<uint8_t> blocks;
  for (const size_t p : order) {
    const Score mine = own(p);
    if (k[p] == 1) {
      best[p] = mine;
      continue;
    }
    bool found = false;
    for (int i = 0; i < k[p]; ++i) {
      for (int j = i + 1; j < k[p]; ++j) {
        blocks.clear();
        for (int b = 0; b < k[p]; ++b)
          if (b != i && b != j) blocks.push_back(block(parts[p], b));
        blocks.push_back(block(parts[p], i) | block(parts[p], j));
        const size_t q = indexOf(pack(blocks));
        const Score chain = mine.with(best[q]);
        if (!found || chain < best[p]) best[p] = chain, next[p] = q, found = true;
      }
    }
  }
  std::vector<std::pair<uint8_t, uint8_t>> merges;
  // The merges one at a time stand unless another order is strictly better: where the measures
  // tie (coplanar pieces, boxes that tile the same area), their order, with the top's ties by
  // area and edge, is the caller's.
  size_t p = indexOf(greedy[n]);
  Score alone;
  for (int c = 1; c < n; ++c) alone = alone.with(own(indexOf(greedy[c])));
  if (!(best[p] < alone)) return {};
  while (k[p] > 1) {
    const size_t q = next[p];
    // The block of q that p does not hold is the union; its two halves are p's blocks inside it.
    uint8_t joined = 0;
    for (int i = 0; i < k[q]; ++i) {
      const uint8_t b = block(parts[q], i);
      bool inP = false;
      for (int j = 0; j < k[p]; ++j) inP = inP || block(parts[p], j) == b;
      if (!inP) joined = b;
    }
    uint8_t first = 0, second = 0;
    for (int j = 0; j < k[p]; ++j) {
      const uint8_t b = block(parts[p], j);
      if ((b & joined) == b) (first == 0 ? first : second) = b;
    }
    merges.emplace_back(first, second);
    p = q;
  }
  return merges;
}

}  // namespace facetree
