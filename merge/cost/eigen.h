// Eigen-decomposition of symmetric 3x3 matrices, for PCA of cluster covariances
// (Willmott 2000, sec. 5.2.2: cyclic Jacobi is the method of choice at this size).
//
// The trigonometric closed form for symmetric 3x3 (Smith 1961) with eigenvectors from cross
// products of the rows of M - lambda I (Eberly 2014, "A Robust Eigensolver for 3x3 Symmetric
// Matrices"): no iteration, where Jacobi needs sweeps (cost/eigen.cpp says why it is the faster;
// the tests hold it to Jacobi, the timings of both are in docs/benchmarks.md).
//
// All functions are total: any finite input gives finite eigenvalues and unit eigenvectors;
// degenerate inputs (zero matrix, repeated eigenvalues) give a deterministic orthonormal basis
// (world axes where the eigenspace is the whole space). Non-finite input gives world axes.
#pragma once

#include <glm/vec3.hpp>

#include "cost/cluster_stats.h"

namespace facetree {

struct Eigen3 {
  double value[3];       // ascending
  glm::dvec3 vector[3];  // unit, right-handed: vector[2] = cross(vector[0], vector[1])
};

// Closed form (Smith 1961) with robust cross-product eigenvectors (Eberly 2014).
Eigen3 eigenAnalytic(const SymMat3& m);

// The eigenvector of the smallest eigenvalue (the normal of the least-squares plane).
glm::dvec3 smallestEigenvector(const SymMat3& m);

// smallestEigenvector's closed form, exposed for the benchmark and the tests.
glm::dvec3 smallestEigenvectorAnalytic(const SymMat3& m);

// A deterministic orthonormal basis (u, v) of the plane orthogonal to unit n, right-handed:
// cross(u, v) = n (Duff et al. 2017, branchless).
void planeBasis(const glm::dvec3& n, glm::dvec3& u, glm::dvec3& v);

}  // namespace facetree
