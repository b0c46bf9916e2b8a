// Speed of the π+π−π0 kinematic fit (apply/kinematic_fit.hpp), in fits per second on one
// core: generated φ → π+π−π0 events, measurements smeared by their errors, made once.
//   build/bin/emcalign_bench_kinematic_fit
// The goal (issue "Physics checks"): ≥ 100 000 fits per second per core.

#include <cmath>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "emcalign/apply/kinematic_fit.hpp"
#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/sim/generators.hpp"

namespace {

using namespace emcalign;

std::vector<apply::ThreePionEvent> events(int n) {
  sim::GeneratorOptions g;
  g.process = sim::Process::ThreePion;
  g.beamEnergy = 510.0 * units::MeV;
  Rng rng(7, 0);
  std::mt19937_64 smear(8);
  std::normal_distribution<double> gauss;
  std::vector<apply::ThreePionEvent> out;
  sim::GeneratedEvent ev;
  while (static_cast<int>(out.size()) < n) {
    const sim::Collision c = sim::generate(g, rng, ev);
    apply::ThreePionEvent e;
    e.totalEnergy = c.energy();
    e.totalMomentum = Vec3(0.0, 0.0, c.momentumZ());
    int photon = 0;
    for (const auto& p : ev.particles) {
      const double theta = std::acos(p.momentum.z() / p.momentum.norm());
      const double phi = std::atan2(p.momentum.y(), p.momentum.x());
      if (p.pdg == sim::pdg::Photon && photon < 2) {
        const double s = 0.042 * p.energy / std::pow(p.energy / 1000.0, 0.25);
        e.photons[static_cast<std::size_t>(photon++)] = {p.energy + s * gauss(smear),
                                                         theta + 0.026 * gauss(smear),
                                                         phi + 0.026 / std::sin(theta) * gauss(smear),
                                                         s,
                                                         0.026,
                                                         0.026 / std::sin(theta)};
      } else if (p.charge() != 0) {
        e.pions[p.pdg > 0 ? 0 : 1] = {theta + 0.005 * gauss(smear), phi + 0.0045 / std::sin(theta) * gauss(smear),
                                      0.005, 0.0045 / std::sin(theta)};
      }
    }
    out.push_back(e);
  }
  return out;
}

void BM_ThreePionFit(benchmark::State& state) {
  static const std::vector<apply::ThreePionEvent> sample = events(10000);
  std::size_t k = 0;
  double chi2 = 0.0;
  for (auto _ : state) {
    const auto r = apply::fitThreePion(sample[k]);
    chi2 += r.chi2;
    benchmark::DoNotOptimize(chi2);
    k = (k + 1) % sample.size();
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}
BENCHMARK(BM_ThreePionFit);

}  // namespace

BENCHMARK_MAIN();
