// clusterCut and clusterDepthCut (facetree/io.h): the cuts of a file in memory as each face's
// cluster, numbered along the face order: the cuts a reader makes (read/source_cut.cpp) over the
// file's arrays.
#include <algorithm>

#include "read/cluster_source.h"

namespace facetree {
namespace {

std::vector<uint32_t> byFace(const ClusterFile& file, const std::vector<CutCluster>& cut) {
  std::vector<uint32_t> cluster(file.indices.size() / 3, 0);
  for (size_t i = 0; i < cut.size(); ++i)
    std::fill(cluster.begin() + std::min(cut[i].first, cluster.size()),
              cluster.begin() + std::min(cut[i].first + cut[i].count, cluster.size()),
              static_cast<uint32_t>(i));
  return cluster;
}

}  // namespace

std::vector<uint32_t> clusterCut(const ClusterFile& file, uint64_t clusters) {
  fch::MemorySource source(file);
  return byFace(file, fch::prefixCut(source, clusters));
}

std::vector<uint32_t> clusterDepthCut(const ClusterFile& file, uint32_t depth) {
  fch::MemorySource source(file);
  return byFace(file, fch::depthCut(source, depth));
}

}  // namespace facetree
