// Covariance-like test matrices R diag(l) R^T with a random rotation R, shared by the
// eigensolver tests and their benchmark.
#pragma once

#include <random>

#include <glm/geometric.hpp>

#include "merge/cost/cluster_stats.h"

namespace facetree::test {

inline SymMat3 withSpectrum(std::mt19937_64& rng, double l0, double l1, double l2) {
  std::normal_distribution<double> g;
  const glm::dvec3 a = glm::normalize(glm::dvec3{g(rng), g(rng), g(rng)});
  const glm::dvec3 b = glm::normalize(glm::cross(a, glm::dvec3{g(rng), g(rng), g(rng)}));
  const glm::dvec3 c = glm::cross(a, b);
  SymMat3 m;
  m.addOuter(a, l0);
  m.addOuter(b, l1);
  m.addOuter(c, l2);
  return m;
}

}  // namespace facetree::test
