// Pieces that share no edge in the exact greedy (ClusterMerger, engine/cluster_merger.h): they
// join by the same cost through proximity candidates between the boxes of different components
// (top/proximity.h), and what stays apart at the end joins in Huffman order of face count, ties by
// Morton rank.
#include <algorithm>
#include <cmath>
#include <numeric>
#include <queue>
#include <tuple>

#include "engine/cluster_merger.h"

namespace facetree {

namespace {

// Candidates each cluster proposes: enough that the pieces' candidate graph is mostly connected
// at once (what stays apart proposes again when the edges run out).
constexpr uint32_t kProximityNeighbours = 6;

}  // namespace

bool ClusterMerger::addCandidates(bool betweenRoots) {
  if (!betweenRoots) candidatesAdded_ = true;
  std::vector<uint32_t> live;
  live.reserve(live_);
  for (uint32_t c = 0; c < clusters_.size(); ++c)
    if (clusters_[c].node != kDead) live.push_back(c);
  std::vector<uint32_t> label(live.size());
  if (betweenRoots) {
    std::iota(label.begin(), label.end(), 0u);
  } else {
    components_ = componentLabels(live, label);
    if (components_ <= 1) return false;
  }
  std::vector<AxisBox> boxes(live.size());
  for (size_t i = 0; i < live.size(); ++i) boxes[i] = boxes_[live[i]];
  const std::vector<std::pair<uint32_t, uint32_t>> pairs = nearestPairs(boxes, label, kProximityNeighbours);
  std::exchange(boxes, {});
  final_ = final_ || betweenRoots;
  bool changed = false;
  for (const auto& [p, q] : pairs) {
    const uint32_t a = live[p], b = live[q];
    if (edgeBetween(a, b) != kNone) continue;
    const uint32_t e = graph_.edgeCount();
    if (e >= kMaxEdges) break;
    graph_.edges.push_back({{a, b}, {graph_.head[a], graph_.head[b]}, 0.0f, 0.0f});
    graph_.head[a] = 2 * e;
    graph_.head[b] = 2 * e + 1;
    graph_.edges[e].key = key(stats_[a], stats_[b], 0.0, a, b, true);
    exactShared_.push_back(0.0);
    candidate_.push_back(1);
    if (inTop_) topEdges_.push_back(e);
    changed = true;
  }
  if (betweenRoots) {
    for (uint32_t e = 0; e < graph_.edgeCount(); ++e) {
      DualEdge& edge = graph_.edges[e];
      if (edge.end[0] == kNone || edge.key != kBlockedKey) continue;
      edge.key =
          key(stats_[edge.end[0]], stats_[edge.end[1]], edge.shared, edge.end[0], edge.end[1], candidate_[e]);
      changed = true;
    }
  }
  rebuildHeap();
  return changed;
}

uint32_t ClusterMerger::componentLabels(std::span<const uint32_t> live, std::vector<uint32_t>& label) const {
  std::vector<uint32_t> component;
  std::vector<uint8_t> seen(graphComponents(graph_, component), 0);
  uint32_t count = 0;
  for (size_t i = 0; i < live.size(); ++i) {
    label[i] = component[live[i]];
    count += seen[label[i]] == 0;
    seen[label[i]] = 1;
  }
  return count;
}

void ClusterMerger::joinComponents() {
  const uint32_t n = static_cast<uint32_t>(clusters_.size());
  std::vector<std::pair<glm::dvec3, uint32_t>> centroids;
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
  for (uint32_t c = 0; c < n; ++c) {
    if (clusters_[c].node == kDead) continue;
    const ClusterStats& s = stats_[c];
    glm::dvec3 p = s.area > 0 ? s.firstMoment / s.area : glm::dvec3(0.0);
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) p = glm::dvec3(0.0);
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
    centroids.emplace_back(p, c);
  }
  std::vector<std::pair<uint64_t, uint32_t>> roots;
  roots.reserve(centroids.size());
  for (const auto& [p, c] : centroids) roots.emplace_back(mortonCode(p, lo, hi), c);
  std::exchange(centroids, {});
  std::sort(roots.begin(), roots.end());
  using Root = std::tuple<uint64_t, uint32_t, uint32_t>;  // (face count, Morton rank, cluster id)
  std::priority_queue<Root, std::vector<Root>, std::greater<Root>> queue;
  for (uint32_t rank = 0; rank < roots.size(); ++rank) {
    const uint32_t c = roots[rank].second;
    queue.emplace(clusters_[c].faceCount, rank, c);
  }
  std::exchange(roots, {});
  while (queue.size() > 1) {
    const auto [countA, rankA, a] = queue.top();
    queue.pop();
    const auto [countB, rankB, b] = queue.top();
    queue.pop();
    const bool aFirst = rankA < rankB;
    merge(aFirst ? a : b, aFirst ? b : a, kNone, 0);
    queue.emplace(countA + countB, std::min(rankA, rankB), aFirst ? a : b);
  }
}

}  // namespace facetree
