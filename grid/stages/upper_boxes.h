// Internal to grid/: the exact boxes of the upper nodes (above the leaf clusters), accumulated from
// every triangle under them as the write streams the geometry, on a helper thread when there is more
// than one (stages/write_plan.cpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/merge.h"
#include "stages/stages.h"

namespace facetree {

// The upper nodes' boxes see every triangle under them (BoxAccumulator): with more than one
// thread they accumulate on a helper while the writer's thread reads, encodes and compresses.
// Batches of leaf blocks (vertices, triangles, ancestors) go over in two alternating buffers, in
// order, so every accumulator sees the same triangles in the same runs and order as inline (the
// boxes are bit-identical). Each block is one run (TriangleRun: its a_f n_f and distinct vertices
// computed once for all its ancestors, BoxAccumulator::addRun). Memory: two batches of at most
// kBatchTriangles triangles and kBatchAncestors ancestor entries, or one leaf block's if larger (a
// block holds at most kTrianglesPerBlock, its ancestors at most the upper tree's height), and one
// run's scratch. (The ancestors need their own bound: --metric garland's upper trees can be
// thousands of levels deep, and a batch of small leaves under them lists every level per leaf.)
//
// The triangles go in parts (kBoxPartTriangles of the file's order, the geometry tasks' ranges):
// each part into fresh accumulators of the nodes it reaches, handed to `sink` (or merged into the
// totals) when it ends, in order. Every node's reference vertex is set beforehand (the first
// corner of its first leaf), so the parts merge exactly: one process and the geometry tasks sum
// the same parts in the same order.
class UpperBoxes {
 public:
  static constexpr size_t kBatchTriangles = 8192;
  static constexpr size_t kBatchAncestors = size_t{1} << 16;
  // A part's accumulators: nodes[i]'s triangles of the part are in parts[i], nodes in the order
  // the part first reached them.
  using Sink = std::function<void(std::span<const uint32_t> nodes, std::span<const BoxAccumulator> parts)>;

  // `frames`: every upper node's orientation and reference vertex (only read), then one along the
  // world axes for each node of `worldAxes` (addWorldAxes), which sees its node's triangles.
  UpperBoxes(const std::vector<BoxAccumulator>& frames, std::span<const uint32_t> worldAxes, bool helper,
             Sink sink)
      : frames_(frames),
        sink_(std::move(sink)),
        slot_(frames.size(), kNoSlot),
        world_(worldAxesSlots(worldAxes, frames.size() - worldAxes.size())) {
    start(helper);
  }
  // The parts merged into `totals` (framed, empty) as they end. A node's first part goes straight
  // into its total, the same bits as merged into an empty one: only the nodes whose triangles
  // cross a part's end (a path from the root per end) hold a second accumulator.
  UpperBoxes(std::vector<BoxAccumulator>& totals, std::span<const uint32_t> worldAxes, bool helper)
      : frames_(totals),
        totals_(&totals),
        slot_(totals.size(), kNoSlot),
        world_(worldAxesSlots(worldAxes, totals.size() - worldAxes.size())) {
    start(helper);
  }
  UpperBoxes(const UpperBoxes&) = delete;
  UpperBoxes& operator=(const UpperBoxes&) = delete;

  // The triangles `indices` (3 each, into `vertices`) of a leaf block under `ancestors`.
  void add(std::span<const glm::vec3> vertices, std::span<const uint32_t> indices,
           std::span<const uint32_t> ancestors) {
    if (ancestors.empty() || indices.empty()) return;
    Batch& b = *filling_;
    b.runs.push_back({b.vertices.size(), vertices.size(), b.indices.size(), indices.size(),
                      b.ancestors.size(), ancestors.size()});
    b.vertices.insert(b.vertices.end(), vertices.begin(), vertices.end());
    b.indices.insert(b.indices.end(), indices.begin(), indices.end());
    b.ancestors.insert(b.ancestors.end(), ancestors.begin(), ancestors.end());
    if (b.indices.size() >= 3 * kBatchTriangles || b.ancestors.size() >= kBatchAncestors) hand();
  }
  // The part so far ends here (an empty part gives the sink nothing).
  void endPart() { filling_->partEnds.push_back(filling_->runs.size()); }
  // Ends the part, and waits until every part is with the sink.
  void finish() {
    if (finished_) return;
    finished_ = true;
    endPart();
    hand();
    if (helper_) helper_->settle();
  }

