// Micro benchmark of the symmetric 3x3 eigensolvers (Google Benchmark; not a ctest test).
// Inputs are covariance-like: R diag(l) R^T with random rotations and spectra drawn from the
// cases a face cluster produces: generic, flat (one eigenvalue ~0), isotropic, two equal.
#include <random>
#include <vector>

#include <benchmark/benchmark.h>
#include <glm/geometric.hpp>

#include "merge/eigen.h"

namespace facetree {
namespace {

constexpr size_t kMatrices = 4096;

enum Spectrum { kGeneric, kFlat, kIsotropic, kTwoEqual, kMixed };

SymMat3 withSpectrum(std::mt19937_64& rng, const double l[3]) {
  std::normal_distribution<double> g;
  const glm::dvec3 a = glm::normalize(glm::dvec3{g(rng), g(rng), g(rng)});
  const glm::dvec3 b = glm::normalize(glm::cross(a, glm::dvec3{g(rng), g(rng), g(rng)}));
  const glm::dvec3 c = glm::cross(a, b);
  const glm::dvec3 axes[3] = {a, b, c};
  SymMat3 m;
  for (int k = 0; k < 3; ++k) {
    const glm::dvec3& v = axes[k];
    m.m[0] += l[k] * v.x * v.x;
    m.m[1] += l[k] * v.x * v.y;
    m.m[2] += l[k] * v.x * v.z;
    m.m[3] += l[k] * v.y * v.y;
    m.m[4] += l[k] * v.y * v.z;
    m.m[5] += l[k] * v.z * v.z;
  }
  return m;
}

std::vector<SymMat3> makeMatrices(Spectrum kind) {
  std::mt19937_64 rng(2024 + kind);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<SymMat3> out;
  for (size_t i = 0; i < kMatrices; ++i) {
    const Spectrum k = kind == kMixed ? Spectrum(i % 4) : kind;
    double l[3];
    switch (k) {
      case kGeneric:
        l[0] = u(rng), l[1] = u(rng), l[2] = u(rng);
        break;
      case kFlat:
        l[0] = 1e-9 * u(rng), l[1] = u(rng), l[2] = u(rng);
        break;
      case kIsotropic:
        l[0] = l[1] = l[2] = 1.0 + 1e-12 * u(rng);
        break;
      default:
        l[0] = u(rng), l[1] = l[2] = 1.0;
        break;
    }
    out.push_back(withSpectrum(rng, l));
  }
  return out;
}

template <class F>
void run(benchmark::State& state, F solve) {
  const std::vector<SymMat3> ms = makeMatrices(Spectrum(state.range(0)));
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(solve(ms[i]));
    i = (i + 1) % ms.size();
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_JacobiFull(benchmark::State& s) {
  run(s, eigenJacobi);
}
void BM_AnalyticFull(benchmark::State& s) {
  run(s, eigenAnalytic);
}
void BM_JacobiSmallest(benchmark::State& s) {
  run(s, smallestEigenvectorJacobi);
}
void BM_AnalyticSmallest(benchmark::State& s) {
  run(s, smallestEigenvectorAnalytic);
}

#define SPECTRA ArgName("spectrum")->Arg(kGeneric)->Arg(kFlat)->Arg(kIsotropic)->Arg(kTwoEqual)->Arg(kMixed)
BENCHMARK(BM_JacobiFull)->SPECTRA;
BENCHMARK(BM_AnalyticFull)->SPECTRA;
BENCHMARK(BM_JacobiSmallest)->SPECTRA;
BENCHMARK(BM_AnalyticSmallest)->SPECTRA;

}  // namespace
}  // namespace facetree

BENCHMARK_MAIN();
