// clusterOrientation: the box frame of a cluster from its statistics (Willmott 2000, sec. 5.3.2),
// chosen exactly as computeBoxes chooses it (boxes/frame.h): flat clusters (eq. 78) take S/|S| and
// the minimum-area rectangle of the points projected on its plane, the others the PCA axes of
// their area-weighted covariance. The points only orient the rectangle (and break PCA ties);
// extents come from BoxAccumulator.
#include <vector>

#include "boxes/box_extent.h"
#include "boxes/frame.h"
#include "cost/surface_stats.h"

namespace facetree {

namespace {

glm::quat orientation(FrameBuilder& builder, const SurfaceStats& stats, std::span<glm::vec3> points,
                      double flatThreshold, BoxPrecision precision, bool& flat, size_t& carried) {
  FrameInput in;
  in.area = stats.area;
  in.sumNormal = stats.sumNormal;
  in.flatThreshold = flatThreshold;
  if (!isFlatCluster(in.area, in.sumNormal, flatThreshold))
    in.covariance = toClusterStats(stats).covariance();
  ClusterFrame frame;
  carried = builder.build(in, points, frame);
  flat = frame.flat;
  return frameQuaternion(frame, precision);
}

}  // namespace

glm::quat clusterOrientation(const SurfaceStats& stats, std::span<const glm::vec3> points,
                             double flatThreshold, BoxPrecision precision, bool& flat) {
  // FrameBuilder reorders its points (hull candidates to the front): work on a copy.
  std::vector<glm::vec3> scratch(points.begin(), points.end());
  FrameBuilder builder;
  size_t carried = 0;
  return orientation(builder, stats, scratch, flatThreshold, precision, flat, carried);
}

static_assert(ClusterOrienter::kMaxCarried == kFrameHullCap);

ClusterOrienter::ClusterOrienter() : builder_(std::make_unique<FrameBuilder>()) {}
ClusterOrienter::~ClusterOrienter() = default;

glm::quat ClusterOrienter::orient(const SurfaceStats& stats, std::span<glm::vec3> points,
                                  double flatThreshold, BoxPrecision precision, bool& flat, size_t& carried) {
  return orientation(*builder_, stats, points, flatThreshold, precision, flat, carried);
}

}  // namespace facetree
