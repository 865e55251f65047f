// Exact oriented bounding boxes and side areas of face clusters (Willmott 2000, sec. 5.3). Frames
// are chosen bottom-up from exact surface moments and the children's hull points (boxes/frame.h);
// extents and side areas are exact, every node projecting every vertex of its face range on its
// stored axes (sec. 5.3.1), over faces packed in hierarchy order one subtree at a time. Subtrees
// run in parallel and side areas sum over fixed blocks: the same bits for any thread count.
#include "boxes/box.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <thread>
#include <type_traits>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include "base/buffer.h"
#include "base/huge_pages.h"
#include "base/parallel_blocks.h"
#include "boxes/box_extent.h"
#include "boxes/frame.h"

namespace facetree {
namespace {

// Side areas are summed within aligned blocks of this many face positions, then block sums
// in order: the canonical order that makes parallel scans bit-identical to serial ones.
constexpr uint32_t kSideBlock = 1u << 12;
// The tree is cut into about this many subtrees for the workers (fixed: independent of the
// thread count) ...
constexpr size_t kTargetSubtrees = 64;
// ... but subtrees smaller than this are not cut further.
constexpr uint32_t kMinSubtreeFaces = 1u << 13;
// Below this many faces everything runs on the calling thread.
constexpr size_t kMinParallelFaces = 1u << 15;
constexpr unsigned kMaxThreads = 8;
// A child cut off from a truncated hierarchy contributes the vertices of at most this many of
// its faces (evenly strided) as hull candidates; its moments stay exact.
constexpr uint32_t kGapSampleFaces = 256;

// A window [begin, end) of the faces in hierarchy order, structure of arrays: vertex k of the
// face at position i is (x[k][i - begin], y[k][i - begin], z[k][i - begin]); (nx, ny, nz) =
// a_f n_f, half the cross product. The arrays have 3 floats of padding (scanBlock).
struct PackedFaces {
  std::vector<float> x[3], y[3], z[3];
  std::vector<float> nx, ny, nz;
  uint32_t begin = 0, end = 0;

  bool holds(uint32_t i) const { return i >= begin && i < end; }
  glm::vec3 vertex(int k, uint32_t i) const {
    i -= begin;
    return {x[k][i], y[k][i], z[k][i]};
  }
};

// The faces in hierarchy order, read from the mesh: the source of the packed windows (which
// hold copies of the same floats) and of the few reads outside any window.
struct FaceSource {
  const MeshView& mesh;
  const std::vector<uint32_t>& order;
  glm::dvec3 origin{0.0};  // moments are taken about this point (the mesh's box center)

  glm::vec3 vertex(int k, uint32_t i) const { return mesh.positions[mesh.indices[3 * size_t(order[i]) + k]]; }

  // Fills `f` with positions [begin, end); its buffers keep their capacity for the next window.
  void pack(uint32_t begin, uint32_t end, PackedFaces& f) const {
    const size_t padded = size_t(end - begin) + 3;  // scanBlock's last step reads up to 3 past the end
    for (int k = 0; k < 3; ++k) f.x[k].resize(padded), f.y[k].resize(padded), f.z[k].resize(padded);
    f.nx.resize(padded), f.ny.resize(padded), f.nz.resize(padded);
    f.begin = begin, f.end = end;
    for (uint32_t i = begin; i < end; ++i) {
      const size_t j = i - begin;
      const uint32_t* tri = &mesh.indices[3 * size_t(order[i])];
      glm::dvec3 v[3];
      for (int k = 0; k < 3; ++k) {
        const glm::vec3& p = mesh.positions[tri[k]];
        f.x[k][j] = p.x, f.y[k][j] = p.y, f.z[k][j] = p.z;
        v[k] = glm::dvec3(p);
      }
      const glm::dvec3 half = 0.5 * glm::cross(v[1] - v[0], v[2] - v[0]);
      f.nx[j] = float(half.x), f.ny[j] = float(half.y), f.nz[j] = float(half.z);
    }
  }
};

// Area integrals of a cluster's surface about FaceSource::origin (cost/cluster_stats.h formulas).
struct Moments {
  double area = 0;
  glm::dvec3 first{0.0};
  double second[6] = {0, 0, 0, 0, 0, 0};
  glm::dvec3 sumNormal{0.0};

