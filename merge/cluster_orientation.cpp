// clusterOrientation: the box frame of a cluster from its statistics (Willmott 2000, sec. 5.3.2),
// chosen exactly as computeBoxes chooses it (frame.h): flat clusters (eq. 78) take S/|S| and
// the minimum-area rectangle of the points projected on its plane, the others the PCA axes of
// their area-weighted covariance. The points only orient the rectangle (and break PCA ties);
// extents come from BoxAccumulator.
#include <vector>

#include "merge/box_extent.h"
#include "merge/frame.h"
#include "merge/surface_stats.h"

namespace facetree {

glm::quat clusterOrientation(const SurfaceStats& stats, std::span<const glm::vec3> points,
                             double flatThreshold, bool& flat) {
  FrameInput in;
  in.area = stats.area;
  in.sumNormal = stats.sumNormal;
  in.flatThreshold = flatThreshold;
  if (!isFlatCluster(in.area, in.sumNormal, flatThreshold))
    in.covariance = toClusterStats(stats).covariance();
  // FrameBuilder reorders its points (hull candidates to the front): work on a copy.
  std::vector<glm::vec3> scratch(points.begin(), points.end());
  FrameBuilder builder;
  ClusterFrame frame;
  builder.build(in, scratch, frame);
  flat = frame.flat;
  return frameQuaternion(frame);
}

}  // namespace facetree
