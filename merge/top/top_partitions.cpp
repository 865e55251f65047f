// lastMergesByPartitions: the order of the top's last merges, chosen over every order at once. With
// n <= 8 clusters left, every order is a chain of set partitions (Bell(8) = 4,140). Each cut of a
// chain has two terms, its box areas over the Morton runs' limit and its fit (area x eFit, eq. 84)
// over the top's own order's; the chain kept is the one whose worst term is least, with no root
// higher than the order one at a time's (Willmott 2000, sec. 5.5.3: a file's cut of k clusters is
// the state k merges before the root).
#include "top/top_partitions.h"

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

// The partitions a list of merges passes through, by k; throws unless each merge joins two
// blocks of the partition before it.
std::vector<Packed> chainOf(int n, std::span<const std::pair<uint8_t, uint8_t>> merges) {
  if (merges.size() != size_t(std::max(n - 1, 0)))
    throw std::invalid_argument("lastMergesByPartitions: the order one at a time has the wrong length");
  std::vector<Packed> chain(size_t(n) + 1, 0);
  std::vector<uint8_t> live;
  for (int i = 0; i < n; ++i) live.push_back(uint8_t(1u << i));
  chain[n] = pack(live);
  for (const auto& [a, b] : merges) {
    const auto ia = std::find(live.begin(), live.end(), a), ib = std::find(live.begin(), live.end(), b);
    if (a == b || ia == live.end() || ib == live.end())
      throw std::invalid_argument("lastMergesByPartitions: the order one at a time joins no two clusters");
    *ia = uint8_t(a | b);
    live.erase(ib);
    chain[live.size()] = pack(live);
  }
  return chain;
}

// The root's height after the merges (a valid order, chainOf), over clusters of these heights.
uint32_t rootHeight(int n, std::span<const std::pair<uint8_t, uint8_t>> merges,
                    std::span<const uint32_t> height) {
  std::vector<uint32_t> h(size_t{1} << n, 0);
  for (int i = 0; i < n; ++i) h[size_t{1} << i] = height[i];
  for (const auto& [a, b] : merges) h[a | b] = std::max(h[a], h[b]) + 1;
  return h[(size_t{1} << n) - 1];
}

}  // namespace

std::vector<std::pair<uint8_t, uint8_t>> lastMergesByPartitions(
    int n, std::span<const double> fit, std::span<const double> boxArea, std::span<const double> boxLimit,
    std::span<const std::pair<uint8_t, uint8_t>> alone, std::span<const uint32_t> height) {
  if (n < 1 || n > kMaxPartitionClusters || fit.size() != (size_t{1} << n) || boxArea.size() != fit.size() ||
      boxLimit.size() < size_t(n) + 1 || height.size() != size_t(n))
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
  const std::vector<Packed> aloneChain = chainOf(n, alone);
  std::vector<double> reference(size_t(n) + 1);
  for (int c = 1; c <= n; ++c) reference[c] = fitSum[indexOf(aloneChain[c])];
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
  // Forward, n blocks to one: best[p] the best chain from the singletons to p, its blocks'
  // heights (in p's block order), the partition before it and the two of its blocks joined. A chain's score
  // is the multiset of its cuts' terms, so the best chain through p starts with the best chain to p. A join
  // is taken only while the blocks can still be joined to one within the root height of the order one at a
  // time: sum of 2^height <= 2^root (Kraft's inequality), so the search never raises the tree.
  struct State {
    Score score;
    std::array<uint32_t, kMaxPartitionClusters> height{};
    size_t before = 0;
    std::pair<uint8_t, uint8_t> join{};
    bool reached = false;
  };
  std::vector<State> best(count);
  std::vector<size_t> order(count);
  for (size_t p = 0; p < count; ++p) order[p] = p;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return k[a] > k[b]; });
  const size_t start = indexOf(aloneChain[n]);
  best[start].reached = true;
  for (int i = 0; i < n; ++i)
    best[start].height[i] = height[std::countr_zero(unsigned(block(parts[start], i)))];
  const uint32_t bound = rootHeight(n, alone, height);
  const double root = std::ldexp(1.0, int(bound));
  std::vector<std::pair<uint8_t, uint32_t>> blocks;
  for (const size_t p : order) {
    if (!best[p].reached || k[p] == 1) continue;
    for (int i = 0; i < k[p]; ++i) {
      for (int j = i + 1; j < k[p]; ++j) {
        blocks.clear();
        for (int b = 0; b < k[p]; ++b)
          if (b != i && b != j) blocks.emplace_back(block(parts[p], b), best[p].height[b]);
        blocks.emplace_back(block(parts[p], i) | block(parts[p], j),
                            std::max(best[p].height[i], best[p].height[j]) + 1);
        double kraft = 0;
        for (const auto& [mask, h] : blocks) kraft += std::ldexp(1.0, int(h));
        if (kraft > root) continue;
        std::sort(blocks.begin(), blocks.end(), std::greater<>());
        Packed packed = 0;
        for (size_t b = 0; b < blocks.size(); ++b) packed |= Packed{blocks[b].first} << (8 * b);
        const size_t q = indexOf(packed);
        const Score chain = best[p].score.with(own(q));
        if (best[q].reached && !(chain < best[q].score)) continue;
        best[q].score = chain;
        best[q].before = p;
        best[q].join = {block(parts[p], i), block(parts[p], j)};
        best[q].reached = true;
        for (size_t b = 0; b < blocks.size(); ++b) best[q].height[b] = blocks[b].second;
      }
    }
  }
  // The merges one at a time stand unless another order is strictly better: where the measures
  // tie (coplanar pieces, boxes that tile the same area), their order, with the top's ties by
  // area and edge, is the caller's.
  Score taken;
  for (int c = 1; c < n; ++c) taken = taken.with(own(indexOf(aloneChain[c])));
  size_t p = indexOf(aloneChain[1]);
  if (!best[p].reached || !(best[p].score < taken)) return {};
  std::vector<std::pair<uint8_t, uint8_t>> merges;
  for (; p != start; p = best[p].before) merges.push_back(best[p].join);
  std::reverse(merges.begin(), merges.end());
  return merges;
}

}  // namespace facetree