  void addTriangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
    const glm::dvec3 half = 0.5 * glm::cross(b - a, c - a);
    const double A = glm::length(half);
    sumNormal += half;
    area += A;
    const glm::dvec3 s = a + b + c;
    first += (A / 3.0) * s;
    const double w = A / 12.0;
    for (const glm::dvec3* p : {&a, &b, &c, &s}) {
      second[0] += w * p->x * p->x;
      second[1] += w * p->x * p->y;
      second[2] += w * p->x * p->z;
      second[3] += w * p->y * p->y;
      second[4] += w * p->y * p->z;
      second[5] += w * p->z * p->z;
    }
  }
  void add(const Moments& o) {
    area += o.area;
    first += o.first;
    for (int i = 0; i < 6; ++i) second[i] += o.second[i];
    sumNormal += o.sumNormal;
  }
  SymMat3 covariance() const {
    ClusterStats s;
    s.area = area;
    s.firstMoment = first;
    for (int i = 0; i < 6; ++i) s.secondMoment.m[i] = second[i];
    return s.covariance();
  }
};

using Extent = BoxExtent;

uint32_t blockEnd(uint32_t i, uint32_t end) {
  return std::min<uint64_t>(end, (uint64_t(i) / kSideBlock + 1) * kSideBlock);
}

#if defined(__x86_64__) && defined(__GNUC__) && defined(__GLIBC__)  // ifunc: glibc only
#define SCAN_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define SCAN_CLONES
#endif

// Positions [begin, end) (within one side block and f's window): min/max of (p - origin) . axis_k
// in float, side areas accumulated in double. Vertex positions minus a vertex of the node are
// exact to half an ulp of the box size, so the float error is relative to the box, not to the
// distance from the world origin (finishBox pads by the bound). PackedFaces arrays have 3
// floats of padding, so the last, partial step loads past `end`: its extra lanes repeat lane
// 0's vertices (no effect on min/max) and have zero area.
// The main loop takes whole steps of four without masks (masking blends on every step cost more
// than the one masked step at the end); the partial last step, if any, is the same code with the lanes
// masked. On x86-64 an AVX2 clone is chosen at load time where available: the same 4-lane operations in the
// same order (no FMA, so no contraction), hence the same bits, with three-operand VEX forms and the double
// accumulators in single ymm registers instead of spilled xmm pairs.
SCAN_CLONES Extent scanBlock(const PackedFaces& f, const ScanFrame& frame, uint32_t begin, uint32_t end) {
  const V4f a0x = splat(frame.axis[0].x), a0y = splat(frame.axis[0].y), a0z = splat(frame.axis[0].z);
  const V4f a1x = splat(frame.axis[1].x), a1y = splat(frame.axis[1].y), a1z = splat(frame.axis[1].z);
  const V4f a2x = splat(frame.axis[2].x), a2y = splat(frame.axis[2].y), a2z = splat(frame.axis[2].z);
  const V4f ox = splat(frame.origin.x), oy = splat(frame.origin.y), oz = splat(frame.origin.z);
  const V4f zero = splat(0.0f);
  V4f lo0 = splat(INFINITY), lo1 = lo0, lo2 = lo0, hi0 = splat(-INFINITY), hi1 = hi0, hi2 = hi0;
  V4d s0{}, s1{}, s2{}, s3{}, s4{}, s5{};
  auto step = [&](uint32_t i, auto masked) {
    [[maybe_unused]] const V4i valid = V4i{0, 1, 2, 3} < int32_t(end - i);
    for (int k = 0; k < 3; ++k) {
      const uint32_t j = i - f.begin;
      V4f x = load4(f.x[k].data() + j) - ox, y = load4(f.y[k].data() + j) - oy,
          z = load4(f.z[k].data() + j) - oz;
      if constexpr (masked)
        x = valid ? x : splat(x[0]), y = valid ? y : splat(y[0]), z = valid ? z : splat(z[0]);
      const V4f p0 = x * a0x + y * a0y + z * a0z;
      const V4f p1 = x * a1x + y * a1y + z * a1z;
      const V4f p2 = x * a2x + y * a2y + z * a2z;
      lo0 = vmin(lo0, p0), hi0 = vmax(hi0, p0);
      lo1 = vmin(lo1, p1), hi1 = vmax(hi1, p1);
      lo2 = vmin(lo2, p2), hi2 = vmax(hi2, p2);
    }
    const uint32_t j = i - f.begin;
    V4f nx = load4(f.nx.data() + j), ny = load4(f.ny.data() + j), nz = load4(f.nz.data() + j);
    if constexpr (masked) nx = valid ? nx : zero, ny = valid ? ny : zero, nz = valid ? nz : zero;
    const V4f d0 = nx * a0x + ny * a0y + nz * a0z;
    const V4f d1 = nx * a1x + ny * a1y + nz * a1z;
    const V4f d2 = nx * a2x + ny * a2y + nz * a2z;
    s0 += __builtin_convertvector(vmax(d0, zero), V4d), s1 += __builtin_convertvector(vmax(-d0, zero), V4d);
    s2 += __builtin_convertvector(vmax(d1, zero), V4d), s3 += __builtin_convertvector(vmax(-d1, zero), V4d);
    s4 += __builtin_convertvector(vmax(d2, zero), V4d), s5 += __builtin_convertvector(vmax(-d2, zero), V4d);
  };
  uint32_t i = begin;
  for (; end - i >= 4; i += 4) step(i, std::false_type{});
  if (i < end) step(i, std::true_type{});
  Extent e;
  const V4f lo[3] = {lo0, lo1, lo2}, hi[3] = {hi0, hi1, hi2};
  for (int k = 0; k < 3; ++k) {
    e.lo[k] = std::min(std::min(lo[k][0], lo[k][1]), std::min(lo[k][2], lo[k][3]));
    e.hi[k] = std::max(std::max(hi[k][0], hi[k][1]), std::max(hi[k][2], hi[k][3]));
  }
  const V4d sides[6] = {s0, s1, s2, s3, s4, s5};
  for (int k = 0; k < 6; ++k) e.side[k] = (sides[k][0] + sides[k][1]) + (sides[k][2] + sides[k][3]);
  return e;
}

Extent scanRange(const PackedFaces& f, const ScanFrame& frame, uint32_t begin, uint32_t end) {
  Extent total;
  for (uint32_t i = begin; i < end;) {
    const uint32_t stop = blockEnd(i, end);
    total.merge(scanBlock(f, frame, i, stop));
    i = stop;
  }
  return total;
}

// The box of extents `e` measured in `frame` (of orientation q) in place of `box` where its
// surface is smaller (smallerBox): a cluster measured along the world axes too.
void keepSmaller(const Extent& e, const ScanFrame& frame, const glm::quat& q, NodeBox& box) {
  NodeBox other;
  other.orientation = q;
  finishBox(e, frame, other);
  if (smallerBox(other, box)) box = other;
}

ScanFrame scanFrame(const FaceSource& f, const glm::quat& q, uint32_t first) {
  const glm::mat3 m = glm::mat3_cast(q);
  return {{m[0], m[1], m[2]}, f.vertex(0, first)};
}

// What a finished child hands its parent: moments and candidate hull points
// (arena[pointsBegin, next carry's pointsBegin or arena end)).
struct Carry {
  Moments moments;
  size_t pointsBegin;
};

// A finished subtree root: its carry with its points copied out.
struct SubtreeResult {
  Moments moments;
  std::vector<glm::vec3> points;
};

enum class TaskKind : uint8_t { kVisit, kFinish, kFace, kRange, kSubtree };
struct Task {
  TaskKind kind;
  uint32_t a;  // node index, face position, range begin, or subtree id
  uint32_t b;  // kFinish: child carries on the stack; kRange: range end
};

struct Context {
  const FaceSource& faces;
  Hierarchy& hierarchy;
  const BuildOptions& options;
  Buffer<uint32_t> subtreeOf;  // node -> subtree id + 1 for precomputed subtree roots (top pass)
  std::vector<SubtreeResult> subtrees;
  // The walk's order (preorder, children in child order) and each node's position in it: a
  // worker prefetches the node it will visit kLookahead visits later (only a hint: a wrong
  // guess costs time, never correctness).
  Buffer<uint32_t> preorder, rank;
  uint64_t worldAxesFaces = 1;  // the clusters measured along the world axes too
};

// Nodes visited ahead of the one being visited, for prefetching.
constexpr uint32_t kLookahead = 8;

// Depth-first, children before parents, one per thread at a time.
class Worker {
 public:
  explicit Worker(Context& ctx) : ctx_(ctx) {}

