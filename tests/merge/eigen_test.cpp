// Symmetric 3x3 eigensolvers: residuals, orthonormality, handedness, degenerate inputs.
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include "eigen_jacobi.h"
#include "merge/cost/eigen.h"
#include "random_spectra.h"

namespace facetree {
namespace {

glm::dvec3 mul(const SymMat3& m, const glm::dvec3& v) {
  return {m.xx() * v.x + m.xy() * v.y + m.xz() * v.z, m.xy() * v.x + m.yy() * v.y + m.yz() * v.z,
          m.xz() * v.x + m.yz() * v.y + m.zz() * v.z};
}

double normMax(const SymMat3& m) {
  double s = 0;
  for (double v : m.m) s = std::max(s, std::abs(v));
  return s;
}

// A family of covariance-like test matrices, including the degenerate cases of clusters.
std::vector<SymMat3> testMatrices() {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<SymMat3> out;
  for (int i = 0; i < 2000; ++i) {
    const double s = std::pow(10.0, 12.0 * u(rng) - 6.0);  // any scale
    switch (i % 7) {
      case 0:
        out.push_back(test::withSpectrum(rng, s * u(rng), s * u(rng), s * u(rng)));
        break;
      case 1:
        out.push_back(test::withSpectrum(rng, s * 1e-12 * u(rng), s * u(rng), s * u(rng)));
        break;  // flat
      case 2:
        out.push_back(test::withSpectrum(rng, 0.0, s * u(rng), s));
        break;  // exactly flat
      case 3:
        out.push_back(test::withSpectrum(rng, s, s, s));
        break;  // isotropic
      case 4:
        out.push_back(test::withSpectrum(rng, s * 0.2, s, s));
        break;  // two equal (top)
      case 5:
        out.push_back(test::withSpectrum(rng, s * 0.2, s * 0.2, s));
        break;  // two equal (bottom)
      case 6:
        out.push_back(test::withSpectrum(rng, 0.0, 0.0, s));
        break;  // a line
    }
  }
  return out;
}

void expectValidDecomposition(const SymMat3& m, const Eigen3& e, double tol) {
  const double scale = normMax(m);
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(std::isfinite(e.value[i]));
    ASSERT_NEAR(glm::length(e.vector[i]), 1.0, 1e-12);
    const glm::dvec3 r = mul(m, e.vector[i]) - e.value[i] * e.vector[i];
    EXPECT_LE(glm::length(r), tol * scale + 1e-300) << "eigenpair " << i;
  }
  EXPECT_LE(e.value[0], e.value[1]);
  EXPECT_LE(e.value[1], e.value[2]);
  EXPECT_NEAR(glm::dot(e.vector[0], e.vector[1]), 0.0, 1e-12);
  EXPECT_NEAR(glm::dot(e.vector[0], e.vector[2]), 0.0, 1e-12);
  EXPECT_NEAR(glm::dot(e.vector[1], e.vector[2]), 0.0, 1e-12);
  EXPECT_NEAR(glm::dot(glm::cross(e.vector[0], e.vector[1]), e.vector[2]), 1.0, 1e-12);
}

void expectValidSmallest(const SymMat3& m, const glm::dvec3& v, double tol) {
  ASSERT_NEAR(glm::length(v), 1.0, 1e-12);
  const double lambda = m.quadratic(v);
  const glm::dvec3 r = mul(m, v) - lambda * v;
  EXPECT_LE(glm::length(r), tol * normMax(m) + 1e-300);
  // It is the smallest: no other eigenvalue is below the Rayleigh quotient.
  const Eigen3 ref = test::eigenJacobi(m);
  EXPECT_LE(lambda, ref.value[0] + tol * normMax(m) + 1e-300);
}

constexpr double kTol = 1e-12;

TEST(Eigen, JacobiRandomAndDegenerate) {
  for (const SymMat3& m : testMatrices()) expectValidDecomposition(m, test::eigenJacobi(m), kTol);
}

TEST(Eigen, AnalyticRandomAndDegenerate) {
  for (const SymMat3& m : testMatrices()) expectValidDecomposition(m, eigenAnalytic(m), kTol);
}

TEST(Eigen, SmallestBothSolvers) {
  for (const SymMat3& m : testMatrices()) {
    expectValidSmallest(m, test::eigenJacobi(m).vector[0], kTol);
    expectValidSmallest(m, smallestEigenvectorAnalytic(m), kTol);
    expectValidSmallest(m, smallestEigenvector(m), kTol);
  }
}

TEST(Eigen, FlatClusterNormal) {
  // Points on the plane z = 0 (rotated): the smallest eigenvector is the plane normal.
  std::mt19937_64 rng(7);
  for (int i = 0; i < 200; ++i) {
    const SymMat3 m = test::withSpectrum(rng, 0.0, 1.0 + i, 3.0 + i);
    const glm::dvec3 ref = test::eigenJacobi(m).vector[0];
    EXPECT_NEAR(std::abs(glm::dot(smallestEigenvector(m), ref)), 1.0, 1e-12);
  }
}

TEST(Eigen, Diagonal) {
  SymMat3 m;
  m.m[0] = 3, m.m[3] = 1, m.m[5] = 2;
  for (const Eigen3& e : {test::eigenJacobi(m), eigenAnalytic(m)}) {
    EXPECT_DOUBLE_EQ(e.value[0], 1);
    EXPECT_DOUBLE_EQ(e.value[1], 2);
    EXPECT_DOUBLE_EQ(e.value[2], 3);
    EXPECT_NEAR(std::abs(e.vector[0].y), 1.0, 1e-15);
    EXPECT_NEAR(std::abs(e.vector[1].z), 1.0, 1e-15);
    EXPECT_NEAR(std::abs(e.vector[2].x), 1.0, 1e-15);
  }
  EXPECT_NEAR(std::abs(smallestEigenvector(m).y), 1.0, 1e-15);
}

TEST(Eigen, ZeroAndIsotropicGiveWorldAxes) {
  SymMat3 zero;
  SymMat3 iso;
  iso.m[0] = iso.m[3] = iso.m[5] = 2.5;
  for (const SymMat3& m : {zero, iso}) {
    for (const Eigen3& e : {test::eigenJacobi(m), eigenAnalytic(m)}) {
      EXPECT_EQ(e.vector[0], glm::dvec3(1, 0, 0));
      EXPECT_EQ(e.vector[1], glm::dvec3(0, 1, 0));
      EXPECT_EQ(e.vector[2], glm::dvec3(0, 0, 1));
      EXPECT_EQ(e.value[0], m.m[0]);
    }
    for (const glm::dvec3& v : {smallestEigenvector(m), test::eigenJacobi(m).vector[0]})
      EXPECT_EQ(v, glm::dvec3(1, 0, 0));
  }
}

TEST(Eigen, TinyAndHugeScalesNoNaN) {
  for (double s : {1e-300, 1e-200, 1e-30, 1e30, 1e200, std::numeric_limits<double>::denorm_min()}) {
    SymMat3 m;
    m.m[0] = 1 * s, m.m[1] = 0.5 * s, m.m[3] = 2 * s, m.m[4] = 0.25 * s, m.m[5] = 3 * s;
    for (const glm::dvec3& v : {smallestEigenvector(m), smallestEigenvectorAnalytic(m)}) {
      EXPECT_TRUE(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z)) << s;
      EXPECT_NEAR(glm::length(v), 1.0, 1e-12) << s;
    }
    const Eigen3 e = eigenAnalytic(m);
    EXPECT_TRUE(std::isfinite(e.value[0]) && std::isfinite(e.value[2]));
  }
}