 private:
  static constexpr uint32_t kNoSlot = UINT32_MAX, kTotal = UINT32_MAX - 1;
  struct Run {
    size_t vertex, vertices, index, indices, ancestor, ancestors;
  };
  struct Batch {
    std::vector<glm::vec3> vertices;
    std::vector<uint32_t> indices;
    std::vector<uint32_t> ancestors;
    std::vector<Run> runs;
    std::vector<size_t> partEnds;  // a part ends before runs[partEnds[k]]
  };

  void partOf(uint32_t node) {
    if (slot_[node] != kNoSlot) return;
    touched_.push_back(node);
    if (totals_ && (*totals_)[node].empty()) {
      slot_[node] = kTotal;
      return;
    }
    slot_[node] = static_cast<uint32_t>(partNodes_.size());
    partNodes_.push_back(node);
    partBoxes_.push_back(frames_[node].part());
  }
  BoxAccumulator* target(uint32_t node) {
    return slot_[node] == kTotal ? &(*totals_)[node] : &partBoxes_[slot_[node]];
  }
  void endPartNow() {
    if (totals_) {
      for (size_t i = 0; i < partNodes_.size(); ++i) (*totals_)[partNodes_[i]].merge(partBoxes_[i]);
    } else if (!partNodes_.empty()) {
      sink_(partNodes_, partBoxes_);
    }
    for (const uint32_t node : touched_) slot_[node] = kNoSlot;
    touched_.clear();
    partNodes_.clear();
    partBoxes_.clear();
  }
  void accumulate(Batch& b) {
    size_t end = 0;
    for (size_t i = 0; i < b.runs.size(); ++i) {
      for (; end < b.partEnds.size() && b.partEnds[end] == i; ++end) endPartNow();
      const Run& r = b.runs[i];
      run_.assign(std::span(b.vertices).subspan(r.vertex, r.vertices),
                  std::span(b.indices).subspan(r.index, r.indices));
      // Every ancestor's accumulators first: a new one may move the others.
      for (size_t k = 0; k < r.ancestors; ++k) {
        const uint32_t a = b.ancestors[r.ancestor + k];
        partOf(a);
        if (world_[a] != kNoSlot) partOf(world_[a]);
      }
      targets_.clear();
      for (size_t k = 0; k < r.ancestors; ++k) {
        const uint32_t a = b.ancestors[r.ancestor + k];
        targets_.push_back(target(a));
        if (world_[a] != kNoSlot) targets_.push_back(target(world_[a]));
      }
      BoxAccumulator::addRun(run_, targets_);
    }
    for (; end < b.partEnds.size(); ++end) endPartNow();
    b.vertices.clear();
    b.indices.clear();
    b.ancestors.clear();
    b.runs.clear();
    b.partEnds.clear();
  }
  void start(bool helper) {
    if (helper) {
      helper_.emplace([this](Batch& b, unsigned) { accumulate(b); });
      filling_ = &helper_->slot();
    }
  }
  // Gives the filled batch to the helper, and fills the other one next (once the helper is done with it).
  void hand() {
    if (!helper_) return accumulate(*filling_);
    helper_->submit();
    filling_ = &helper_->slot();
  }

  const std::vector<BoxAccumulator>& frames_;
  std::vector<BoxAccumulator>* totals_ = nullptr;
  Sink sink_;
  std::vector<uint32_t> slot_;             // per accumulator: its accumulator of the part, kTotal or kNoSlot
  std::vector<uint32_t> world_;            // per upper node: its accumulator along the world axes, or kNoSlot
  std::vector<uint32_t> touched_;          // the nodes the part reached
  std::vector<uint32_t> partNodes_;        // those with an accumulator of the part, in order
  std::vector<BoxAccumulator> partBoxes_;  // and those accumulators
  bool finished_ = false;
  TriangleRun run_;                          // scratch of accumulate()
  std::vector<BoxAccumulator*> targets_;     // a run's ancestors
  Batch inline_;                             // the one batch without a helper
  Batch* filling_ = &inline_;                // the batch this thread fills
  std::optional<HelperRing<Batch>> helper_;  // last: stops before the rest goes
};

}  // namespace facetree