  // Frames of every node below and including `root`. With `scan`, also the exact boxes (else
  // only the orientation is stored and `visited` lists the nodes). Subtree roots found in
  // ctx.subtreeOf (when `usePrecomputed`) are taken from ctx.subtrees.
  // With `scan`, the faces of `root` are packed first.
  SubtreeResult run(uint32_t root, bool scan, bool usePrecomputed, std::vector<uint32_t>* visited) {
    if (scan) {
      const Node& n = ctx_.hierarchy.nodes[root];
      ctx_.faces.pack(n.first, n.first + n.count, window_);
    } else {
      window_.begin = window_.end = 0;
    }
    tasks_.clear();
    carries_.clear();
    arena_.clear();
    tasks_.push_back({TaskKind::kVisit, root, 0});
    pos_ = ctx_.rank[root];
    while (!tasks_.empty()) {
      const Task t = tasks_.back();
      tasks_.pop_back();
      switch (t.kind) {
        case TaskKind::kVisit:
          visit(t.a, usePrecomputed);
          break;
        case TaskKind::kFinish:
          finish(t.a, t.b, scan, visited);
          break;
        case TaskKind::kFace:
          pushFace(t.a);
          break;
        case TaskKind::kRange:
          pushRange(t.a, t.b);
          break;
        case TaskKind::kSubtree:
          pushSubtree(t.a);
          break;
      }
    }
    SubtreeResult out;
    out.moments = carries_.back().moments;
    out.points.assign(arena_.begin() + ptrdiff_t(carries_.back().pointsBegin), arena_.end());
    return out;
  }

