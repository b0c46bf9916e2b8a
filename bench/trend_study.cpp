// The trend analysis (validation/trend.hpp) on series made by hand, for docs/campaign.md:
// how often noise alone makes a step, a drift or an unstable period (the false-alarm rates the
// penalties buy), how large a step or a drift must be to be found, and how well a drift inside
// flat runs is found with its ends. Deterministic (fixed seeds).
//
//   build/bin/emcalign_trend_study [TRIALS]      (default 2000 per line)

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "emcalign/validation/trend.hpp"

using emcalign::validation::analyseTrend;
using emcalign::validation::Trend;
using emcalign::validation::TrendOptions;
using emcalign::validation::TrendSeries;

namespace {

// n IOVs of 10 runs (IOV i: runs 10i+1 .. 10i+10); error 1, true scatter `scatter`; the
// value of IOV i is truth(i) + noise. `statistical`: the errors are the fits' statistical ones.
TrendSeries make(std::size_t n, double scatter, const std::function<double(std::size_t)>& truth, bool statistical,
                 std::mt19937_64& rng, std::int64_t runsPerIov = 10) {
  std::normal_distribution<double> noise(0.0, scatter);
  TrendSeries s{emcalign::Param::Dx, {}, statistical};
  for (std::size_t i = 0; i < n; ++i) {
    const auto first = static_cast<std::int64_t>(i) * runsPerIov + 1;
    s.points.push_back({first, first + runsPerIov - 1, truth(i) + noise(rng), 1.0});
  }
  return s;
}

struct Rates {
  double steps = 0, drifts = 0, stepAtPlace = 0, unstable = 0;
};

// A step of `step` at n/2 and a slope of `drift` (per IOV) over the second half.
std::function<double(std::size_t)> stepAndDrift(std::size_t n, double step, double drift) {
  return [=](std::size_t i) { return i >= n / 2 ? step + drift * static_cast<double>(i - n / 2) : 0.0; };
}

Rates rates(std::size_t n, double scatter, double step, double drift, int trials, std::uint64_t seed,
            const TrendOptions& options = {}, bool statistical = false) {
  std::mt19937_64 rng(seed);
  Rates r;
  for (int k = 0; k < trials; ++k) {
    const Trend t = analyseTrend({make(n, scatter, stepAndDrift(n, step, drift), statistical, rng)}, options);
    r.steps += t.steps.empty() ? 0 : 1;
    r.drifts += t.drifts.empty() ? 0 : 1;
    r.unstable += std::any_of(t.segments.begin(), t.segments.end(), [](const auto& g) { return !g.stable(); }) ? 1 : 0;
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
  r.unstable /= trials;
  return r;
}

// A ramp over IOVs [20, 30) of 60 (runs 201-300: it starts after run 200 and stops at run
// 300), of `total` errors in all, inside flat IOVs; statistical errors, scatter 1.
struct RampRates {
  double found = 0, start = 0, end = 0, orStep = 0, steps = 0, plainSteps = 0, flatDrifting = 0, slopePull = 0;
};

RampRates ramp(double total, int trials, std::uint64_t seed, const TrendOptions& options = {}) {
  std::mt19937_64 rng(seed);
  RampRates r;
  const auto truth = [&](std::size_t i) {
    // the IOV's mean over its runs of a ramp from run 200 to run 300
    double sum = 0.0;
    for (int run = 10 * static_cast<int>(i) + 1; run <= 10 * static_cast<int>(i) + 10; ++run) {
      sum += total * std::clamp((run - 200) / 100.0, 0.0, 1.0);
    }
    return sum / 10.0;
  };
  int pulls = 0;
  for (int k = 0; k < trials; ++k) {
    const Trend t = analyseTrend({make(60, 1.0, truth, true, rng)}, options);
    r.steps += t.steps.empty() ? 0 : 1;
    r.plainSteps += std::any_of(t.steps.begin(), t.steps.end(), [](const auto& s) { return !s.orDrift; }) ? 1 : 0;
    if (t.drifts.size() != 1) continue;
    const auto& d = t.drifts[0];
    r.found += 1;
    r.start += d.startRun && std::abs(*d.startRun - 200) <= 10 ? 1 : 0;
    r.end += d.endRun && std::abs(*d.endRun - 300) <= 10 ? 1 : 0;
    r.orStep += d.orStep ? 1 : 0;
    if (d.error > 0.0) {
      r.slopePull += std::abs(d.slopePerRun - total / 100.0) / d.error < 3.0 ? 1 : 0;
      ++pulls;
    }
    for (const auto& g : t.segments) {
      if ((g.lastRun <= 190 || g.firstRun >= 311) && !g.drifting.empty()) {
        r.flatDrifting += 1;
        break;
      }
    }
  }
  for (double* v : {&r.found, &r.start, &r.end, &r.orStep, &r.steps, &r.plainSteps, &r.flatDrifting}) *v /= trials;
  r.slopePull = pulls > 0 ? r.slopePull / pulls : 0.0;
  return r;
}

void noiseTable(int trials) {
  std::printf("## Noise alone (quoted errors: right, scatter 1; too large: 0.3; too small: 2)\n\n");
  std::printf(
      "| IOVs | scatter / error | series with a false step | with a false drift | with a period not called stable "
      "|\n|---|---|---|---|---|\n");
  for (std::size_t n : {20, 50, 106, 200, 500}) {
    for (double scatter : {1.0, 0.3, 2.0}) {
      if (n != 106 && scatter != 1.0) continue;
      const Rates r = rates(n, scatter, 0.0, 0.0, trials, 1000 + n);
      std::printf("| %zu | %.1f | %.2f %% | %.2f %% | %.2f %% |\n", n, scatter, 100 * r.steps, 100 * r.drifts,
                  100 * r.unstable);
    }
  }
  {
    TrendOptions o;
    o.penalty = 3.0 * std::log(106.0);
    const Rates r = rates(106, 1.0, 0.0, 0.0, trials, 1106, o);
    std::printf("| 106 | 1.0, penalty 3 ln n instead of 4 ln n | %.2f %% | %.2f %% | %.2f %% |\n", 100 * r.steps,
                100 * r.drifts, 100 * r.unstable);
  }
  std::printf("\n## Noise alone, statistical errors (right: scatter 1; 30 %% too small: 1.3)\n\n");
  std::printf(
      "| IOVs | scatter / error | series with a false step | with a false drift | with a period not called stable "
      "|\n|---|---|---|---|---|\n");
  for (std::size_t n : {20, 30, 50, 106, 200}) {
    for (double scatter : {1.0, 1.3}) {
      if (n != 106 && scatter != 1.0) continue;
      const Rates r = rates(n, scatter, 0.0, 0.0, trials, 5000 + n, {}, true);
      std::printf("| %zu | %.1f | %.2f %% | %.2f %% | %.2f %% |\n", n, scatter, 100 * r.steps, 100 * r.drifts,
                  100 * r.unstable);
    }
  }
}

// The newcomer's α of issue 43: IOVs of 2 runs (60 runs), statistical errors 1, a ramp of 6.5
// errors from run 8 to run 27 inside flat runs.
TrendSeries newcomer(std::mt19937_64& rng) {
  return make(
      30, 1.0,
      [](std::size_t i) {
        double sum = 0.0;
        for (int run = 2 * static_cast<int>(i) + 1; run <= 2 * static_cast<int>(i) + 2; ++run) {
          sum += 6.5 / 19.0 * std::clamp(run - 8, 0, 19);
        }
        return sum / 2.0;
      },
      true, rng, 2);
}

void kneePenaltyTable(int trials) {
  std::printf(
      "\n## The knee penalty (statistical errors): false drifts in noise; the newcomer's ramp (6.5 errors from run 8 "
      "to run 27 in IOVs of 2 runs) found with both ends within ±3 runs; a drift over the last 53 of 106 IOVs "
      "(3 errors) given a false end\n\n");
  std::printf(
      "| knee penalty: to flag, to place | false drift, 30 IOVs | false drift, 106 IOVs | newcomer: start found | both "
      "ends ± 3 runs | "
      "drift to the end: false end |\n|---|---|---|---|---|---|\n");
  const auto row = [&](const char* label, const std::function<double(double)>& penalty, double shape) {
    TrendOptions o30, o106;
    o30.kneePenalty = penalty(30.0);
    o106.kneePenalty = penalty(106.0);
    o30.kneeShapePenalty = o106.kneeShapePenalty = shape;
    const Rates a = rates(30, 1.0, 0.0, 0.0, trials, 7030, o30, true);
    const Rates b = rates(106, 1.0, 0.0, 0.0, trials, 7106, o106, true);
    std::mt19937_64 rng(7500);
    int start = 0, ends = 0, falseEnd = 0;
    for (int k = 0; k < trials; ++k) {
      const Trend t = analyseTrend({newcomer(rng)}, o30);
      if (t.drifts.size() == 1 && t.drifts[0].startRun) {
        ++start;
        ends +=
            std::abs(*t.drifts[0].startRun - 8) <= 3 && t.drifts[0].endRun && std::abs(*t.drifts[0].endRun - 27) <= 3
                ? 1
                : 0;
      }
      const Trend u = analyseTrend({make(106, 1.0, stepAndDrift(106, 0.0, 3.0 / 53.0), true, rng)}, o106);
      falseEnd += u.drifts.size() == 1 && u.drifts[0].endRun ? 1 : 0;
    }
    std::printf("| %s | %.2f %% | %.2f %% | %.1f %% | %.1f %% | %.1f %% |\n", label, 100 * a.drifts, 100 * b.drifts,
                100.0 * start / trials, 100.0 * ends / trials, 100.0 * falseEnd / trials);
  };
  row(
      "ln n, 2", [](double n) { return std::log(n); }, 2.0);
  row(
      "1.5 ln n, 2 (the default)", [](double n) { return 1.5 * std::log(n); }, 2.0);
  row(
      "1.5 ln n, 0 (the best fit)", [](double n) { return 1.5 * std::log(n); }, 0.0);
  row(
      "2 ln n, 2", [](double n) { return 2.0 * std::log(n); }, 2.0);
}

}  // namespace

int main(int argc, char** argv) {
  const int trials = argc > 1 ? std::atoi(argv[1]) : 2000;
  std::printf("# emcalign trend study, %d series per line\n\n", trials);
  noiseTable(trials);
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
    TrendOptions noKnee;
    noKnee.kneeTest = false;
    const Rates q = rates(106, 1.0, 0.0, total / 53.0, trials, seed, noKnee);
    std::printf("| %.1f | %.1f %% | %.1f %% | %.1f %% |\n", total, 100 * r.drifts, 100 * r.steps, 100 * q.steps);
  }
  std::printf(
      "\n## A drift inside flat runs: a ramp over IOVs 20-29 of 60 (runs 201-300), statistical errors (total change "
      "in units of one IOV's error)\n\n");
  std::printf(
      "| total change | drift found | start ± 10 runs | end ± 10 runs | slope within 3σ | \"or a step\" | a step "
      "reported (false) | … without a drift beside it | a flat period called drifting |\n"
      "|---|---|---|---|---|---|---|---|---|\n");
  for (double total : {3.0, 5.0, 7.0, 10.0}) {
    const RampRates r = ramp(total, trials, 4000 + static_cast<std::uint64_t>(10 * total));
    std::printf("| %.0f | %.1f %% | %.1f %% | %.1f %% | %.1f %% | %.1f %% | %.1f %% | %.1f %% | %.1f %% |\n", total,
                100 * r.found, 100 * r.start, 100 * r.end, 100 * r.slopePull, 100 * r.orStep, 100 * r.steps,
                100 * r.plainSteps, 100 * r.flatDrifting);
  }
  kneePenaltyTable(trials);
  return 0;
}
