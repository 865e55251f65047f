// orderTop: the order in which the file opens the hierarchy, top down. The file's cut of k clusters
// is its first k - 1 nodes (Willmott 2000, sec. 5.5.3); here the top's nodes and those below them
// are ordered by what expanding a node removes from the cut's fit, the sum of area x eFit (eq. 84)
// over its clusters, looking a few expansions ahead, with the cut's box areas held within the top's
// limit. The placed nodes are re-costed above every other node, so that the prefix is this order in
// core and out of core alike.
#include "top/top_order.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "top/proximity.h"

namespace facetree {

namespace {

constexpr uint32_t kNoNode = 0xFFFFFFFFu;
// Expansions a node's score looks ahead.
constexpr int kLookahead = 8;
// A cluster of at most this share of the top's sliver area has no surface to speak of.
constexpr double kSurfacelessShare = 1e-9;
// Each placed node's cost over the next one's: far above a float's resolution, also of the log
// keys the out-of-core write sorts by.
constexpr float kCostStep = 1.0f + 1.0f / 4096.0f;
// The least cost a placed node takes (the out-of-core keys clamp costs to 1e-30).
constexpr float kLeastCost = 1e-29f;

class TopOrder {
 public:
  TopOrder(const TopTree& tree, const std::function<double(const SurfaceStats&)>& areaFit)
      : tree_(tree), areaFit_(areaFit) {}

  uint32_t run() {
    const auto count = static_cast<uint32_t>(tree_.nodes.size());
    if (count == 0 || !isTop(count - 1)) return 0;
    std::vector<uint32_t> top;  // the top's own nodes in their own order: the last merge first
    for (uint32_t i = count; i-- > tree_.firstTop;)
      if (isTop(i)) top.push_back(i);
    size_t nextTop = 0, topLeft = top.size();
    double leafFit = 0;  // the highest area x eFit of a leaf in the cut
    sum_ = boxOf(count - 1);
    // Expands node i, which adds `grown` to the cut's box areas (its Open's growth).
    const auto expand = [&](uint32_t i, double grown) {
      sum_ += grown;
      placed_.push_back(i);
      expanded_.insert(i);
      if (isTop(i)) --topLeft;
      for (const uint32_t child : tree_.nodes[i].child) {
        if (!(child & kLeafChild))
          open_.push_back({child, score(child), growth(child)});
        else
          leafFit = std::max(leafFit, fitOf(child));
      }
    };
    expand(count - 1, growth(count - 1));
    // Top down, by score, for at most tree.orderedCuts steps, and while the best score passes
    // every leaf's fit in the cut: past that, a leaf's own splits, which the order does not see,
    // may remove more, and eq. 84's order resumes. Then the top's nodes left, in their order.
    bool ordering = true;
    while (topLeft > 0 || (ordering && placed_.size() < tree_.orderedCuts && !open_.empty())) {
      while (nextTop < top.size() && isExpanded(top[nextTop])) ++nextTop;
      const uint32_t own = nextTop < top.size() ? top[nextTop] : kNoNode;
      if (!lookThroughSurfaceless_ && placed_.size() >= top.size()) {
        // As many clusters as the top's own order holds once it has placed all its nodes: it
        // shows every cluster without surface the top attached, and the lookahead passes them.
        lookThroughSurfaceless_ = true;
        best_.clear();
        for (Open& o : open_) o.score = score(o.node);
      }
      size_t pick = open_.size();
      if (ordering && placed_.size() < tree_.orderedCuts) {
        pick = choose(own);
        if (open_[pick].score < leafFit) pick = open_.size(), ordering = false;
        if (ordering) ordered_ = placed_.size() + 1;
      }
      if (!ordering && own == kNoNode) break;
      if (pick == open_.size())
        for (size_t j = 0; j < open_.size(); ++j)
          if (open_[j].node == own) pick = j;
      const Open chosen = open_[pick];
      open_[pick] = open_.back();
      open_.pop_back();
      expand(chosen.node, chosen.growth);
    }
    recost();
    return static_cast<uint32_t>(placed_.size());
  }

