// Simulation throughput per process on one thread, with the full realism of the default
// options (shower spots, background, noise, reconstruction). Target (issue): at least
// 200 000 e+e- → e+e- events/s per core.
//
//   build/bin/emcalign_bench_simulation --benchmark_min_time=2

#include <benchmark/benchmark.h>

#include "emcalign/core/units.hpp"
#include "emcalign/sim/simulation.hpp"

namespace {

using namespace emcalign;

void simulate(benchmark::State& state, sim::Process process, bool ideal, double thetaMinDeg = 10.0,
              double thetaMaxDeg = 170.0) {
  static const auto calo = *geometry::Calorimeter::create(geometry::DetectorDescription::sndDefault());
  geometry::AlignmentParameters eta;
  eta[Param::Alpha] = 3.0 * units::deg;
  eta[Param::Dx] = 0.3;
  eta[Param::Dp1] = eta[Param::Dp2] = eta[Param::Dp3] = 0.4;
  sim::SimulationOptions o;
  o.generator.process = process;
  o.generator.beamEnergy = sim::defaultBeamEnergy(process);
  o.generator.thetaMin = thetaMinDeg * units::deg;
  o.generator.thetaMax = thetaMaxDeg * units::deg;
  if (ideal) o.setIdealised();
  const auto simulation = *sim::Simulation::create(calo, eta, o);
  sim::EventScratch scratch(calo.size());
  std::vector<ParticleRow> rows;
  std::vector<TruthRow> truth;
  std::int64_t i = 0;
  for (auto _ : state) {
    if (rows.size() > 100000) {
      rows.clear();
      truth.clear();
    }
    simulation.simulateEvent(i++, scratch, rows, truth);
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_SimulateEE(benchmark::State& s) { simulate(s, sim::Process::Bhabha, false); }
// The calibration sample of the validation and the period simulations (θ 40°–140°).
void BM_SimulateEE40to140(benchmark::State& s) { simulate(s, sim::Process::Bhabha, false, 40.0, 140.0); }
void BM_SimulateGG(benchmark::State& s) { simulate(s, sim::Process::GammaGamma, false); }
void BM_Simulate3Pi(benchmark::State& s) { simulate(s, sim::Process::ThreePion, false); }
void BM_SimulateEEIdealised(benchmark::State& s) { simulate(s, sim::Process::Bhabha, true); }
BENCHMARK(BM_SimulateEE);
BENCHMARK(BM_SimulateEE40to140);
BENCHMARK(BM_SimulateGG);
BENCHMARK(BM_Simulate3Pi);
BENCHMARK(BM_SimulateEEIdealised);

}  // namespace

BENCHMARK_MAIN();
