// The symmetric 3x3 eigensolver: the trigonometric closed form (Smith 1961) with robust
// cross-product eigenvectors (Eberly 2014), in place of Willmott's cyclic Jacobi (2000, sec. 5.2.2).
//
// smallestEigenvector forwards to the closed form (below: why).
#include "cost/eigen.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

#include <glm/geometric.hpp>

namespace facetree {
namespace {

// The closed form meets Jacobi's accuracy (residual |Mv - lambda v| <= 1e-12 |M|, orthonormal,
// right-handed; eigen_test.cpp). The closed form costs a fixed handful of square roots and one
// acos, where Jacobi needs 4-5 sweeps of 3 rotations, each with a sqrt and two divisions, on the
// spectra clusters have (it is cheaper only on matrices already diagonal): smallestEigenvector
// uses the closed form. Willmott's Table 7 compares Jacobi with QR-shift, not with the closed form.

bool allFinite(const SymMat3& m) {
  for (double v : m.m)
    if (!std::isfinite(v)) return false;
  return true;
}

double maxAbs(const SymMat3& m) {
  double s = 0;
  for (double v : m.m) s = std::max(s, std::abs(v));
  return s;
}

Eigen3 worldAxes(double v0, double v1, double v2) {
  Eigen3 e;
  e.value[0] = v0;
  e.value[1] = v1;
  e.value[2] = v2;
  e.vector[0] = {1, 0, 0};
  e.vector[1] = {0, 1, 0};
  e.vector[2] = {0, 0, 1};
  return e;
}

// Sorts ascending (stable for ties: keeps the lower index first) and makes the basis
// right-handed.
void sortAndOrient(Eigen3& e) {
  auto order = [&](int i, int j) {
    if (e.value[j] < e.value[i]) {
      std::swap(e.value[i], e.value[j]);
      std::swap(e.vector[i], e.vector[j]);
    }
  };
  order(0, 1);
  order(1, 2);
  order(0, 1);
  e.vector[2] = glm::cross(e.vector[0], e.vector[1]);
}

// Unit eigenvector of symmetric `a` for a simple eigenvalue `lambda`: the largest cross
// product of two rows of a - lambda I (Eberly 2014). `fallback` if a - lambda I has rank < 2.
glm::dvec3 eigenvectorFromRows(const double a[3][3], double lambda, const glm::dvec3& fallback) {
  const glm::dvec3 r0{a[0][0] - lambda, a[0][1], a[0][2]};
  const glm::dvec3 r1{a[0][1], a[1][1] - lambda, a[1][2]};
  const glm::dvec3 r2{a[0][2], a[1][2], a[2][2] - lambda};
  const glm::dvec3 c01 = glm::cross(r0, r1);
  const glm::dvec3 c02 = glm::cross(r0, r2);
  const glm::dvec3 c12 = glm::cross(r1, r2);
  const double d01 = glm::dot(c01, c01);
  const double d02 = glm::dot(c02, c02);
  const double d12 = glm::dot(c12, c12);
  if (d01 >= d02 && d01 >= d12 && d01 > 0) return c01 / std::sqrt(d01);
  if (d02 >= d12 && d02 > 0) return c02 / std::sqrt(d02);
  if (d12 > 0) return c12 / std::sqrt(d12);
  return fallback;
}

// Scales (x, y), not both zero, to unit length, dividing by the larger of the two first so that
// the square cannot overflow (Eberly 2014).
void scaleToUnit(double& x, double& y) {
  if (std::abs(x) >= std::abs(y)) {
    y /= x;
    x = 1.0 / std::sqrt(1.0 + y * y);
    y *= x;
  } else {
    x /= y;
    y = 1.0 / std::sqrt(1.0 + x * x);
    x *= y;
  }
}

// Unit eigenvector for `lambda` orthogonal to the unit eigenvector `w` (Eberly 2014): the
// 2x2 problem on the plane of w. Robust for a repeated lambda (then any vector of the plane).
glm::dvec3 eigenvectorInComplement(const double a[3][3], const glm::dvec3& w, double lambda) {
  glm::dvec3 u, v;
  planeBasis(w, u, v);
  auto mul = [&](const glm::dvec3& x) {
    return glm::dvec3{a[0][0] * x.x + a[0][1] * x.y + a[0][2] * x.z,
                      a[0][1] * x.x + a[1][1] * x.y + a[1][2] * x.z,
                      a[0][2] * x.x + a[1][2] * x.y + a[2][2] * x.z};
  };
  const glm::dvec3 au = mul(u), av = mul(v);
  double m00 = glm::dot(u, au) - lambda;
  double m01 = glm::dot(u, av);
  double m11 = glm::dot(v, av) - lambda;
  const double abs00 = std::abs(m00), abs01 = std::abs(m01), abs11 = std::abs(m11);
  if (abs00 >= abs11) {
    if (!(std::max(abs00, abs01) > 0)) return u;  // also NaN
    scaleToUnit(m00, m01);
    return glm::normalize(m01 * u - m00 * v);
  }
  if (!(std::max(abs11, abs01) > 0)) return u;
  scaleToUnit(m11, m01);
  return glm::normalize(m11 * u - m01 * v);
}

// Copy of m as a full matrix scaled by a power of two (exact, no overflow even for subnormal
// input) so that the largest entry is in [1, 2); returns the scale (0 for the zero matrix).
double scaledFull(const SymMat3& m, double a[3][3]) {
  const double s = maxAbs(m);
  const int e = s > 0 ? std::ilogb(s) : 0;
  // One multiplication by 2^-e when 2^-e is a normal double, else scalbn per entry.
  const bool normalFactor = e > -1000 && e < 1000;
  const double factor = normalFactor ? std::scalbn(1.0, -e) : 0.0;
  auto f = [&](double v) { return normalFactor ? v * factor : std::scalbn(v, -e); };
  a[0][0] = f(m.xx());
  a[0][1] = a[1][0] = f(m.xy());
  a[0][2] = a[2][0] = f(m.xz());
  a[1][1] = f(m.yy());
  a[1][2] = a[2][1] = f(m.yz());
  a[2][2] = f(m.zz());
  return s > 0 ? std::scalbn(1.0, e) : 0.0;
}

// Eigenvalues of the scaled matrix (ascending) by the trigonometric formula (Smith 1961).
// Returns false when all three are equal (a = q I).
bool analyticValues(const double a[3][3], double value[3], double& halfDet) {
  const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
  const double q = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
  const double b00 = a[0][0] - q, b11 = a[1][1] - q, b22 = a[2][2] - q;
  const double p2 = (b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * off) / 6.0;
  if (!(p2 > 0)) {
    value[0] = value[1] = value[2] = q;
    halfDet = 0;
    return false;
  }
  const double p = std::sqrt(p2);
  const double inv = 1.0 / p;
  const double c00 = b00 * inv, c11 = b11 * inv, c22 = b22 * inv;
  const double c01 = a[0][1] * inv, c02 = a[0][2] * inv, c12 = a[1][2] * inv;
  const double det =
      c00 * (c11 * c22 - c12 * c12) - c01 * (c01 * c22 - c12 * c02) + c02 * (c01 * c12 - c11 * c02);
  halfDet = std::clamp(0.5 * det, -1.0, 1.0);
  const double phi = std::acos(halfDet) / 3.0;
  // beta2 = 2 cos(phi), beta0 = 2 cos(phi + 2 pi / 3) = -cos(phi) - sqrt(3) sin(phi).
  const double c = std::cos(phi);
  const double s = std::sqrt(std::max(0.0, 1.0 - c * c));
  const double beta2 = 2.0 * c;
  const double beta0 = -c - std::numbers::sqrt3 * s;
  const double beta1 = -(beta0 + beta2);
  value[0] = q + p * beta0;
  value[1] = q + p * beta1;
  value[2] = q + p * beta2;
  return true;
}

}  // namespace

void planeBasis(const glm::dvec3& w, glm::dvec3& u, glm::dvec3& v) {
  const double sign = std::copysign(1.0, w.z);
  const double a = -1.0 / (sign + w.z);
  const double b = w.x * w.y * a;
  u = {1.0 + sign * w.x * w.x * a, sign * b, -sign * w.x};
  v = {b, sign + w.y * w.y * a, -w.y};
}

Eigen3 eigenAnalytic(const SymMat3& m) {
  if (!allFinite(m)) return worldAxes(0, 0, 0);
  double a[3][3];
  const double scale = scaledFull(m, a);
  if (scale == 0) return worldAxes(0, 0, 0);
  double value[3], halfDet;
  if (!analyticValues(a, value, halfDet))
    return worldAxes(value[0] * scale, value[1] * scale, value[2] * scale);
  Eigen3 e;
  // The eigenvalue farther from the middle one is simple: solve it first by cross products,
  // the middle one in its orthogonal complement, the third by a cross product.
  if (halfDet >= 0) {
    e.vector[2] = eigenvectorFromRows(a, value[2], glm::dvec3{0, 0, 1});
    e.vector[1] = eigenvectorInComplement(a, e.vector[2], value[1]);
    e.vector[0] = glm::cross(e.vector[1], e.vector[2]);
  } else {
    e.vector[0] = eigenvectorFromRows(a, value[0], glm::dvec3{1, 0, 0});
    e.vector[1] = eigenvectorInComplement(a, e.vector[0], value[1]);
    e.vector[2] = glm::cross(e.vector[0], e.vector[1]);
  }
  // Rayleigh quotients: acos loses up to sqrt(eps) near repeated eigenvalues; the quotient of
  // an accurate vector is accurate to eps |M|.
  for (int i = 0; i < 3; ++i) {
    SymMat3 s;
    s.m[0] = a[0][0], s.m[1] = a[0][1], s.m[2] = a[0][2], s.m[3] = a[1][1], s.m[4] = a[1][2],
    s.m[5] = a[2][2];
    e.value[i] = s.quadratic(e.vector[i]) * scale;
  }
  sortAndOrient(e);
  return e;
}

glm::dvec3 smallestEigenvectorAnalytic(const SymMat3& m) {
  if (!allFinite(m)) return {1, 0, 0};
  double a[3][3];
  if (scaledFull(m, a) == 0) return {1, 0, 0};
  double value[3], halfDet;
  if (!analyticValues(a, value, halfDet)) return {1, 0, 0};
  if (halfDet < 0) return eigenvectorFromRows(a, value[0], glm::dvec3{1, 0, 0});
  // The smallest two may be close: go through the well separated largest one.
  const glm::dvec3 w = eigenvectorFromRows(a, value[2], glm::dvec3{0, 0, 1});
  return eigenvectorInComplement(a, w, value[0]);
}

glm::dvec3 smallestEigenvector(const SymMat3& m) {
  return smallestEigenvectorAnalytic(m);
}

}  // namespace facetree