 private:
  struct Open {
    uint32_t node;
    double score;
    double growth;  // what expanding it adds to the cut's box areas
  };
  using Best = std::array<double, kLookahead + 1>;
  struct Memo {
    Best value;
    int budget = 0;  // value[d] is exact for d <= budget
    double own = 0;  // gain(n), from budget 1 on
  };

  bool isTop(uint32_t i) const {
    return i >= tree_.firstTop && tree_.nodes[i].stats.area >= tree_.sliverArea;
  }
  bool isExpanded(uint32_t i) const { return expanded_.contains(i); }

  const SurfaceStats& statsOf(uint32_t ref) const {
    return (ref & kLeafChild) ? tree_.leaves[ref & ~kLeafChild] : tree_.nodes[ref].stats;
  }
  double fitOf(uint32_t ref) {
    const auto [at, added] = fit_.try_emplace(ref, 0.0);
    if (added) at->second = areaFit_(statsOf(ref));
    return at->second;
  }
  double boxOf(uint32_t ref) const { return clusterBox(statsOf(ref)).area(); }
  double gain(uint32_t i) {
    const ClusterMergeNode& node = tree_.nodes[i];
    return fitOf(i) - fitOf(node.child[0]) - fitOf(node.child[1]);
  }
  // What expanding node i adds to the cut's box areas.
  double growth(uint32_t i) const {
    const ClusterMergeNode& node = tree_.nodes[i];
    return boxOf(node.child[0]) + boxOf(node.child[1]) - boxOf(i);
  }

  // Whether expanding node i puts a cluster without surface (degenerate faces) in the cut. The top
  // joins such a cluster to the smallest cluster that takes it, to keep it out of coarse cuts: the
  // lookahead does not pass through that merge while the cut holds fewer clusters than the top's
  // own order shows with all its nodes placed.
  bool exposesSurfaceless(uint32_t i) const {
    const ClusterMergeNode& node = tree_.nodes[i];
    const double least = kSurfacelessShare * tree_.sliverArea;
    return statsOf(node.child[0]).area <= least || statsOf(node.child[1]).area <= least;
  }

  // Node n's score (see the top of the file): the best average of best(n)[d] / d.
  double score(uint32_t n) {
    const Best& b = best(n, kLookahead);
    double s = -std::numeric_limits<double>::infinity();
    for (int d = 1; d <= kLookahead; ++d)
      if (b[d] > -std::numeric_limits<double>::infinity()) s = std::max(s, b[d] / d);
    return s;
  }

  // best(n, budget)[d], d <= budget: the most gain d expansions of n's subtree remove, n's first
  // (a set of d nodes closed under parents), by the tree's knapsack over its two children; -inf
  // where n's subtree holds fewer than d nodes. Entry d needs only the children's entries below d,
  // so a node's table grows: a deeper budget adds entries and keeps those it has. Only the nodes
  // within the lookahead of an open node get one (the exact order's tree is the whole mesh's).
  const Best& best(uint32_t n, int budget) {
    Memo& memo = best_[n];  // budget 0: nothing computed yet
    if (memo.budget >= budget) return memo.value;
    Best none;  // a leaf, or a split the lookahead does not pass
    none.fill(-std::numeric_limits<double>::infinity());
    none[0] = 0;
    const bool stops = !lookThroughSurfaceless_ && isTop(n) && exposesSurfaceless(n);
    const ClusterMergeNode& node = tree_.nodes[n];
    const auto childBest = [&](uint32_t child) -> const Best& {
      return (child & kLeafChild) || stops || budget < 2 ? none : best(child, budget - 1);
    };
    const Best& a = childBest(node.child[0]);
    const Best& b = childBest(node.child[1]);
    if (memo.budget == 0) memo.value = none, memo.own = gain(n);
    const double own = memo.own;
    for (int d = memo.budget + 1; d <= budget; ++d)
      for (int x = 0; x < d; ++x)
        if (a[x] > -std::numeric_limits<double>::infinity() &&
            b[d - 1 - x] > -std::numeric_limits<double>::infinity())
          memo.value[d] = std::max(memo.value[d], own + a[x] + b[d - 1 - x]);
    memo.budget = budget;
    return memo.value;
  }

