// Internal to grid/: the exact boxes of the upper nodes (above the leaf clusters), accumulated from
// every triangle under them as the write streams the geometry, on a helper thread when there is more
// than one (out_of_core_write.cpp).
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <span>
#include <thread>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/merge.h"

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
class UpperBoxes {
 public:
  static constexpr size_t kBatchTriangles = 8192;
  static constexpr size_t kBatchAncestors = size_t{1} << 16;

  UpperBoxes(std::vector<BoxAccumulator>& boxes, bool helper) : boxes_(boxes) {
    if (helper) thread_ = std::thread([this] { run(); });
  }
  ~UpperBoxes() { finish(); }
  UpperBoxes(const UpperBoxes&) = delete;
  UpperBoxes& operator=(const UpperBoxes&) = delete;

  // The triangles `indices` (3 each, into `vertices`) of a leaf block under `ancestors`.
  void add(std::span<const glm::vec3> vertices, std::span<const uint32_t> indices,
           std::span<const uint32_t> ancestors) {
    if (ancestors.empty() || indices.empty()) return;
    Batch& b = batch_[filling_];
    b.runs.push_back({b.vertices.size(), vertices.size(), b.indices.size(), indices.size(),
                      b.ancestors.size(), ancestors.size()});
    b.vertices.insert(b.vertices.end(), vertices.begin(), vertices.end());
    b.indices.insert(b.indices.end(), indices.begin(), indices.end());
    b.ancestors.insert(b.ancestors.end(), ancestors.begin(), ancestors.end());
    if (b.indices.size() >= 3 * kBatchTriangles || b.ancestors.size() >= kBatchAncestors) hand();
  }
  // Waits until every triangle added is in its accumulators.
  void finish() {
    if (!thread_.joinable()) {
      accumulate(batch_[filling_]);
      return;
    }
    hand();
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    changed_.notify_all();
    thread_.join();
  }

 private:
  struct Run {
    size_t vertex, vertices, index, indices, ancestor, ancestors;
  };
  struct Batch {
    std::vector<glm::vec3> vertices;
    std::vector<uint32_t> indices;
    std::vector<uint32_t> ancestors;
    std::vector<Run> runs;
  };

  void accumulate(Batch& b) {
    for (const Run& r : b.runs) {
      run_.assign(std::span(b.vertices).subspan(r.vertex, r.vertices),
                  std::span(b.indices).subspan(r.index, r.indices));
      targets_.clear();
      for (size_t k = 0; k < r.ancestors; ++k) targets_.push_back(&boxes_[b.ancestors[r.ancestor + k]]);
      BoxAccumulator::addRun(run_, targets_);
    }
    b.vertices.clear();
    b.indices.clear();
    b.ancestors.clear();
    b.runs.clear();
  }
  // Gives the filled batch to the helper once it is done with the other one, and fills that one next.
  void hand() {
    if (!thread_.joinable()) {
      accumulate(batch_[filling_]);
      return;
    }
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return !pending_; });
    pending_ = true;
    filling_ ^= 1;
    lock.unlock();
    changed_.notify_all();
  }
  void run() {
    std::unique_lock lock(mutex_);
    for (;;) {
      changed_.wait(lock, [&] { return pending_ || stop_; });
      if (!pending_) return;
      Batch& b = batch_[filling_ ^ 1];
      lock.unlock();
      accumulate(b);  // arithmetic on preallocated accumulators: nothing throws
      lock.lock();
      pending_ = false;
      changed_.notify_all();
    }
  }

  std::vector<BoxAccumulator>& boxes_;
  TriangleRun run_;                       // scratch of accumulate()
  std::vector<BoxAccumulator*> targets_;  // a run's ancestors
  Batch batch_[2];
  int filling_ = 0;  // the batch this thread fills; the helper reads the other while pending_
  bool pending_ = false, stop_ = false;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::thread thread_;
};

}  // namespace facetree