TEST(Eigen, NonFiniteInputGivesWorldAxes) {
  SymMat3 m;
  m.m[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(smallestEigenvector(m), glm::dvec3(1, 0, 0));
  EXPECT_EQ(eigenAnalytic(m).vector[2], glm::dvec3(0, 0, 1));
  m.m[0] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(eigenAnalytic(m).vector[1], glm::dvec3(0, 1, 0));
}

TEST(Eigen, CovarianceOfTriangles) {
  // Covariance of a bumpy surface from exact triangle moments (the way the merge uses it).
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  ClusterStats s;
  for (int i = 0; i < 100; ++i) {
    const glm::dvec3 a{u(rng), u(rng), 0.01 * u(rng)}, b{u(rng), u(rng), 0.01 * u(rng)},
        c{u(rng), u(rng), 0.01 * u(rng)};
    s = ClusterStats::merged(s, ClusterStats::fromTriangle(a, b, c), 0);
  }
  const SymMat3 cov = s.covariance();
  const glm::dvec3 n = smallestEigenvector(cov);
  EXPECT_GT(std::abs(n.z), 0.99);
  expectValidDecomposition(cov, test::eigenJacobi(cov), kTol);
  expectValidDecomposition(cov, eigenAnalytic(cov), kTol);
}

}  // namespace
}  // namespace facetree