  // The open node to expand next, or open_.size() for the top's own next node `own` (kNoNode
  // when none is left).
  size_t choose(uint32_t own) const {
    const size_t cut = placed_.size() + 1;  // clusters now; one more after the step
    if (cut + 1 >= tree_.boxLimit.size()) return bestOpen(std::numeric_limits<double>::infinity());
    const double limit = tree_.boxLimit[cut + 1];
    if (cut + 1 < tree_.keptCuts && own != kNoNode) return bestOpen(std::max(limit, sum_ + growth(own)));
    if (const size_t pick = bestOpen(limit); pick < open_.size()) return pick;
    size_t pick = 0;
    for (size_t j = 1; j < open_.size(); ++j)
      if (open_[j].growth < open_[pick].growth) pick = j;
    return pick;
  }
  // The open node of the best score (ties to the later node) that leaves the cut's box areas
  // within `limit`; open_.size() when none does.
  size_t bestOpen(double limit) const {
    size_t pick = open_.size();
    for (size_t j = 0; j < open_.size(); ++j) {
      if (!(sum_ + open_[j].growth <= limit)) continue;
      if (pick == open_.size() || open_[j].score > open_[pick].score ||
          (open_[j].score == open_[pick].score && open_[j].node > open_[pick].node))
        pick = j;
    }
    return pick;
  }

  // The placed nodes above every other node's effective cost (the highest cost among them and
  // below the leaves: the others are closed under children), the ordered ones each kCostStep
  // above the next.
  void recost() {
    std::vector<uint32_t> sorted = placed_;
    std::sort(sorted.begin(), sorted.end());
    float rest = tree_.leavesCost;
    for (uint32_t i = 0, j = 0; i < tree_.nodes.size(); ++i) {
      if (j < sorted.size() && sorted[j] == i) {
        ++j;
        continue;
      }
      rest = std::max(rest, tree_.nodes[i].cost);
    }
    // The top's nodes placed after the ordered cuts share one cost: equal costs go in reverse
    // creation order, theirs, in the file and out of core alike.
    float c = std::max(rest, kLeastCost);
    const auto above = [](float x) {
      const float next = x * kCostStep;
      return next > x ? next : std::nextafter(x, std::numeric_limits<float>::infinity());
    };
    if (ordered_ < placed_.size()) c = above(c);
    for (size_t j = ordered_; j < placed_.size(); ++j) tree_.nodes[placed_[j]].cost = c;
    for (size_t j = ordered_; j-- > 0;) {
      c = above(c);
      tree_.nodes[placed_[j]].cost = c;
    }
  }

  const TopTree& tree_;
  const std::function<double(const SurfaceStats&)>& areaFit_;
  std::unordered_map<uint32_t, double> fit_;  // area x eFit by child reference, as computed
  std::unordered_map<uint32_t, Memo> best_;   // best() by node, as far as computed
  std::vector<uint32_t> placed_;              // expansion order
  size_t ordered_ = 1;                        // of which the first are ordered by score (the root)
  bool lookThroughSurfaceless_ = false;       // see exposesSurfaceless
  std::unordered_set<uint32_t> expanded_;     // the same, as a set
  std::vector<Open> open_;                    // nodes whose parent is expanded
  double sum_ = 0;                            // the cut's box areas
};

}  // namespace

uint32_t orderTop(const TopTree& tree, const std::function<double(const SurfaceStats&)>& areaFit) {
  return TopOrder(tree, areaFit).run();
}

}  // namespace facetree
