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

namespace {

using namespace emcalign;
using units::deg;

std::vector<calib::ProfileBin> bins(const calib::FitGeometry& g) {
  geometry::AlignmentParameters eta;
  eta[Param::Alpha] = 3.0 * deg;
  eta[Param::Dx] = 0.3;
  eta[Param::Dp1] = 0.6;
  eta[Param::Dp2] = 0.2;
  eta[Param::Dp3] = 0.4;
  eta[Param::DyRel] = 0.05;
  Rng rng(1, 0);
  std::vector<calib::ProfileBin> out;
  for (int i = 0; i < 16; ++i) {
    for (int j = 0; j < 10; ++j) {
      calib::ProfileBin b;
      b.iPhi = i;
      b.iTheta = j;
      b.n = 400;
      b.phiMean = (i + 0.5) * 22.5 * deg;
      b.thetaMean = (49.5 + 9.0 * j) * deg;
      b.energyMean = 610.0;
      const auto f = calib::modelAt(g, eta.values, b.phiMean, b.thetaMean, b.energyMean);
      b.yPhi = f.phi + 0.2 * deg * rng.normal();
      b.yTheta = f.theta + 0.2 * deg * rng.normal();
      b.sigmaPhi = b.sigmaTheta = 0.2 * deg;
      out.push_back(b);
    }
  }
  calib::markUsedBins(out, 10);
  return out;
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