 private:
  void visit(uint32_t node, bool usePrecomputed) {
    if (pos_ + kLookahead < ctx_.preorder.size()) prefetchNode(ctx_.preorder[pos_ + kLookahead]);
    ++pos_;
    const Node& n = ctx_.hierarchy.nodes[node];
    const uint32_t count = uint32_t(ctx_.hierarchy.nodes.size());
    Task child[3];
    uint32_t k = 0;
    auto rangeOf = [&](uint32_t c, uint32_t& b, uint32_t& e) {
      if (c & kFaceChild) {
        b = c & ~kFaceChild, e = b + 1;
      } else {
        b = ctx_.hierarchy.nodes[c].first, e = b + ctx_.hierarchy.nodes[c].count;
      }
    };
    const bool cut[2] = {!(n.child[0] & kFaceChild) && n.child[0] >= count,
                         !(n.child[1] & kFaceChild) && n.child[1] >= count};
    const uint32_t end = n.first + n.count;
    for (int i = 0; i < 2; ++i) {
      const uint32_t c = n.child[i];
      if (c & kFaceChild) {
        child[k++] = {TaskKind::kFace, c & ~kFaceChild, 0};
      } else if (!cut[i]) {
        prefetchNode(c);
        if (usePrecomputed && ctx_.subtreeOf[c] != 0)
          child[k++] = {TaskKind::kSubtree, ctx_.subtreeOf[c] - 1, 0};
        else
          child[k++] = {TaskKind::kVisit, c, 0};
      } else if (!cut[1 - i]) {
        // Cut off by truncation: the faces of the node that its sibling does not cover.
        uint32_t sb, se;
        rangeOf(n.child[1 - i], sb, se);
        if (sb > n.first) child[k++] = {TaskKind::kRange, n.first, sb};
        if (se < end) child[k++] = {TaskKind::kRange, se, end};
      } else if (i == 0) {
        child[k++] = {TaskKind::kRange, n.first, end};  // both cut off: one range for both
      }
    }
    tasks_.push_back({TaskKind::kFinish, node, k});
    for (uint32_t i = k; i-- > 0;) tasks_.push_back(child[i]);
  }

