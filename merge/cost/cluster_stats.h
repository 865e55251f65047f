// Additive, exact statistics of a face cluster (Willmott 2000, sec. 5.2.3 and 5.4).
//
// Moments are area integrals over the cluster's surface, taken about a mesh-wide origin
// (the caller shifts positions) so that the variance below does not cancel catastrophically.
// For a triangle (a, b, c) of area A with s = a + b + c:
//   integral of x      dA = A s / 3
//   integral of x x^T  dA = A (a a^T + b b^T + c c^T + s s^T) / 12
#pragma once

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

namespace facetree {

// Symmetric 3x3 matrix, upper triangle: xx, xy, xz, yy, yz, zz.
struct SymMat3 {
  double m[6] = {0, 0, 0, 0, 0, 0};
  double xx() const { return m[0]; }
  double xy() const { return m[1]; }
  double xz() const { return m[2]; }
  double yy() const { return m[3]; }
  double yz() const { return m[4]; }
  double zz() const { return m[5]; }
  // M += w v v^T
  void addOuter(const glm::dvec3& v, double w) {
    m[0] += w * v.x * v.x;
    m[1] += w * v.x * v.y;
    m[2] += w * v.x * v.z;
    m[3] += w * v.y * v.y;
    m[4] += w * v.y * v.z;
    m[5] += w * v.z * v.z;
  }
  friend SymMat3 operator+(const SymMat3& a, const SymMat3& b) {
    SymMat3 s;
    for (int i = 0; i < 6; ++i) s.m[i] = a.m[i] + b.m[i];
    return s;
  }
  // v^T M v
  double quadratic(const glm::dvec3& v) const {
    return m[0] * v.x * v.x + m[3] * v.y * v.y + m[5] * v.z * v.z +
           2.0 * (m[1] * v.x * v.y + m[2] * v.x * v.z + m[4] * v.y * v.z);
  }
  // The covariance about the mean of points of total `weight` (> 0), this their second moment and
  // `first` their first.
  SymMat3 central(const glm::dvec3& first, double weight) const {
    const double inv = 1.0 / weight;
    const glm::dvec3 mean = first * inv;
    SymMat3 c;
    c.m[0] = m[0] * inv - mean.x * mean.x;
    c.m[1] = m[1] * inv - mean.x * mean.y;
    c.m[2] = m[2] * inv - mean.x * mean.z;
    c.m[3] = m[3] * inv - mean.y * mean.y;
    c.m[4] = m[4] * inv - mean.y * mean.z;
    c.m[5] = m[5] * inv - mean.z * mean.z;
    return c;
  }
};

struct ClusterStats {
  double area = 0;
  double perimeter = 0;
  glm::dvec3 sumNormal{0.0};  // S = sum of a_f n_f
  glm::dvec3 firstMoment{0.0};
  SymMat3 secondMoment;

  static ClusterStats fromTriangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
    ClusterStats s;
    const glm::dvec3 cross = glm::cross(b - a, c - a);
    s.sumNormal = 0.5 * cross;
    s.area = 0.5 * glm::length(cross);
    s.perimeter = glm::length(b - a) + glm::length(c - b) + glm::length(a - c);
    const glm::dvec3 sum = a + b + c;
    s.firstMoment = (s.area / 3.0) * sum;
    const double w = s.area / 12.0;
    const glm::dvec3* v[4] = {&a, &b, &c, &sum};
    for (const glm::dvec3* p : v) s.secondMoment.addOuter(*p, w);
    return s;
  }

  // fromTriangle for float corners taken about `origin`, written out in scalars with the exact
  // arithmetic FaceGeometry::leafStats uses (it calls this; tests/merge/merge_api_test.cpp checks
  // they agree bit for bit), so that stats summed from it match the engine's.
  static ClusterStats fromShiftedTriangle(const glm::vec3& pa, const glm::vec3& pb, const glm::vec3& pc,
                                          const glm::dvec3& origin) {
    const double ax = pa.x - origin.x, ay = pa.y - origin.y, az = pa.z - origin.z;
    const double bx = pb.x - origin.x, by = pb.y - origin.y, bz = pb.z - origin.z;
    const double cx = pc.x - origin.x, cy = pc.y - origin.y, cz = pc.z - origin.z;
    const double ux = bx - ax, uy = by - ay, uz = bz - az;  // b - a
    const double vx = cx - ax, vy = cy - ay, vz = cz - az;  // c - a
    const double wx = cx - bx, wy = cy - by, wz = cz - bz;  // c - b
    const double nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    ClusterStats s;
    s.sumNormal = glm::dvec3(0.5 * nx, 0.5 * ny, 0.5 * nz);
    s.area = 0.5 * std::sqrt(nx * nx + ny * ny + nz * nz);
    s.perimeter = std::sqrt(ux * ux + uy * uy + uz * uz) + std::sqrt(vx * vx + vy * vy + vz * vz) +
                  std::sqrt(wx * wx + wy * wy + wz * wz);
    const double sx = ax + bx + cx, sy = ay + by + cy, sz = az + bz + cz;
    const double third = s.area / 3.0, w = s.area / 12.0;
    s.firstMoment = glm::dvec3(third * sx, third * sy, third * sz);
    double* m = s.secondMoment.m;
    m[0] = w * (ax * ax + bx * bx + cx * cx + sx * sx);
    m[1] = w * (ax * ay + bx * by + cx * cy + sx * sy);
    m[2] = w * (ax * az + bx * bz + cx * cz + sx * sz);
    m[3] = w * (ay * ay + by * by + cy * cy + sy * sy);
    m[4] = w * (ay * az + by * bz + cy * cz + sy * sz);
    m[5] = w * (az * az + bz * bz + cz * cz + sz * sz);
    return s;
  }

  // Union of two clusters that share `sharedLength` of boundary (0 for disjoint ones).
  static ClusterStats merged(const ClusterStats& a, const ClusterStats& b, double sharedLength) {
    ClusterStats s;
    s.area = a.area + b.area;
    s.perimeter = std::max(0.0, a.perimeter + b.perimeter - 2.0 * sharedLength);
    s.sumNormal = a.sumNormal + b.sumNormal;
    s.firstMoment = a.firstMoment + b.firstMoment;
    s.secondMoment = a.secondMoment + b.secondMoment;
    return s;
  }

  double projectedArea() const { return glm::length(sumNormal); }

  // Area-weighted covariance of the surface about its centroid (zero for zero area).
  SymMat3 covariance() const { return area > 0 ? secondMoment.central(firstMoment, area) : SymMat3{}; }
};

}  // namespace facetree
