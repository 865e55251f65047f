// nearestPairs: k nearest boxes of another label by box gap, through a bounding volume hierarchy
// built by median splits of the box centres along their widest axis (leaves of kLeafBoxes). A query
// walks it depth first, nearer child first, and prunes a node whose lower bound, (gap to the node's
// box, distance to the node's box of centres), is past the k-th best found, or whose boxes all carry
// the query's own label. Orders compare (gap^2, centre distance^2, index) exactly in double, so
// the pairs do not depend on the walk.
#include "top/proximity.h"

#include "cost/surface_stats.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

namespace facetree {

namespace {

constexpr uint32_t kLeafBoxes = 4;
// A box accepts at most this many times k proposals, the nearest.
constexpr uint32_t kAcceptedPerProposed = 2;
constexpr uint32_t kMixed = std::numeric_limits<uint32_t>::max();

struct TreeNode {
  AxisBox box;      // of its boxes
  AxisBox centres;  // of its boxes' centres
  uint32_t label;   // the one label of all its boxes, or kMixed
  uint32_t first;   // a leaf: its boxes [first, first + count) of the order; else its first child
  uint32_t count;   // 0 for an inner node, whose children are first and first + 1
};

double squaredDistance(const glm::vec3& p, const AxisBox& b) {
  double sum = 0;
  for (int i = 0; i < 3; ++i) {
    const double d = std::max({0.0, double(b.lo[i]) - double(p[i]), double(p[i]) - double(b.hi[i])});
    sum += d * d;
  }
  return sum;
}

double squaredDistance(const glm::vec3& p, const glm::vec3& q) {
  double sum = 0;
  for (int i = 0; i < 3; ++i) {
    const double d = double(p[i]) - double(q[i]);
    sum += d * d;
  }
  return sum;
}

struct Candidate {
  double gap, centre;  // both squared
  uint32_t index;
  bool operator<(const Candidate& o) const {
    if (gap != o.gap) return gap < o.gap;
    if (centre != o.centre) return centre < o.centre;
    return index < o.index;
  }
};

class BoxTree {
 public:
  // Over the boxes that are not empty, and not of label `without`.
  BoxTree(std::span<const AxisBox> boxes, std::span<const uint32_t> label, uint32_t without = kMixed)
      : boxes_(boxes), label_(label) {
    for (uint32_t i = 0; i < boxes.size(); ++i)
      if (!boxes[i].empty() && label[i] != without) order_.push_back(i);
    centre_.resize(boxes.size());  // also of the queries it leaves out
    for (uint32_t i = 0; i < boxes.size(); ++i)
      if (!boxes[i].empty()) centre_[i] = boxes[i].centre();
    if (order_.empty()) return;
    nodes_.reserve(2 * order_.size() / kLeafBoxes + 2);
    nodes_.push_back({});
    build(0, 0, static_cast<uint32_t>(order_.size()));
  }

  const std::vector<uint32_t>& order() const { return order_; }

  // The k nearest boxes to box q of a label other than q's, nearest first.
  void nearest(uint32_t q, uint32_t k, std::vector<Candidate>& best, std::vector<uint32_t>& stack) const {
    best.clear();
    stack.clear();
    if (nodes_.empty() || k == 0) return;
    const AxisBox& box = boxes_[q];
    const glm::vec3 centre = centre_[q];
    const uint32_t own = label_[q];
    const auto bound = [&](const TreeNode& node) {
      return Candidate{squaredBoxGap(box, node.box), squaredDistance(centre, node.centres), 0};
    };
    const auto pruned = [&](const Candidate& b) {
      if (best.size() < k) return false;
      const Candidate& worst = best.back();
      return b.gap > worst.gap || (b.gap == worst.gap && b.centre > worst.centre);
    };
    stack.push_back(0);
    while (!stack.empty()) {
      const TreeNode& node = nodes_[stack.back()];
      stack.pop_back();
      if (node.label == own || pruned(bound(node))) continue;
      if (node.count == 0) {
        const TreeNode& a = nodes_[node.first];
        const TreeNode& b = nodes_[node.first + 1];
        const bool aFirst = !(bound(b) < bound(a));
        stack.push_back(aFirst ? node.first + 1 : node.first);  // the farther one waits
        stack.push_back(aFirst ? node.first : node.first + 1);
        continue;
      }
      for (uint32_t at = node.first; at < node.first + node.count; ++at) {
        const uint32_t j = order_[at];
        if (label_[j] == own) continue;
        const Candidate c{squaredBoxGap(box, boxes_[j]), squaredDistance(centre, centre_[j]), j};
        if (best.size() == k && !(c < best.back())) continue;
        if (best.size() == k) best.pop_back();
        best.insert(std::upper_bound(best.begin(), best.end(), c), c);
      }
    }
  }

