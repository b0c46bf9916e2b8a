// Time of the staged fit of 160 bins (320 residuals × 12 parameters, 6 stages, covariance):
//   build/bin/emcalign_bench_fit
// With `--profile FILE` (a profile of `emcalign fit --profile-out`), also the fit of that
// profile exactly as `emcalign fit --profile-in FILE` makes it, in process: what
// bench/minuit_crosscheck.py sets beside the staged iminuit fit of the same profile.

#include <benchmark/benchmark.h>

#include <cstdio>
#include <string>
#include <vector>

#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/profiles.hpp"
#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "synthetic_bins.hpp"

namespace {

using namespace emcalign;
using units::deg;

// 160 bins of the model at a paper-like misalignment with noise of σ = 0.2°.
std::vector<calib::ProfileBin> bins(const calib::FitGeometry& g) {
  geometry::AlignmentParameters eta;
  eta[Param::Alpha] = 3.0 * deg;
  eta[Param::Dx] = 0.3;
  eta[Param::Dp1] = 0.6;
  eta[Param::Dp2] = 0.2;
  eta[Param::Dp3] = 0.4;
  eta[Param::DyRel] = 0.05;
  Rng rng(1, 0);
  calib::testing::SyntheticBinOptions o;
  o.noise = &rng;
  o.entries = 400;
  o.energy = 610.0;
  return calib::testing::syntheticBins(g, eta.values, o);
}

void BM_StagedFit160Bins(benchmark::State& state) {
  const auto g = calib::FitGeometry::of(geometry::DetectorDescription::sndDefault());
  const auto b = bins(g);
  for (auto _ : state) benchmark::DoNotOptimize(calib::fitProfiles(b, g));
}
BENCHMARK(BM_StagedFit160Bins)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
  std::vector<char*> args;
  std::string profile;
  for (int i = 0; i < argc; ++i) {
    if (std::string(argv[i]) == "--profile" && i + 1 < argc) {
      profile = argv[++i];
    } else {
      args.push_back(argv[i]);
    }
  }
  if (!profile.empty()) {
    auto bins = calib::readProfileCsv(profile);
    if (!bins) {
      std::fprintf(stderr, "%s\n", bins.error().message.c_str());
      return 1;
    }
    calib::markUsedBins(*bins, calib::ProfileOptions{}.minEntries);
    benchmark::RegisterBenchmark("BM_StagedFitOfProfile", [b = std::move(*bins)](benchmark::State& state) {
      const auto g = calib::FitGeometry::of(geometry::DetectorDescription::sndDefault());
      for (auto _ : state) benchmark::DoNotOptimize(calib::fitProfiles(b, g));
    })->Unit(benchmark::kMillisecond);
  }
  int count = static_cast<int>(args.size());
  benchmark::Initialize(&count, args.data());
  if (benchmark::ReportUnrecognizedArguments(count, args.data())) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
