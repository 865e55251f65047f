// Conversions between the public SurfaceStats and GarlandQuadrics (merge.h) and the merge's
// ClusterStats and GarlandStats (cost/cost.h).
#pragma once

#include <cstdint>

#include "cost/cluster_stats.h"
#include "cost/cost.h"
#include "facetree/merge.h"

namespace facetree {

// Triangles are summed in blocks, then the block sums: a sum over n triangles then errs by
// O((n / kSumBlock + kSumBlock) eps) instead of O(n eps).
constexpr uint32_t kSumBlock = 1024;

// sum += s for a running sum of statistics, public (SurfaceStats) or the merge's (ClusterStats).
inline double& secondMomentOf(SurfaceStats& s, int i) { return s.secondMoment[i]; }
inline double& secondMomentOf(ClusterStats& s, int i) { return s.secondMoment.m[i]; }
template <class Sum>
void addStats(Sum& sum, const ClusterStats& s) {
  sum.area += s.area;
  sum.perimeter += s.perimeter;
  sum.sumNormal += s.sumNormal;
  sum.firstMoment += s.firstMoment;
  for (int i = 0; i < 6; ++i) secondMomentOf(sum, i) += s.secondMoment.m[i];
}

inline ClusterStats toClusterStats(const SurfaceStats& s) {
  ClusterStats c;
  c.area = s.area;
  c.perimeter = s.perimeter;
  c.sumNormal = s.sumNormal;
  c.firstMoment = s.firstMoment;
  for (int i = 0; i < 6; ++i) c.secondMoment.m[i] = s.secondMoment[i];
  return c;
}

inline SurfaceStats toSurfaceStats(const ClusterStats& c, uint64_t faceCount, uint32_t height) {
  SurfaceStats s;
  s.area = c.area;
  s.perimeter = c.perimeter;
  s.sumNormal = c.sumNormal;
  s.firstMoment = c.firstMoment;
  for (int i = 0; i < 6; ++i) s.secondMoment[i] = c.secondMoment.m[i];
  s.faceCount = faceCount;
  s.height = height;
  return s;
}

inline GarlandStats toGarlandStats(const GarlandQuadrics& q) {
  GarlandStats g;
  for (int i = 0; i < 6; ++i) g.cornerSecond.m[i] = q.cornerSecond[i];
  g.cornerFirst = q.cornerFirst;
  g.cornerCount = q.cornerCount;
  g.dirWeight = q.dirWeight;
  g.dirFirst = q.dirFirst;
  for (int i = 0; i < 6; ++i) g.dirSecond.m[i] = q.dirSecond[i];
  g.normalSum = q.normalSum;
  return g;
}

inline GarlandQuadrics toGarlandQuadrics(const GarlandStats& g) {
  GarlandQuadrics q;
  for (int i = 0; i < 6; ++i) q.cornerSecond[i] = g.cornerSecond.m[i];
  q.cornerFirst = g.cornerFirst;
  q.cornerCount = g.cornerCount;
  q.dirWeight = g.dirWeight;
  q.dirFirst = g.dirFirst;
  for (int i = 0; i < 6; ++i) q.dirSecond[i] = g.dirSecond.m[i];
  q.normalSum = g.normalSum;
  return q;
}

}  // namespace facetree