  // The depth-first walk jumps around nodes[] (reverse creation order) and boxes[]: about a
  // third of the time went to cache misses on them before these prefetches. A child's entries
  // are fetched when its parent is visited; the second child's have its sibling's whole
  // subtree to arrive, and the box has the child's own subtree before finish() writes it.
  void prefetchNode(uint32_t c) const {
    const char* node = reinterpret_cast<const char*>(ctx_.hierarchy.nodes.data() + c);
    const char* box = reinterpret_cast<const char*>(ctx_.hierarchy.boxes.data() + c);
    __builtin_prefetch(node);
    __builtin_prefetch(node + sizeof(Node) - 1);
    __builtin_prefetch(box, 1);
    __builtin_prefetch(box + sizeof(NodeBox) - 1, 1);
  }

  // Vertex k of the face at position i: from the window when it holds i (the same floats).
  glm::vec3 vertex(int k, uint32_t i) const {
    return window_.holds(i) ? window_.vertex(k, i) : ctx_.faces.vertex(k, i);
  }

  void pushFace(uint32_t pos) {
    Carry c{{}, arena_.size()};
    const glm::dvec3 o = ctx_.faces.origin;
    const glm::vec3 v[3] = {vertex(0, pos), vertex(1, pos), vertex(2, pos)};
    c.moments.addTriangle(glm::dvec3(v[0]) - o, glm::dvec3(v[1]) - o, glm::dvec3(v[2]) - o);
    arena_.insert(arena_.end(), v, v + 3);
    carries_.push_back(c);
  }

  void pushRange(uint32_t begin, uint32_t end) {
    Carry c{{}, arena_.size()};
    const glm::dvec3 o = ctx_.faces.origin;
    const uint32_t stride = std::max<uint32_t>(1, (end - begin + kGapSampleFaces - 1) / kGapSampleFaces);
    for (uint32_t i = begin; i < end; ++i) {
      const glm::vec3 v[3] = {vertex(0, i), vertex(1, i), vertex(2, i)};
      c.moments.addTriangle(glm::dvec3(v[0]) - o, glm::dvec3(v[1]) - o, glm::dvec3(v[2]) - o);
      if ((i - begin) % stride == 0) arena_.insert(arena_.end(), v, v + 3);
    }
    carries_.push_back(c);
  }

  void pushSubtree(uint32_t id) {
    const SubtreeResult& r = ctx_.subtrees[id];
    carries_.push_back({r.moments, arena_.size()});
    arena_.insert(arena_.end(), r.points.begin(), r.points.end());
  }

  void finish(uint32_t node, uint32_t k, bool scan, std::vector<uint32_t>* visited) {
    Node& n = ctx_.hierarchy.nodes[node];
    const size_t base = carries_.size() - k;
    const size_t begin = k > 0 ? carries_[base].pointsBegin : arena_.size();
    Moments m;
    for (size_t i = base; i < carries_.size(); ++i) m.add(carries_[i].moments);
    FrameInput in;
    in.area = n.area;
    in.sumNormal = glm::dvec3(n.sumNormal);
    if (!isFlatCluster(in.area, in.sumNormal, ctx_.options.flatThreshold)) in.covariance = m.covariance();
    in.flatThreshold = ctx_.options.flatThreshold;
    ClusterFrame frame;
    const size_t kept =
        frames_.build(in, std::span<glm::vec3>(arena_.data() + begin, arena_.size() - begin), frame);
    arena_.resize(begin + kept);
    n.flags = (n.flags & ~uint32_t(kNodeFlatFrame)) | (frame.flat ? uint32_t(kNodeFlatFrame) : 0u);
    NodeBox& box = ctx_.hierarchy.boxes[node];
    box.orientation = frameQuaternion(frame, ctx_.options.boxes);
    if (scan) {
      const ScanFrame sf = scanFrame(ctx_.faces, box.orientation, n.first);
      finishBox(scanRange(window_, sf, n.first, n.first + n.count), sf, box);
      if (measuresWorldAxes(n.count, ctx_.worldAxesFaces, box.orientation, ctx_.options.boxes)) {
        const glm::quat world = worldOrientation(ctx_.options.boxes);
        const ScanFrame wf = scanFrame(ctx_.faces, world, n.first);
        keepSmaller(scanRange(window_, wf, n.first, n.first + n.count), wf, world, box);
      }
    } else if (visited) {
      visited->push_back(node);
    }
    carries_.resize(base);
    carries_.push_back({m, begin});
  }