 private:
  void build(uint32_t at, uint32_t first, uint32_t count) {
    TreeNode node{};
    node.label = label_[order_[first]];
    for (uint32_t i = first; i < first + count; ++i) {
      const uint32_t b = order_[i];
      node.box = AxisBox::united(node.box, boxes_[b]);
      node.centres.add(centre_[b]);
      if (label_[b] != node.label) node.label = kMixed;
    }
    if (count <= kLeafBoxes) {
      node.first = first;
      node.count = count;
      nodes_[at] = node;
      return;
    }
    const glm::vec3 extent = node.centres.hi - node.centres.lo;
    const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
    const uint32_t half = count / 2;
    const auto begin = order_.begin() + first;
    std::nth_element(begin, begin + half, begin + count, [&](uint32_t a, uint32_t b) {
      const float ca = centre_[a][axis], cb = centre_[b][axis];
      return ca != cb ? ca < cb : a < b;
    });
    node.first = static_cast<uint32_t>(nodes_.size());
    node.count = 0;
    nodes_[at] = node;
    nodes_.push_back({});
    nodes_.push_back({});
    build(node.first, first, half);
    build(node.first + 1, first + half, count - half);
  }

  std::span<const AxisBox> boxes_;
  std::span<const uint32_t> label_;
  std::vector<uint32_t> order_;
  std::vector<glm::vec3> centre_;
  std::vector<TreeNode> nodes_;
};

// The box the moments imply: each axis centroid +- sqrt(3 variance).
AxisBox momentBox(const ClusterStats& stats) {
  AxisBox box;
  if (!(stats.area > 0)) return box;
  const glm::dvec3 mean = stats.firstMoment / stats.area;
  const SymMat3 c = stats.covariance();
  const glm::dvec3 half(std::sqrt(3.0 * std::max(0.0, c.xx())), std::sqrt(3.0 * std::max(0.0, c.yy())),
                        std::sqrt(3.0 * std::max(0.0, c.zz())));
  box.lo = glm::vec3(mean - half);
  box.hi = glm::vec3(mean + half);
  return box;
}

}  // namespace

AxisBox clusterBox(const SurfaceStats& stats) {
  const AxisBox given{stats.boundsMin, stats.boundsMax};
  return given.empty() ? momentBox(toClusterStats(stats)) : given;
}

std::vector<std::pair<uint32_t, uint32_t>> nearestPairs(std::span<const AxisBox> boxes,
                                                        std::span<const uint32_t> label, uint32_t k) {
  const BoxTree tree(boxes, label);
  // The largest label's boxes (a mesh's main piece) search a tree without them: in the whole tree
  // their walk would open every node near them that holds another label's box, to skip their own.
  uint32_t largest = kMixed;
  size_t most = 0;
  {
    std::vector<uint32_t> labels;
    for (const uint32_t q : tree.order()) labels.push_back(label[q]);
    std::sort(labels.begin(), labels.end());
    for (size_t begin = 0, end = 0; begin < labels.size(); begin = end) {
      for (end = begin; end < labels.size() && labels[end] == labels[begin]; ++end) {
      }
      if (end - begin > most) most = end - begin, largest = labels[begin];
    }
  }
  // Labels of one box each (the roots' final joins) have nothing of their own to skip.
  std::optional<BoxTree> others;
  if (most > 1) others.emplace(boxes, label, largest);
  // Proposals as (proposed, proposer) in 8 bytes; their distances are recomputed per proposed box.
  std::vector<std::pair<uint32_t, uint32_t>> proposals;
  proposals.reserve(tree.order().size() * k);
  {
    std::vector<Candidate> best;
    std::vector<uint32_t> stack;
    for (const uint32_t q : tree.order()) {
      (others && label[q] == largest ? *others : tree).nearest(q, k, best, stack);
      for (const Candidate& c : best) proposals.emplace_back(c.index, q);
    }
  }
  std::sort(proposals.begin(), proposals.end());
  // A box that many propose (a small piece beside a large one) accepts the nearest
  // kAcceptedPerProposed x k; a pair proposed both ways is kept when either side accepts it.
  std::vector<std::pair<uint32_t, uint32_t>> accepted;
  accepted.reserve(proposals.size());
  std::vector<Candidate> from;
  for (size_t begin = 0, end = 0; begin < proposals.size(); begin = end) {
    const uint32_t to = proposals[begin].first;
    for (end = begin; end < proposals.size() && proposals[end].first == to; ++end) {
    }
    from.clear();
    const glm::vec3 centre = boxes[to].centre();
    for (size_t i = begin; i < end; ++i) {
      const uint32_t q = proposals[i].second;
      from.push_back({squaredBoxGap(boxes[to], boxes[q]), squaredDistance(centre, boxes[q].centre()), q});
    }
    const size_t keep = std::min<size_t>(from.size(), kAcceptedPerProposed * k);
    std::partial_sort(from.begin(), from.begin() + static_cast<ptrdiff_t>(keep), from.end());
    for (size_t i = 0; i < keep; ++i)
      accepted.emplace_back(std::min(to, from[i].index), std::max(to, from[i].index));
  }
  std::exchange(proposals, {});
  std::sort(accepted.begin(), accepted.end());
  accepted.erase(std::unique(accepted.begin(), accepted.end()), accepted.end());
  return accepted;
}

}  // namespace facetree
