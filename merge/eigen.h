// Eigen-decomposition of symmetric 3x3 matrices, for PCA of cluster covariances
// (Willmott 2000, sec. 5.2.2: cyclic Jacobi is the method of choice at this size).
#pragma once

#include <glm/vec3.hpp>

#include "merge/cluster_stats.h"

namespace facetree {

struct Eigen3 {
  double value[3];      // ascending
  glm::dvec3 vector[3]; // unit, right-handed: vector[2] = cross(vector[0], vector[1])
};

// Cyclic Jacobi rotations until the off-diagonal is negligible.
Eigen3 eigenJacobi(const SymMat3& m);

// The eigenvector of the smallest eigenvalue (the normal of the least-squares plane).
glm::dvec3 smallestEigenvector(const SymMat3& m);

}  // namespace facetree
