// Micro benchmark of the symmetric 3x3 eigensolvers (Google Benchmark; not a ctest test).
// Inputs are covariance-like: R diag(l) R^T with random rotations and spectra drawn from the
// cases a face cluster produces: generic, flat (one eigenvalue ~0), isotropic, two equal.
#include <random>
#include <vector>

#include <benchmark/benchmark.h>
#include <glm/geometric.hpp>

#include "eigen_jacobi.h"
#include "merge/cost/eigen.h"
#include "random_spectra.h"

namespace facetree {
namespace {

constexpr size_t kMatrices = 4096;

enum Spectrum { kGeneric, kFlat, kIsotropic, kTwoEqual, kMixed };

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
    out.push_back(test::withSpectrum(rng, l[0], l[1], l[2]));
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
  run(s, test::eigenJacobi);
}
void BM_AnalyticFull(benchmark::State& s) {
  run(s, eigenAnalytic);
}
void BM_JacobiSmallest(benchmark::State& s) {
  run(s, [](const SymMat3& m) { return test::eigenJacobi(m).vector[0]; });
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
