// The reference the tests hold the library's closed-form eigensolver to: cyclic Jacobi rotations
// (Willmott 2000, sec. 5.2.2: the method of choice at this size; Press et al. 1992, sec. 11.1),
// on matrices of moderate scale (no rescaling against overflow).
#pragma once

#include <algorithm>
#include <cmath>
#include <utility>

#include <glm/geometric.hpp>

#include "merge/cost/eigen.h"

namespace facetree::test {

// Eigenvalues ascending (ties keep the lower index first), a right-handed orthonormal basis; the
// zero matrix gives the world axes.
inline Eigen3 eigenJacobi(const SymMat3& m) {
  double a[3][3] = {{m.xx(), m.xy(), m.xz()}, {m.xy(), m.yy(), m.yz()}, {m.xz(), m.yz(), m.zz()}};
  double v[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  double largest = 0;
  for (double x : m.m) largest = std::max(largest, std::abs(x));
  const double tolerance = 1e-15 * largest;
  constexpr int kPairs[3][3] = {{0, 1, 2}, {0, 2, 1}, {1, 2, 0}};  // p, q, the other index
  for (int sweep = 0; sweep < 32; ++sweep) {
    const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    if (off <= tolerance * tolerance) break;
    for (const auto& pair : kPairs) {
      const int p = pair[0], q = pair[1], r = pair[2];
      const double apq = a[p][q];
      if (apq == 0) continue;
      const double theta = (a[q][q] - a[p][p]) / (2.0 * apq);
      const double t = std::copysign(1.0 / (std::abs(theta) + std::sqrt(theta * theta + 1.0)), theta);
      const double c = 1.0 / std::sqrt(t * t + 1.0), s = t * c;
      a[p][p] -= t * apq;
      a[q][q] += t * apq;
      a[p][q] = a[q][p] = 0;
      const double arp = a[r][p], arq = a[r][q];
      a[r][p] = a[p][r] = c * arp - s * arq;
      a[r][q] = a[q][r] = s * arp + c * arq;
      for (int k = 0; k < 3; ++k) {
        const double vkp = v[k][p], vkq = v[k][q];
        v[k][p] = c * vkp - s * vkq;
        v[k][q] = s * vkp + c * vkq;
      }
    }
  }
  Eigen3 e;
  for (int i = 0; i < 3; ++i) {
    e.value[i] = a[i][i];
    e.vector[i] = glm::normalize(glm::dvec3{v[0][i], v[1][i], v[2][i]});
  }
  const auto order = [&](int i, int j) {
    if (e.value[j] < e.value[i]) std::swap(e.value[i], e.value[j]), std::swap(e.vector[i], e.vector[j]);
  };
  order(0, 1);
  order(1, 2);
  order(0, 1);
  e.vector[2] = glm::cross(e.vector[0], e.vector[1]);
  return e;
}

}  // namespace facetree::test
