// cutFits: the fit error of a cut of a cluster file, eFit of Willmott 2000, eq. 84 summed over the
// cut's clusters, and how spatially coherent the cut is: the sum of its boxes' surface areas
// against that of as many runs of the faces in Morton order. Each cluster is a run of the face
// order, so one pass over the faces sums every cut's open cluster at once (SurfaceStatsSum: eFit
// needs no dual graph); the Morton runs come from an external sort of every face's code and
// corners' box (ExternalSorter). One pass serves the file in memory and the file read
// under a cap (read/cluster_source.h): the same figures to the last bit.
#include <algorithm>
#include <stdexcept>
#include <string>

#include "cut/cut_fit_sums.h"
#include "facetree/storage.h"
#include "read/cluster_source.h"
#include "shape/file_shape.h"

namespace facetree {
namespace {

// A face in the Morton order: its code and its corners' box. Faces enter the sort in face order,
// which it keeps among equal codes (a KeyedOrder).
struct MortonFace {
  uint64_t code;
  float lo[3], hi[3];
};
struct MortonLess {
  bool operator()(const MortonFace& a, const MortonFace& b) const { return a.code < b.code; }
  uint64_t key(const MortonFace& m) const { return m.code; }
};

// The figures of `cuts` (each in face order, covering every face) over one pass of the nodes for
// their boxes (and the branching statistics, with `branching`) and two of the faces.
std::vector<CutFit> fitsOfCuts(fch::ClusterSource& reader, const std::vector<std::vector<CutCluster>>& cuts,
                               BranchingStats* branching) {
  std::vector<CutFit> fits;
  const uint64_t faces = reader.header().triangleCount;
  fch::VertexBounds bounds;
  reader.forEachVertexFrame([&](uint64_t, std::span<const glm::vec3> vertices) {
    for (const glm::vec3& p : vertices) bounds.add(p);
  });
  const glm::dvec3 origin = bounds.centre();

  std::vector<uint64_t> nodes;
  for (const std::vector<CutCluster>& cut : cuts)
    for (const CutCluster& c : cut)
      if (c.node != kNoNode) nodes.push_back(c.node);
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  // The boxes of the cuts' nodes, in a pass that stops after the last of them unless it also
  // gives the branching statistics.
  std::vector<NodeBox> boxes(nodes.size());
  ShapePass pass(reader.header());
  if (!nodes.empty() || branching)
    reader.forEachNode([&](uint64_t index, const FchNode& node, uint32_t depth) {
      if (branching) pass.visit(node, depth);
      const auto at = std::lower_bound(nodes.begin(), nodes.end(), index);
      if (at != nodes.end() && *at == index) boxes[at - nodes.begin()] = node.box;
      return branching || index < nodes.back();
    });
  if (branching) *branching = pass.stats();
  const auto boxOf = [&](const CutCluster& c) -> const NodeBox* {
    if (c.node == kNoNode) return nullptr;
    return &boxes[std::lower_bound(nodes.begin(), nodes.end(), c.node) - nodes.begin()];
  };

  // The centroids' box, which the Morton codes are taken in.
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
  const auto centroid = [](const fch::FacePiece& piece, size_t t) {
    glm::dvec3 p(0.0);
    for (int k = 0; k < 3; ++k) p += glm::dvec3(piece.vertices[piece.indices[3 * t + k]]);
    return p / 3.0;
  };
  reader.forEachFacePiece(
      [&](const fch::FacePiece& piece) {
        for (size_t t = 0; t < piece.indices.size() / 3; ++t) {
          const glm::dvec3 c = centroid(piece, t);
          lo = glm::min(lo, c), hi = glm::max(hi, c);
        }
      },
      FaceFields::Geometry);

  // Every cut's clusters, and every face into the sort.
  std::vector<fch::CutFitSum> sums(cuts.size(), fch::CutFitSum(origin));
  std::vector<size_t> at(cuts.size(), 0);
  TempSpace space(reader.temporaryDirectory());
  ExternalSorter<MortonFace, MortonLess> sorted(
      space, "morton", std::max<uint64_t>(reader.memoryBytes() / 8, 4096), {}, kSpillStored);
  // A helper takes each frame's Morton side while this thread sums the cuts: each side's state is
  // its own, so the figures are those of one thread.
  reader.forEachFacePiece(
      [&](const fch::FacePiece& piece) {
        const size_t triangles = piece.indices.size() / 3;
        const auto corner = [&](size_t t, int k) -> const glm::vec3& {
          return piece.vertices[piece.indices[3 * t + k]];
        };
        runWorkers(2, [&](unsigned worker, const std::atomic<bool>&) {
          if (worker == 1) {
            for (size_t t = 0; t < triangles; ++t) {
              MortonFace m{mortonCode(centroid(piece, t), lo, hi), {}, {}};
              for (int a = 0; a < 3; ++a) {
                m.lo[a] = std::min({corner(t, 0)[a], corner(t, 1)[a], corner(t, 2)[a]});
                m.hi[a] = std::max({corner(t, 0)[a], corner(t, 1)[a], corner(t, 2)[a]});
              }
              sorted.push(m);
            }
            return;
          }
          for (size_t t = 0; t < triangles; ++t) {
            const uint64_t p = piece.first + t;
            for (size_t i = 0; i < cuts.size(); ++i) {
              sums[i].add(corner(t, 0), corner(t, 1), corner(t, 2));
              if (at[i] == cuts[i].size() || p < cuts[i][at[i]].first)
                throw std::invalid_argument("cutFits: the cut does not cover face " + std::to_string(p));
              const CutCluster& c = cuts[i][at[i]];
              if (p + 1 == c.first + c.count) sums[i].close(boxOf(c)), ++at[i];
            }
          }
        });
      },
      FaceFields::Geometry);
  for (fch::CutFitSum& sum : sums) fits.push_back(sum.finish());

  // Run r of a cut of R runs: positions [r F / R, (r + 1) F / R) of the Morton order.
  struct Runs {
    uint64_t runs = 0, r = 0, end = 0;
    fch::AreaBox box;
  };
  std::vector<Runs> runs;
  for (const CutFit& fit : fits) {
    Runs each;
    each.runs = std::min<uint64_t>(fit.clusters, faces);
    each.end = each.runs ? faces / each.runs : 0;
    runs.push_back(each);
  }
  uint64_t rank = 0;
  sorted.finish();
  std::vector<MortonFace> block(4096);
  for (size_t got; (got = sorted.read(block)) > 0;)
    for (const MortonFace& m : std::span(block).first(got)) {
      for (size_t i = 0; i < runs.size(); ++i) {
        Runs& run = runs[i];
        run.box.add(glm::vec3(m.lo[0], m.lo[1], m.lo[2]));
        run.box.add(glm::vec3(m.hi[0], m.hi[1], m.hi[2]));
        if (rank + 1 == run.end) {
          fits[i].mortonBoxArea += run.box.area();
          run.box = fch::AreaBox{};
          ++run.r;
          run.end = (run.r + 1) * faces / run.runs;
        }
      }
      ++rank;
    }
  return fits;
}

}  // namespace

std::vector<CutFit> cutFits(ClusterFileReader& reader, std::span<const uint64_t> clusters,
                            BranchingStats* branching) {
  if (clusters.empty()) {
    if (branching) *branching = branchingStats(reader);
    return {};
  }
  std::vector<std::vector<CutCluster>> cuts;
  for (const uint64_t count : clusters) cuts.push_back(reader.cut(count));
  fch::ReaderSource source(reader);
  return fitsOfCuts(source, cuts, branching);
}

std::vector<CutFit> cutFits(const ClusterFile& file, std::span<const uint64_t> clusters) {
  if (clusters.empty()) return {};
  const size_t faces = file.indices.size() / 3;
  if (file.header.triangleCount != faces || (faces > 0 && file.vertices.empty()))
    throw std::invalid_argument("cutFit: the cluster file was read without its geometry");
  for (const uint32_t v : file.indices)
    if (v >= file.vertices.size()) throw std::invalid_argument("cutFit: vertex index out of range");
  fch::MemorySource source(file);
  std::vector<std::vector<CutCluster>> cuts;
  for (const uint64_t count : clusters) cuts.push_back(fch::prefixCut(source, count));
  return fitsOfCuts(source, cuts, nullptr);
}

CutFit cutFit(const ClusterFile& file, uint64_t clusters) {
  return cutFits(file, std::span<const uint64_t>(&clusters, 1)).front();
}

}  // namespace facetree
