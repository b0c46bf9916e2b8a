// Throughput of the geometry kernels the simulation and the fit call most:
// the forward/inverse transform of a point, building the placements from η, and the model
// residual with its 12 derivatives (Ceres Jets), as one fit bin costs; and the counter
// containing a point (Calorimeter::locate, once per shower spot of the simulation), for
// points in random order (every branch unpredictable) and along showers.

#include <random>
#include <vector>

#include <benchmark/benchmark.h>
#include <ceres/jet.h>

#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/geometry/residual_model.hpp"

namespace {

using namespace emcalign;
using namespace emcalign::geometry;

AlignmentParameters paperLike() {
  AlignmentParameters eta;
  eta[Param::Alpha] = 3.0 * units::deg;
  eta[Param::Beta1] = 0.2 * units::deg;
  eta[Param::Dx] = 0.3;
  eta[Param::Dp1] = 0.6;
  eta[Param::Dp2] = 0.2;
  eta[Param::Dp3] = 0.4;
  eta[Param::DyRel] = 0.05;
  eta[Param::BetaRel] = 0.1 * units::deg;
  return eta;
}

std::vector<Vec3> points(std::size_t n) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> c(-1.0, 1.0), p(0.0, 6.283185307179586);
  std::vector<Vec3> out;
  for (std::size_t i = 0; i < n; ++i) out.push_back(pointAt(41.0, std::acos(c(rng)), p(rng)));
  return out;
}

const AlignmentRadii kRadii{53.7, 69.5};

void BM_Forward(benchmark::State& state) {
  const auto t = *AlignmentTransform::create(paperLike(), kRadii);
  const auto pts = points(1024);
  for (auto _ : state) {
    for (const Vec3& p : pts) benchmark::DoNotOptimize(t.forward(p));
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * pts.size()));
}
BENCHMARK(BM_Forward);

void BM_InverseAuto(benchmark::State& state) {
  const auto t = *AlignmentTransform::create(paperLike(), kRadii);
  const auto pts = points(1024);
  for (auto _ : state) {
    for (const Vec3& p : pts) benchmark::DoNotOptimize(t.inverseAuto(p));
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * pts.size()));
}
BENCHMARK(BM_InverseAuto);

void BM_CreateTransform(benchmark::State& state) {
  const auto eta = paperLike();
  for (auto _ : state) benchmark::DoNotOptimize(AlignmentTransform::create(eta, kRadii));
}
BENCHMARK(BM_CreateTransform);

// 160 bins × (f_φ, f_θ) with 12 derivatives: one Jacobian evaluation of the fit.
void BM_ModelJacobian160Bins(benchmark::State& state) {
  using Jet = ceres::Jet<double, 12>;
  ParamVectorT<Jet> eta;
  const ParamVector v = paperLike().values;
  for (int k = 0; k < 12; ++k) eta[k] = Jet(v[k], k);
  const ShowerDepth depth = ShowerDepth::of(DetectorDescription::sndDefault());
  for (auto _ : state) {
    const auto plus = hemisphereTransform<Jet>(eta, Hemisphere::Plus, kRadii);
    const auto minus = hemisphereTransform<Jet>(eta, Hemisphere::Minus, kRadii);
    for (int i = 0; i < 16; ++i) {
      for (int j = 0; j < 10; ++j) {
        const double phi = (i + 0.5) * 22.5 * units::deg, theta = (45.0 + (j + 0.5) * 9.0) * units::deg;
        benchmark::DoNotOptimize(modelResidual<Jet>(plus, minus, phi, theta, depth.radius(612.5, theta)));
      }
    }
  }
}
BENCHMARK(BM_ModelJacobian160Bins);

void locate(benchmark::State& state, bool alongShowers) {
  static const auto calo = *Calorimeter::create(DetectorDescription::sndDefault());
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> at;
  while (at.size() < 4096) {
    // Random points of the EMC volume, or 32 spots within 8 cm of a radial axis at a time.
    const double theta = (40.0 + 100.0 * u(rng)) * units::deg, phi = 6.283185307179586 * u(rng);
    const int spots = alongShowers ? 32 : 1;
    for (int k = 0; k < spots; ++k) {
      const double r = 33.0 + 35.0 * u(rng);
      const Vec3 p = pointAt(r, theta, phi) + Vec3(8.0 * u(rng) - 4.0, 8.0 * u(rng) - 4.0, 8.0 * u(rng) - 4.0);
      at.push_back(p);
    }
  }
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(calo.locate(at[i]));
    i = (i + 1) & 4095;
  }
  state.SetItemsProcessed(state.iterations());
}
void BM_LocateRandomPoints(benchmark::State& s) { locate(s, false); }
void BM_LocateAlongShowers(benchmark::State& s) { locate(s, true); }
BENCHMARK(BM_LocateRandomPoints);
BENCHMARK(BM_LocateAlongShowers);

}  // namespace

BENCHMARK_MAIN();
