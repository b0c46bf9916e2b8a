// The trend analysis (validation/trend.hpp) on series made by hand, for docs/campaign.md:
// how often noise alone makes a step or a drift (the false-alarm rate the penalty buys), and
// how large a step or a drift must be to be found. Deterministic (fixed seeds).
//
//   build/bin/emcalign_trend_study [TRIALS]      (default 2000 per line)

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "emcalign/validation/trend.hpp"

using emcalign::validation::analyseTrend;
using emcalign::validation::Trend;
using emcalign::validation::TrendSeries;

namespace {

// n IOVs of 10 runs; quoted error 1, true scatter `scatter`; a step of `step` at n/2 and a
// slope of `drift` (per IOV) over the second half.
TrendSeries make(std::size_t n, double scatter, double step, double drift, std::mt19937_64& rng) {
  std::normal_distribution<double> noise(0.0, scatter);
  TrendSeries s{emcalign::Param::Dx, {}};
  for (std::size_t i = 0; i < n; ++i) {
    const auto first = static_cast<std::int64_t>(10 * i + 1);
    double v = noise(rng);
    if (i >= n / 2) v += step + drift * static_cast<double>(i - n / 2);
    s.points.push_back({first, first + 9, v, 1.0});
  }
  return s;
}

struct Rates {
  double steps = 0, drifts = 0, stepAtPlace = 0;
};

Rates rates(std::size_t n, double scatter, double step, double drift, int trials, std::uint64_t seed,
            const emcalign::validation::TrendOptions& options = {}) {
  std::mt19937_64 rng(seed);
  Rates r;
  for (int k = 0; k < trials; ++k) {
    const Trend t = analyseTrend({make(n, scatter, step, drift, rng)}, options);
    r.steps += t.steps.empty() ? 0 : 1;
    r.drifts += t.drifts.empty() ? 0 : 1;
    for (const auto& s : t.steps) {
      if (s.index + 1 >= n / 2 && s.index <= n / 2 + 1) {
        r.stepAtPlace += 1;
        break;
      }
    }
  }
  r.steps /= trials;
  r.drifts /= trials;
  r.stepAtPlace /= trials;
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  const int trials = argc > 1 ? std::atoi(argv[1]) : 2000;
  std::printf("# emcalign trend study, %d series per line\n\n", trials);
  std::printf("## Noise alone (errors right: scatter 1; too large: 0.3; too small: 2)\n\n");
  std::printf("| IOVs | scatter / error | series with a false step | with a false drift |\n|---|---|---|---|\n");
  for (std::size_t n : {20, 50, 106, 200, 500}) {
    for (double scatter : {1.0, 0.3, 2.0}) {
      if (n != 106 && scatter != 1.0) continue;
      const Rates r = rates(n, scatter, 0.0, 0.0, trials, 1000 + n);
      std::printf("| %zu | %.1f | %.2f %% | %.2f %% |\n", n, scatter, 100 * r.steps, 100 * r.drifts);
    }
  }
  {
    emcalign::validation::TrendOptions o;
    o.penalty = 3.0 * std::log(106.0);
    const Rates r = rates(106, 1.0, 0.0, 0.0, trials, 1106, o);
    std::printf("| 106 | 1.0, penalty 3 ln n instead of 4 ln n | %.2f %% | %.2f %% |\n", 100 * r.steps, 100 * r.drifts);
  }
  std::printf("\n## A step in the middle of 106 IOVs (size in units of one IOV's error)\n\n");
  std::printf("| step | found (± 1 IOV) |\n|---|---|\n");
  for (double step : {1.0, 1.5, 2.0, 2.5, 3.0, 4.0}) {
    const Rates r = rates(106, 1.0, step, 0.0, trials, 2000 + static_cast<std::uint64_t>(10 * step));
    std::printf("| %.1f | %.1f %% |\n", step, 100 * r.stepAtPlace);
  }
  std::printf("\n## A drift over the last 53 of 106 IOVs (total change in units of one IOV's error)\n\n");
  std::printf(
      "| total change | drift flagged | a step reported | a step reported without the knee test |\n"
      "|---|---|---|---|\n");
  for (double total : {1.0, 2.0, 3.0, 4.0, 6.0}) {
    const auto seed = 3000 + static_cast<std::uint64_t>(10 * total);
    const Rates r = rates(106, 1.0, 0.0, total / 53.0, trials, seed);
    emcalign::validation::TrendOptions noKnee;
    noKnee.kneeTest = false;
    const Rates q = rates(106, 1.0, 0.0, total / 53.0, trials, seed, noKnee);
    std::printf("| %.1f | %.1f %% | %.1f %% | %.1f %% |\n", total, 100 * r.drifts, 100 * r.steps, 100 * q.steps);
  }
  return 0;
}
