// Conversions between the public SurfaceStats (merge.h) and the merge's ClusterStats.
#pragma once

#include <cstdint>

#include "merge/cluster_stats.h"
#include "merge/merge.h"

namespace facetree {

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

}  // namespace facetree