  Context& ctx_;
  FrameBuilder frames_;
  std::vector<Task> tasks_;
  std::vector<Carry> carries_;
  std::vector<glm::vec3> arena_;
  PackedFaces window_;  // the faces of the subtree being scanned
  uint32_t pos_ = 0;    // position of the next visit in ctx_.preorder, if the walk follows it
};

void validate(const MeshView& mesh, const Hierarchy& h) {
  const size_t faces = h.faceOrder.size();
  const size_t tris = mesh.triangleCount();
  for (uint32_t t : h.faceOrder)
    if (t >= tris) throw std::invalid_argument("computeBoxes: faceOrder entry out of range");
  for (uint32_t v : mesh.indices)
    if (v >= mesh.positions.size()) throw std::invalid_argument("computeBoxes: vertex index out of range");
  for (size_t i = 0; i < h.nodes.size(); ++i) {
    const Node& n = h.nodes[i];
    if (n.count == 0 || uint64_t(n.first) + n.count > faces)
      throw std::invalid_argument("computeBoxes: node face range out of range");
    for (uint32_t c : n.child) {
      if (c & kFaceChild) {
        if ((c & ~kFaceChild) < n.first || (c & ~kFaceChild) >= n.first + n.count)
          throw std::invalid_argument("computeBoxes: face child outside its parent's range");
      } else if (c <= i) {
        throw std::invalid_argument("computeBoxes: child node index not after its parent");
      } else if (c < h.nodes.size() &&
                 (h.nodes[c].first < n.first ||
                  uint64_t(h.nodes[c].first) + h.nodes[c].count > uint64_t(n.first) + n.count)) {
        throw std::invalid_argument("computeBoxes: child range outside its parent's range");
      }
    }
  }
}

float roundUp(double v) {
  float f = float(v);
  // v >= 0 here (a half extent), so the next float up is the next bit pattern (nextafterf is
  // a library call).
  if (double(f) < v)
    f = f >= 0 ? std::bit_cast<float>(std::bit_cast<uint32_t>(f) + 1)
               : std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

}  // namespace

glm::quat frameQuaternion(const ClusterFrame& frame, BoxPrecision precision) {
  const glm::dmat3 m(frame.axis[0], frame.axis[1], frame.axis[2]);
  return latticeOrientation(glm::quat(glm::normalize(glm::quat_cast(m))), orientationBits(precision));
}

glm::quat worldOrientation(BoxPrecision precision) {
  return frameQuaternion(ClusterFrame{}, precision);
}

uint64_t worldAxesFaces(const BuildOptions& options, uint64_t meshFaces) {
  return options.worldAxesFaces ? options.worldAxesFaces : std::max<uint64_t>(1, meshFaces / kWorldAxesShare);
}

bool measuresWorldAxes(uint64_t faces, uint64_t leastFaces, const glm::quat& orientation,
                       BoxPrecision precision) {
  return faces >= leastFaces && orientation != worldOrientation(precision);
}

bool smallerBox(const NodeBox& candidate, const NodeBox& box) {
  const auto surface = [](const NodeBox& b) {
    const glm::dvec3 h(b.halfExtent);
    return h.x * h.y + h.y * h.z + h.z * h.x;
  };
  return surface(candidate) < surface(box);
}

void finishBox(const BoxExtent& e, const ScanFrame& frame, NodeBox& box, double minPad) {
  glm::dvec3 axis[3];
  for (int k = 0; k < 3; ++k) axis[k] = glm::dvec3(frame.axis[k]);
  const glm::dvec3 o(frame.origin);
  double r2 = 0;  // |p - o| <= sqrt(sum of max(lo^2, hi^2)) for (near-)orthonormal axes
  for (int k = 0; k < 3; ++k) r2 += std::max(e.lo[k] * e.lo[k], e.hi[k] * e.hi[k]);
  const double pad = std::max(kProjectionError * std::sqrt(r2) * 1.01, minPad);
  // The float axes are orthonormal only to ~1e-7: solve dot(center - o, axis_k) = mid_k instead
  // of summing mid_k axis_k.
  const glm::dmat3 a(axis[0], axis[1], axis[2]);
  const glm::dvec3 mid = 0.5 * glm::dvec3(e.lo[0] + e.hi[0], e.lo[1] + e.hi[1], e.lo[2] + e.hi[2]);
  box.center = glm::vec3(o + glm::inverse(glm::transpose(a)) * mid);
  const glm::dvec3 c = glm::dvec3(box.center) - o;
  for (int k = 0; k < 3; ++k) {
    const double ck = glm::dot(c, axis[k]);
    box.halfExtent[k] = roundUp(std::max({e.hi[k] - ck, ck - e.lo[k], 0.0}) + pad);
  }
  for (int k = 0; k < 6; ++k) box.sideArea[k] = float(e.side[k]);
}

void computeBoxesWithThreads(const MeshView& mesh, Hierarchy& hierarchy, const BuildOptions& options,
                             unsigned threads) {
  std::vector<Node>& nodes = hierarchy.nodes;
  reserveHugePages(hierarchy.boxes, nodes.size());
  hierarchy.boxes.assign(nodes.size(), NodeBox{});
  if (nodes.empty()) return;
  validate(mesh, hierarchy);
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  threads = std::min(threads, kMaxThreads);
  if (hierarchy.faceOrder.size() < kMinParallelFaces) threads = 1;

  FaceSource faces{mesh, hierarchy.faceOrder};
  {
    glm::vec3 lo(INFINITY), hi(-INFINITY);
    for (const glm::vec3& p : mesh.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
    if (!mesh.positions.empty()) faces.origin = 0.5 * (glm::dvec3(lo) + glm::dvec3(hi));
  }
  Context ctx{faces, hierarchy, options, {}, {}, {}, {}, worldAxesFaces(options, hierarchy.faceOrder.size())};

  // Roots of nodes unreachable from nodes[0] (none in a well-formed hierarchy) are handled as
  // further trees; children have larger indices than parents, so a forward pass finds the roots.
  // The same pass ranks the nodes in the walk's preorder from their subtree sizes (a backward
  // pass): both read nodes[] sequentially.
  std::vector<uint32_t> roots;
  {
    const uint32_t count = uint32_t(nodes.size());
    Buffer<uint32_t>& size = ctx.preorder;  // subtree sizes first
    size.resize(count);
    for (uint32_t i = count; i-- > 0;) {
      uint32_t s = 1;
      for (uint32_t c : nodes[i].child)
        if (!(c & kFaceChild) && c < count) s += size[c];
      size[i] = s;
    }
    std::vector<bool> reached(count, false);
    ctx.rank.resize(count);
    uint32_t next = 0;
    for (uint32_t i = 0; i < count; ++i) {
      if (!reached[i]) roots.push_back(i), ctx.rank[i] = next, next += size[i];
      uint32_t r = ctx.rank[i] + 1;
      for (uint32_t c : nodes[i].child) {
        if (!(c & kFaceChild) && c < count) reached[c] = true, ctx.rank[c] = r, r += size[c];
      }
    }
    // Out-of-range ranks (only from a node with two parents, which the walk does not expect
    // either) leave holes: a hole prefetches node 0.
    std::fill(ctx.preorder.begin(), ctx.preorder.end(), 0u);
    for (uint32_t i = 0; i < count; ++i)
      if (ctx.rank[i] < count) ctx.preorder[ctx.rank[i]] = i;
  }

  for (uint32_t root : roots) {
    // Cut the tree into subtrees: split the largest until there are enough or all are small.
    std::vector<uint32_t> cut{root};
    while (cut.size() < kTargetSubtrees) {
      const auto largest = std::max_element(
          cut.begin(), cut.end(), [&](uint32_t a, uint32_t b) { return nodes[a].count < nodes[b].count; });
      if (nodes[*largest].count < kMinSubtreeFaces) break;
      const uint32_t split = *largest;
      cut.erase(largest);
      for (uint32_t c : nodes[split].child)
        if (!(c & kFaceChild) && c < nodes.size()) cut.push_back(c);
    }
    if (cut.size() == 1 && cut[0] == root) {
      Worker(ctx).run(root, true, false, nullptr);
      continue;
    }
    // Subtrees in parallel, largest first.
    std::sort(cut.begin(), cut.end(), [&](uint32_t a, uint32_t b) {
      return nodes[a].count != nodes[b].count ? nodes[a].count > nodes[b].count : a < b;
    });
    ctx.subtrees.assign(cut.size(), {});
    ctx.subtreeOf.assign(nodes.size(), 0);
    for (size_t i = 0; i < cut.size(); ++i) ctx.subtreeOf[cut[i]] = uint32_t(i + 1);
    std::atomic<size_t> nextSubtree{0};
    onThreads(threads, [&](unsigned) {
      Worker worker(ctx);
      for (size_t i; (i = nextSubtree.fetch_add(1)) < cut.size();)
        ctx.subtrees[i] = worker.run(cut[i], true, false, nullptr);
    });
    // The nodes above the cut: frames serially, then their scans by blocks in parallel.
    std::vector<uint32_t> top;
    Worker(ctx).run(root, false, true, &top);
    // A node's items in its own frame, then, where it measures them too, along the world axes.
    struct Item {
      uint32_t node, begin, end;
      bool world;
    };
    const glm::quat world = worldOrientation(options.boxes);
    std::vector<Item> items;
    std::vector<size_t> firstItem, firstWorldItem;
    for (uint32_t node : top) {
      firstItem.push_back(items.size());
      const Node& n = nodes[node];
      const bool both =
          measuresWorldAxes(n.count, ctx.worldAxesFaces, hierarchy.boxes[node].orientation, options.boxes);
      for (bool w : {false, true}) {
        if (w) firstWorldItem.push_back(items.size());
        if (w && !both) continue;
        for (uint32_t i = n.first; i < n.first + n.count; i = blockEnd(i, n.first + n.count))
          items.push_back({node, i, blockEnd(i, n.first + n.count), w});
      }
    }
    firstItem.push_back(items.size());
    // Items grouped by side block: a worker packs one block and scans every top node's part
    // of it (each partial goes to its item's slot, so the sums below keep their order).
    std::vector<uint32_t> byBlock(items.size());
    for (uint32_t i = 0; i < byBlock.size(); ++i) byBlock[i] = i;
    std::stable_sort(byBlock.begin(), byBlock.end(), [&](uint32_t a, uint32_t b) {
      return items[a].begin / kSideBlock < items[b].begin / kSideBlock;
    });
    std::vector<size_t> groups;  // starts of runs of byBlock in one block, then its size
    for (size_t i = 0; i < byBlock.size(); ++i)
      if (i == 0 || items[byBlock[i]].begin / kSideBlock != items[byBlock[i - 1]].begin / kSideBlock)
        groups.push_back(i);
    groups.push_back(byBlock.size());
    std::vector<Extent> partial(items.size());
    std::atomic<size_t> nextGroup{0};
    onThreads(threads, [&](unsigned) {
      PackedFaces window;
      for (size_t g; (g = nextGroup.fetch_add(1)) + 1 < groups.size();) {
        uint32_t begin = items[byBlock[groups[g]]].begin, end = begin;
        for (size_t k = groups[g]; k < groups[g + 1]; ++k) {
          begin = std::min(begin, items[byBlock[k]].begin);
          end = std::max(end, items[byBlock[k]].end);
        }
        faces.pack(begin, end, window);
        for (size_t k = groups[g]; k < groups[g + 1]; ++k) {
          const Item& item = items[byBlock[k]];
          const ScanFrame sf = scanFrame(faces, item.world ? world : hierarchy.boxes[item.node].orientation,
                                         nodes[item.node].first);
          partial[byBlock[k]] = scanBlock(window, sf, item.begin, item.end);
        }
      }
    });
    for (size_t t = 0; t < top.size(); ++t) {
      Extent total, worldTotal;
      for (size_t i = firstItem[t]; i < firstWorldItem[t]; ++i) total.merge(partial[i]);
      for (size_t i = firstWorldItem[t]; i < firstItem[t + 1]; ++i) worldTotal.merge(partial[i]);
      NodeBox& box = hierarchy.boxes[top[t]];
      finishBox(total, scanFrame(faces, box.orientation, nodes[top[t]].first), box);
      if (firstWorldItem[t] < firstItem[t + 1]) {
        keepSmaller(worldTotal, scanFrame(faces, world, nodes[top[t]].first), world, box);
      }
    }
  }
}

void computeBoxes(const MeshView& mesh, Hierarchy& hierarchy, const BuildOptions& options) {
  computeBoxesWithThreads(mesh, hierarchy, options, options.threads);
}

}  // namespace facetree
