// The trend analysis on series made by hand: steps where they are (inside an IOV too),
// drifts flagged, and nothing found in noise more often than the penalty promises.

#include "emcalign/validation/trend.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

namespace emcalign::validation {
namespace {

using io::Json;

// n IOVs of 10 runs each (runs 1-10, 11-20, ...), values from `value(i)` plus N(0, sigma).
template <class F>
TrendSeries series(std::size_t n, double sigma, std::mt19937_64& rng, F value, Quantity name = Param::Dx) {
  std::normal_distribution<double> noise(0.0, sigma);
  TrendSeries s{name, {}};
  for (std::size_t i = 0; i < n; ++i) {
    const auto first = static_cast<std::int64_t>(10 * i + 1);
    s.points.push_back({first, first + 9, value(i) + noise(rng), sigma});
  }
  return s;
}

TEST(Trend, FindsAStepAtItsIov) {
  std::mt19937_64 rng(1);
  const auto s = series(60, 0.01, rng, [](std::size_t i) { return i < 25 ? 0.25 : 0.40; });
  const Trend t = analyseTrend({s});
  ASSERT_EQ(t.steps.size(), 1u);
  EXPECT_EQ(t.steps[0].index, 25u);
  EXPECT_EQ(t.steps[0].firstRunAfter, 251);
  EXPECT_FALSE(t.steps[0].withinIov.has_value());
  EXPECT_NEAR(t.steps[0].size, 0.15, 4.0 * t.steps[0].error);
  EXPECT_GT(t.steps[0].z(), 10.0);
  EXPECT_TRUE(t.drifts.empty());
  ASSERT_EQ(t.segments.size(), 2u);
  EXPECT_EQ(t.segments[0].lastRun, 250);
  EXPECT_EQ(t.segments[1].firstRun, 251);
  EXPECT_EQ(t.segments[1].stepsAtStart, std::vector<Quantity>{Param::Dx});
}

TEST(Trend, AnIovStraddlingAStepIsATransition) {
  std::mt19937_64 rng(2);
  // IOV 30 (runs 301-310) holds 7 runs before the step and 3 after: its value is the mixture.
  const auto s = series(60, 0.01, rng, [](std::size_t i) {
    return i < 30 ? 0.25 : i == 30 ? 0.7 * 0.25 + 0.3 * 0.45 : 0.45;
  });
  const Trend t = analyseTrend({s});
  ASSERT_EQ(t.steps.size(), 1u);
  ASSERT_TRUE(t.steps[0].withinIov.has_value());
  EXPECT_EQ(t.steps[0].withinIov->first, 301);
  EXPECT_EQ(t.steps[0].withinIov->second, 310);
  EXPECT_NEAR(static_cast<double>(t.steps[0].firstRunAfter), 308.0, 1.0);  // 7 runs before
  ASSERT_EQ(t.segments.size(), 3u);
  EXPECT_FALSE(t.segments[0].transition);
  EXPECT_TRUE(t.segments[1].transition);
  EXPECT_EQ(t.segments[1].firstRun, 301);
  EXPECT_EQ(t.segments[1].lastRun, 310);
  EXPECT_FALSE(t.segments[2].transition);
  EXPECT_TRUE(t.drifts.empty()) << t.drifts[0].parameter;
  const auto j = trendJson(t, {s});
  EXPECT_EQ(j["steps"][0]["within_iov"][0], 301);
  EXPECT_TRUE(j["segments"][1]["transition"].get<bool>());
}

TEST(Trend, FlagsADriftAndDoesNotCutIt) {
  std::mt19937_64 rng(3);
  // Constant for 40 IOVs, then 0.001 per IOV (0.0001 per run) for 40 more.
  const auto s = series(80, 0.005, rng, [](std::size_t i) { return 0.15 + (i < 40 ? 0.0 : 0.001 * (i - 40.0)); });
  const Trend t = analyseTrend({s});
  EXPECT_TRUE(t.steps.empty()) << t.steps[0].z();
  ASSERT_EQ(t.drifts.size(), 1u);
  EXPECT_NEAR(t.drifts[0].slopePerRun, 1e-4, 4.0 * t.drifts[0].error);
  EXPECT_GE(t.drifts[0].firstRun, 301);  // where the line starts is loosely determined
  EXPECT_LE(t.drifts[0].firstRun, 551);
  EXPECT_EQ(t.drifts[0].lastRun, 800);
  ASSERT_FALSE(t.segments.empty());
  EXPECT_EQ(t.segments.back().drifting, std::vector<Quantity>{Param::Dx});
}

// A drift starting inside a series is a knee, not a step: a continuous broken line fits it.
TEST(Trend, ADriftStartingMidwayIsNoStep) {
  std::mt19937_64 rng(8);
  int steps = 0;
  for (int k = 0; k < 100; ++k) {
    const auto s = series(106, 1.0, rng, [](std::size_t i) { return i < 53 ? 0.0 : 6.0 * (i - 53.0) / 53.0; });
    steps += analyseTrend({s}).steps.empty() ? 0 : 1;
  }
  EXPECT_LE(steps, 6);  // 2 % in bench/trend_study.cpp
}

// The penalty 4 ln n keeps false steps and drifts rare in pure noise (docs/campaign.md).
TEST(Trend, NoiseAloneRarelyMakesAStepOrADrift) {
  std::mt19937_64 rng(4);
  int falseSteps = 0, falseDrifts = 0;
  const int trials = 300;
  for (int k = 0; k < trials; ++k) {
    const auto s = series(100, 0.01, rng, [](std::size_t) { return 0.3; });
    const Trend t = analyseTrend({s});
    falseSteps += t.steps.empty() ? 0 : 1;
    falseDrifts += t.drifts.empty() ? 0 : 1;
  }
  EXPECT_LE(falseSteps, trials * 3 / 100) << falseSteps;
  EXPECT_LE(falseDrifts, trials * 3 / 100) << falseDrifts;
}

TEST(Trend, ErrorScaleFollowsTheScatter) {
  // The scale is the scatter / error ratio at the upper end of its uncertainty (×(1 + 2.3/√m)).
  const double upper = 1.0 + 2.3 / std::sqrt(399.0);
  std::mt19937_64 rng(5);
  auto s = series(400, 3.0, rng, [](std::size_t) { return 0.0; });
  for (auto& p : s.points) p.error = 1.0;  // the errors say 1, the points scatter by 3
  EXPECT_NEAR(errorScale(s), 3.0 * upper, 0.55);
  // Errors larger than the scatter (a systematic common to every IOV, as σ_sys): scaled down.
  auto t = series(400, 0.3, rng, [](std::size_t) { return 0.0; });
  for (auto& p : t.points) p.error = 1.0;
  EXPECT_NEAR(errorScale(t), 0.3 * upper, 0.055);  // 3 standard errors of the estimate
  // Too few points to tell: left as they are.
  auto u = series(5, 0.3, rng, [](std::size_t) { return 0.0; });
  for (auto& p : u.points) p.error = 1.0;
  EXPECT_EQ(errorScale(u), 1.0);
}

TEST(Trend, LineFitIsExactOnALine) {
  TrendSeries s{Param::Dz, {}};
  for (int i = 0; i < 10; ++i) s.points.push_back({10 * i + 1, 10 * i + 10, 0.1 + 0.002 * (10 * i + 5.5), 0.01});
  const LineFit f = fitLine(s, 0, 10, 1.0, true);
  EXPECT_NEAR(f.b, 0.002, 1e-12);
  EXPECT_NEAR(f.value(5.5), 0.1 + 0.002 * 5.5, 1e-12);
  EXPECT_NEAR(f.chi2, 0.0, 1e-9);
  const LineFit c = fitLine(s, 0, 10, 1.0, false);
  EXPECT_EQ(c.b, 0.0);
  EXPECT_GT(c.chi2, 100.0);
}

TEST(Trend, ShortSeries) {
  std::mt19937_64 rng(6);
  // Three points: too few for two segments.
  const auto three = series(3, 0.01, rng, [](std::size_t i) { return i < 1 ? 0.0 : 1.0; });
  EXPECT_TRUE(changePoints(three, 1.0, 10.0, 2.0, 2).empty());
  // (the first IOV departs from the two after it: an edge, a period of its own)
  const Trend short3 = analyseTrend({three});
  ASSERT_EQ(short3.segments.size(), 2u);
  EXPECT_EQ(short3.segments[0].departing, std::vector<Quantity>{Param::Dx});
  // Seven IOVs (a period cut into groups of 50 000): a step is still found, between constants.
  const auto seven = series(7, 0.01, rng, [](std::size_t i) { return i < 3 ? 0.3 : 0.45; });
  const Trend t = analyseTrend({seven});
  ASSERT_EQ(t.steps.size(), 1u);
  EXPECT_EQ(t.steps[0].firstRunAfter, 31);
}

// Steps of several parameters at one change of the detector make one boundary.
TEST(Trend, StepsOfSeveralParametersMakeOneBoundary) {
  std::mt19937_64 rng(7);
  const auto dx = series(
      50, 0.01, rng, [](std::size_t i) { return i < 20 ? 0.3 : 0.4; }, Param::Dx);
  const auto psi = series(
      50, 1.0, rng, [](std::size_t i) { return i < 20 ? 40.0 : 110.0; }, Physical::Psi);
  const auto alpha = series(
      50, 0.01, rng, [](std::size_t) { return 2.9; }, Param::Alpha);
  const Trend t = analyseTrend({alpha, dx, psi});
  ASSERT_EQ(t.steps.size(), 2u);
  ASSERT_EQ(t.segments.size(), 2u);
  EXPECT_EQ(t.segments[1].firstRun, 201);
  EXPECT_EQ(t.segments[1].stepsAtStart.size(), 2u);
}

// A change seen inside IOV 30 by one parameter and as a plain step at IOV 31 by a stronger
// one: IOV 30 is still the transition (its calibration mixes the two detectors).
TEST(Trend, ATransitionSeenByOneParameterIsKept) {
  std::mt19937_64 rng(9);
  const auto dx = series(
      60, 0.01, rng, [](std::size_t i) { return i < 30    ? 0.25
                                                : i == 30 ? 0.3
                                                          : 0.45; }, Param::Dx);
  const auto psi = series(
      60, 1.0, rng, [](std::size_t i) { return i <= 30 ? 40.0 : 115.0; }, Physical::Psi);
  const Trend t = analyseTrend({dx, psi});
  ASSERT_EQ(t.steps.size(), 2u);
  ASSERT_EQ(t.segments.size(), 3u);
  EXPECT_TRUE(t.segments[1].transition);
  EXPECT_EQ(t.segments[1].firstRun, 301);
  EXPECT_EQ(t.segments[2].firstRun, 311);
  EXPECT_EQ(t.segments[2].stepsAtStart.size(), 2u);
}

// Too few IOVs to locate a step (2 × min-segment): the trend says so, and names a parameter
// its one value cannot describe, instead of "no step" (issue 29: two IOVs 26σ apart).
TEST(Trend, TooFewIovsIsSaidAndAnInconsistentSeriesNamed) {
  for (std::size_t n : {2u}) {
    TrendSeries dx{Param::Dx, {}}, alpha{Param::Alpha, {}};
    for (std::size_t i = 0; i < n; ++i) {
      const auto first = static_cast<std::int64_t>(10 * i + 101);
      dx.points.push_back({first, first + 9, i == 0 ? -0.196 : -0.075, 0.004});
      alpha.points.push_back({first, first + 9, 2.8 + 0.01 * static_cast<double>(i % 2), 0.03});
    }
    const Trend t = analyseTrend({alpha, dx});
    EXPECT_FALSE(t.resolvable());
    EXPECT_TRUE(t.steps.empty());
    ASSERT_EQ(t.inconsistencies.size(), 1u) << n;
    EXPECT_EQ(t.inconsistencies[0].parameter, Param::Dx);
    EXPECT_TRUE(t.inconsistencies[0].unsplittable);
    EXPECT_EQ(t.inconsistencies[0].ndf, static_cast<int>(n) - 1);
    EXPECT_GT(t.inconsistencies[0].chi2, 400.0);
    const std::string verdict = trendVerdict(t);
    EXPECT_NE(verdict.find("Too few IOVs to locate a step"), std::string::npos) << verdict;
    EXPECT_NE(verdict.find("dx"), std::string::npos) << verdict;
    EXPECT_EQ(verdict.find("No step"), std::string::npos) << verdict;
    const std::string md = trendMarkdown(t, {alpha, dx}, {"test"});
    EXPECT_EQ(md.find("No step"), std::string::npos) << md;
    EXPECT_NE(md.find("Drifts not tested"), std::string::npos) << md;
    EXPECT_EQ(md.find("No drift"), std::string::npos) << md;
    EXPECT_EQ(trendJson(t, {alpha, dx}).at("inconsistent").size(), 1u);
    ASSERT_EQ(t.segments.size(), 1u);
    EXPECT_EQ(t.segments[0].inconsistent, std::vector<Quantity>{Param::Dx});
  }
  // Three IOVs, the first apart from the two after it: the edge is named, still not "no step".
  {
    TrendSeries dx{Param::Dx, {{101, 110, -0.196, 0.004}, {111, 120, -0.075, 0.004}, {121, 130, -0.0752, 0.004}}};
    const Trend t = analyseTrend({dx});
    EXPECT_FALSE(t.resolvable());
    ASSERT_EQ(t.edges.size(), 1u);
    EXPECT_FALSE(t.edges[0].atEnd);
    EXPECT_NEAR(t.edges[0].departure, -0.121, 0.002);
    const std::string verdict = trendVerdict(t);
    EXPECT_NE(verdict.find("Too few IOVs to locate a step"), std::string::npos) << verdict;
    EXPECT_NE(verdict.find("dx in the first IOV (runs 101-110)"), std::string::npos) << verdict;
    EXPECT_EQ(verdict.find("No step"), std::string::npos) << verdict;
    EXPECT_EQ(verdict.find("no parameter differs"), std::string::npos) << verdict;
  }
  // Consistent values: too few IOVs is still said, with no parameter blamed, and the one
  // period is not called stable (issue 29: "1 of 1 period stable" beside "too few IOVs").
  TrendSeries flat{Param::Dx, {{1, 10, 0.1, 0.01}, {11, 20, 0.105, 0.01}, {21, 30, 0.098, 0.01}}};
  const Trend t = analyseTrend({flat});
  EXPECT_TRUE(t.inconsistencies.empty());
  EXPECT_NE(trendVerdict(t).find("Too few IOVs"), std::string::npos);
  EXPECT_NE(trendVerdict(t).find("no parameter differs"), std::string::npos);
  ASSERT_EQ(t.segments.size(), 1u);
  EXPECT_FALSE(t.segments[0].stable());
  const std::string md = trendMarkdown(t, {flat}, {"test"});
  EXPECT_NE(md.find("(0 stable)"), std::string::npos) << md;
  EXPECT_NE(md.find("consistent with one value, but not called stable"), std::string::npos) << md;
  EXPECT_FALSE(trendJson(t, {flat}).at("segments")[0].at("stable").get<bool>());
}

// A short series whose step the error scale blurs (issue 29's newcomer period: dx 0.40 ->
// 0.30 at run 161, 6 IOVs after a step at 83, the scatter/error scale 5.5 from the steps
// themselves): the partitioning keeps one line, flagged as a drift; a step fits it far better
// and is reported beside it (where beta1 steps too), never a drift alone. A true drift over
// 12 IOVs gets no step alternative.
TEST(Trend, ADriftThatAStepFitsAsWellIsReportedAsEither) {
  TrendSeries dx{Param::Dx, {}}, beta1{Param::Beta1, {}};
  const std::vector<std::tuple<std::int64_t, std::int64_t, double, double, double>> iovs = {
      {1, 22, 0.2485, 0.0037, 0.1877},    {23, 47, 0.2507, 0.0033, 0.2014},    {48, 69, 0.2489, 0.0034, 0.1763},
      {70, 91, 0.3271, 0.0035, 0.1958},   {92, 120, 0.4004, 0.0034, 0.2071},   {121, 141, 0.3998, 0.0036, 0.1920},
      {142, 162, 0.3891, 0.0035, 0.1535}, {163, 183, 0.3022, 0.0039, -0.1208}, {184, 204, 0.2915, 0.0035, -0.0910},
      {205, 240, 0.3024, 0.0027, -0.0965}};
  for (const auto& [first, last, x, e, b] : iovs) {
    dx.points.push_back({first, last, x, e});
    beta1.points.push_back({first, last, b, 0.01});
  }
  // dx alone: flagged as a drift, the step reported beside it (fitting better).
  const Trend t = analyseTrend({dx});
  ASSERT_EQ(t.drifts.size(), 1u);
  const TrendDrift& d = t.drifts[0];
  EXPECT_EQ(d.parameter, Param::Dx);
  ASSERT_TRUE(d.orStep.has_value());
  EXPECT_TRUE(d.orStep->preferred());
  EXPECT_EQ(d.orStep->firstRunAfter, 163);
  EXPECT_NEAR(d.orStep->size, -0.097, 0.005);
  EXPECT_LT(d.orStep->chi2Step, 1.0);
  const std::string text = stepAlternativeText(t, d);
  EXPECT_NE(text.find("a step fits better: -0.09"), std::string::npos) << text;
  EXPECT_NE(trendMarkdown(t, {dx}, {"test"}).find("drifting: dx (or a step"), std::string::npos);
  EXPECT_FALSE(trendJson(t, {dx}).at("drifts")[0].at("or_step").is_null());
  // The figure draws the step's two constants, not the line.
  for (const auto& f : trendFigures(t, {dx})) {
    const auto drawn = std::count_if(f.segments.begin(), f.segments.end(), [](const auto& l) { return l.orStep; });
    EXPECT_EQ(drawn, 2);
  }
  // With beta1 stepping at the same run (a reassembly), it is that step: no drift, the periods
  // after it stable (issue 29's third try: "drifting: dx" where dx was constant).
  const Trend u = analyseTrend({beta1, dx});
  EXPECT_TRUE(u.drifts.empty());
  const auto step = std::find_if(u.steps.begin(), u.steps.end(), [](const TrendStep& st) {
    return st.parameter == Param::Dx && st.firstRunAfter == 163;
  });
  ASSERT_NE(step, u.steps.end()) << trendMarkdown(u, {beta1, dx}, {"test"});
  EXPECT_NEAR(step->size, -0.097, 0.005);
  ASSERT_TRUE(step->insteadOfDrift.has_value());
  EXPECT_GT(step->insteadOfDrift->second, step->insteadOfDrift->first);  // the drift fits worse
  for (const auto& g : u.segments) EXPECT_TRUE(g.drifting.empty()) << g.firstRun;

  std::mt19937_64 rng(31);
  const auto drift = series(12, 0.003, rng, [](std::size_t i) { return 0.3 + 0.01 * static_cast<double>(i); });
  const Trend v = analyseTrend({drift});
  ASSERT_EQ(v.drifts.size(), 1u);
  EXPECT_FALSE(v.drifts[0].orStep.has_value()) << stepAlternativeText(v, v.drifts[0]);
}

// A step of one parameter an IOV away from the IOV that straddles another's change is a change
// of its own: the periods start at both, and none that holds a step is called stable (issue
// 29: beta_rel's step at run 48 inside "runs 1-69: stable", blamed on dx's change at 70-91).
TEST(Trend, AStepAnIovAwayFromATransitionStartsItsOwnPeriod) {
  std::mt19937_64 rng(48);
  const auto dx = series(
      30, 0.003, rng, [](std::size_t i) { return i < 12    ? 0.25
                                                 : i == 12 ? 0.30
                                                           : 0.40; }, Param::Dx);
  const auto beta = series(
      30, 0.003, rng, [](std::size_t i) { return i < 11 ? 0.08 : 0.12; }, Param::BetaRel);
  const Trend t = analyseTrend({dx, beta});
  ASSERT_EQ(t.steps.size(), 2u);
  std::vector<std::int64_t> starts;
  for (const auto& g : t.segments) starts.push_back(g.firstRun);
  EXPECT_EQ(starts, (std::vector<std::int64_t>{1, 111, 121, 131})) << trendMarkdown(t, {dx, beta}, {"test"});
  EXPECT_EQ(t.segments[1].stepsAtStart, std::vector<Quantity>{Param::BetaRel});
  EXPECT_TRUE(t.segments[2].transition);
}

// A step one IOV before the end (issue 29: dx 0.30 -> 0.45 in the last of 12 IOVs) is an
// edge, not a drift: no drift flagged, the segment before it stable, the IOV named.
TEST(Trend, AStepInTheLastIovIsAnEdgeNotADrift) {
  std::mt19937_64 rng(29);
  const auto dx = series(12, 0.01, rng, [](std::size_t i) { return i < 11 ? 0.30 : 0.45; });
  const auto alpha = series(
      12, 0.02, rng, [](std::size_t) { return 2.9; }, Param::Alpha);
  const Trend t = analyseTrend({alpha, dx});
  EXPECT_TRUE(t.drifts.empty());
  EXPECT_TRUE(t.steps.empty());
  EXPECT_TRUE(t.inconsistencies.empty());
  ASSERT_EQ(t.edges.size(), 1u);
  EXPECT_EQ(t.edges[0].parameter, Param::Dx);
  EXPECT_TRUE(t.edges[0].atEnd);
  EXPECT_EQ(t.edges[0].firstRun, 111);
  EXPECT_NEAR(t.edges[0].departure, 0.15, 0.05);
  ASSERT_EQ(t.segments.size(), 2u);
  EXPECT_TRUE(t.segments[0].stable());
  EXPECT_EQ(t.segments[1].departing, std::vector<Quantity>{Param::Dx});
  EXPECT_FALSE(t.segments[1].stable());
  const std::string md = trendMarkdown(t, {alpha, dx}, {"test"});
  EXPECT_NE(md.find("## An IOV at an end of the tag departs"), std::string::npos) << md;
  EXPECT_EQ(md.find("## Drifts"), std::string::npos) << md;
  EXPECT_EQ(md.find("No step:"), std::string::npos) << md;
  EXPECT_EQ(trendJson(t, {alpha, dx}).at("edges").size(), 1u);
  // The figure: the segment ends before the edge IOV, flat.
  const auto figures = trendFigures(t, {alpha, dx});
  ASSERT_EQ(figures.size(), 2u);
  ASSERT_FALSE(figures[1].segments.empty());
  EXPECT_EQ(figures[1].segments.back().x1, 110.0);
  for (const auto& l : figures[1].segments) {
    EXPECT_FALSE(l.drift);
    EXPECT_NEAR(l.y0, 0.30, 0.02);
    EXPECT_NEAR(l.y1, 0.30, 0.02);
  }
  // In noise alone, no edge.
  std::mt19937_64 quiet(30);
  int found = 0;
  for (int k = 0; k < 200; ++k) {
    const auto flat = series(12, 0.01, quiet, [](std::size_t) { return 0.3; });
    found += analyseTrend({flat}).edges.empty() ? 0 : 1;
  }
  EXPECT_LE(found, 6) << "edges in 200 series of noise";
}

// Enough IOVs to locate a step, but values that no step (two IOVs on each side) explains:
// reported, not "no step".
TEST(Trend, ASegmentItsModelDoesNotFitIsReported) {
  const TrendSeries s{Param::Dx, {{1, 10, 0.3, 0.01}, {11, 20, 0.4, 0.01}, {21, 30, 0.4, 0.01}, {31, 40, 0.3, 0.01}}};
  const Trend t = analyseTrend({s});
  EXPECT_TRUE(t.resolvable());
  EXPECT_TRUE(t.steps.empty());
  ASSERT_FALSE(t.inconsistencies.empty());
  EXPECT_FALSE(t.inconsistencies[0].unsplittable);
  EXPECT_NE(trendVerdict(t).find("No step located, but"), std::string::npos) << trendVerdict(t);
}

// An outlier in a long series is set aside between two segments (a "transition" without a
// step): said in the verdict and the text, never silent.
TEST(Trend, AnIovSetAsideIsReported) {
  std::mt19937_64 rng(11);
  auto s = series(20, 0.01, rng, [](std::size_t) { return 0.3; });
  s.points[9].value += 0.1;
  const Trend t = analyseTrend({s});
  EXPECT_TRUE(t.steps.empty());
  ASSERT_EQ(t.setAside.size(), 1u);
  EXPECT_EQ(t.setAside[0].firstRun, 91);
  EXPECT_NE(trendVerdict(t).find("runs 91-100"), std::string::npos) << trendVerdict(t);
  EXPECT_NE(trendMarkdown(t, {s}, {"test"}).find("- runs 91-100: dx"), std::string::npos);
}

TEST(Trend, NoiseAloneGetsACleanVerdict) {
  std::mt19937_64 rng(14);
  // Noise alone: a clean verdict, and the χ² test is passed by (nearly) every noise series.
  int flagged = 0, remarked = 0;
  for (int k = 0; k < 200; ++k) {
    const auto n = series(40, 0.01, rng, [](std::size_t) { return 0.3; });
    const Trend u = analyseTrend({n});
    flagged += u.inconsistencies.empty() ? 0 : 1;
    if (u.steps.empty() && u.inconsistencies.empty() && u.setAside.empty()) {
      EXPECT_EQ(trendVerdict(u), "No step: no parameter changed between IOVs more than its errors allow.");
    } else {
      ++remarked;
    }
  }
  EXPECT_LE(flagged, 6) << "of 200 noise series";
  EXPECT_LE(remarked, 10) << "of 200 noise series";
}

// A step between segments whose slopes are not significant is measured between their means,
// not between lines bent by noise (issue 29: +0.132 ± 0.010 from lines for a true +0.150).
TEST(Trend, AStepBetweenFlatSegmentsIsTheDifferenceOfTheirMeans) {
  std::mt19937_64 rng(12);
  for (int k = 0; k < 20; ++k) {
    const auto s = series(16, 0.005, rng, [](std::size_t i) { return i < 8 ? -0.2 : -0.05; });
    const Trend t = analyseTrend({s});
    ASSERT_EQ(t.steps.size(), 1u);
    const auto& segs = t.series[0].segments;
    ASSERT_EQ(segs.size(), 2u);
    if (segs[0].sloped || segs[1].sloped) continue;
    EXPECT_NEAR(t.steps[0].size, segs[1].constant.a - segs[0].constant.a, 1e-12);
    EXPECT_NEAR(t.steps[0].size, 0.15, 4.0 * t.steps[0].error);
  }
}

// Known boundaries: the series is cut there whatever the data say; what changed is reported,
// and a boundary inside an IOV makes it a transition.
TEST(Trend, KnownBoundariesAreCutAndMeasured) {
  std::mt19937_64 rng(13);
  const auto dx = series(
      30, 0.01, rng, [](std::size_t i) { return i < 15 ? 0.25 : 0.40; }, Param::Dx);
  const auto alpha = series(
      30, 0.01, rng, [](std::size_t) { return 2.9; }, Param::Alpha);
  TrendOptions o;
  o.boundaries = {151, 75, 100000};  // at IOV 15; inside IOV 7 (runs 71-80); after the series
  const Trend t = analyseTrend({alpha, dx}, o);
  ASSERT_EQ(t.boundaries.size(), 3u);
  EXPECT_EQ(t.boundaries[0].run, 75);
  ASSERT_TRUE(t.boundaries[0].withinIov.has_value());
  EXPECT_EQ(t.boundaries[0].withinIov->first, 71);
  EXPECT_TRUE(t.boundaries[0].changed.empty());
  EXPECT_TRUE(t.boundaries[0].measurable);
  EXPECT_EQ(t.boundaries[1].run, 151);
  EXPECT_EQ(t.boundaries[1].changed, std::vector<Quantity>{Param::Dx});
  EXPECT_FALSE(t.boundaries[2].measurable);
  ASSERT_EQ(t.steps.size(), 1u);
  EXPECT_TRUE(t.steps[0].known);
  EXPECT_EQ(t.steps[0].firstRunAfter, 151);
  EXPECT_NEAR(t.steps[0].size, 0.15, 4.0 * t.steps[0].error);
  // Periods: 1-70, the transition 71-80, 81-150, 151-300.
  ASSERT_EQ(t.segments.size(), 4u);
  EXPECT_TRUE(t.segments[1].transition);
  EXPECT_EQ(t.segments[1].firstRun, 71);
  EXPECT_TRUE(t.segments[2].afterKnownBoundary);
  EXPECT_EQ(t.segments[3].firstRun, 151);
  EXPECT_TRUE(t.segments[3].afterKnownBoundary);
  const auto changes = knownChanges(dx, {75, 151});
  ASSERT_EQ(changes.size(), 2u);
  EXPECT_EQ(changes[0], (Change{8, true}));
  EXPECT_EQ(changes[1], (Change{15, false}));
  const std::string md = trendMarkdown(t, {alpha, dx}, {"test"});
  EXPECT_NE(md.find("run 75 (inside IOV 71-80, set aside): no parameter changed"), std::string::npos) << md;
}

TEST(Trend, ACampaignIsWarnedWhenItsIovsAreTooFewForATrend) {
  EXPECT_NE(tooFewIovsForTrend(3, 160000).find("3 IOVs"), std::string::npos);
  EXPECT_NE(tooFewIovsForTrend(3, 160000).find("--min-events 26000"), std::string::npos);
  EXPECT_TRUE(tooFewIovsForTrend(4, 160000).empty());
}

// trend.json read back (parseTrend) holds what the analysis found: its steps (one inside an
// IOV), drifts with their step alternative in words, periods, inconsistencies and verdict, in
// the analysis' own types; a file of another kind, or an unknown parameter, is refused by key.
TEST(Trend, TheFileReadsBackAsTheAnalysisFound) {
  std::mt19937_64 rng(12);
  const auto dx = series(40, 0.01, rng, [](std::size_t i) { return i < 20 ? 0.25 : i == 20 ? 0.31 : 0.45; });
  const auto dz = series(
      40, 0.01, rng, [](std::size_t i) { return 0.1 + 0.004 * static_cast<double>(i); }, Param::Dz);
  const Trend t = analyseTrend({dx, dz});
  ASSERT_FALSE(t.steps.empty());
  ASSERT_FALSE(t.drifts.empty());
  Json file = trendJson(t, {dx, dz});
  file["tag"] = "t";
  file["models"] = {"the paper's model"};
  auto read = parseTrend(file, "trend.json");
  ASSERT_TRUE(read.ok()) << read.error().message;
  const TrendRecord& r = *read;
  EXPECT_EQ(r.tag, "t");
  EXPECT_TRUE(r.conditions.empty());
  EXPECT_EQ(r.models, std::vector<std::string>{"the paper's model"});
  EXPECT_EQ(r.iovs, t.iovs);
  EXPECT_EQ(r.verdict, trendVerdict(t));
  EXPECT_EQ(r.driftTests, t.tests);
  ASSERT_EQ(r.steps.size(), t.steps.size());
  for (std::size_t k = 0; k < t.steps.size(); ++k) {
    EXPECT_EQ(r.steps[k].step.parameter, t.steps[k].parameter);
    EXPECT_EQ(r.steps[k].step.firstRunAfter, t.steps[k].firstRunAfter);
    EXPECT_EQ(r.steps[k].step.withinIov, t.steps[k].withinIov);
    EXPECT_DOUBLE_EQ(r.steps[k].step.z(), t.steps[k].z());
    EXPECT_TRUE(std::isnan(r.steps[k].trueSize));  // no truth given
  }
  ASSERT_EQ(r.drifts.size(), t.drifts.size());
  for (std::size_t k = 0; k < t.drifts.size(); ++k) {
    EXPECT_EQ(r.drifts[k].drift.parameter, t.drifts[k].parameter);
    EXPECT_EQ(r.drifts[k].drift.firstRun, t.drifts[k].firstRun);
    EXPECT_DOUBLE_EQ(r.drifts[k].drift.slopePerRun, t.drifts[k].slopePerRun);
    EXPECT_EQ(r.drifts[k].drift.orStep.has_value(), t.drifts[k].orStep.has_value());
    EXPECT_EQ(r.drifts[k].orStepText, stepAlternativeText(t, t.drifts[k]));
  }
  ASSERT_EQ(r.segments.size(), t.segments.size());
  for (std::size_t k = 0; k < t.segments.size(); ++k) {
    EXPECT_EQ(r.segments[k].firstRun, t.segments[k].firstRun);
    EXPECT_EQ(r.segments[k].end - r.segments[k].begin, t.segments[k].end - t.segments[k].begin);
    EXPECT_EQ(r.segments[k].stable(), t.segments[k].stable()) << "period " << k;
    EXPECT_EQ(r.segments[k].drifting, t.segments[k].drifting);
    EXPECT_EQ(r.segments[k].transition, t.segments[k].transition);
  }
  EXPECT_EQ(r.inconsistencies.size(), t.inconsistencies.size());

  const auto refusal = [&](auto change) {
    Json j = file;
    change(j);
    auto bad = parseTrend(j, "d/trend.json");
    return bad.ok() ? std::string("accepted") : bad.error().message;
  };
  EXPECT_EQ(refusal([](Json& j) { j["format"] = "emcalign-compare/1"; }),
            "d/trend.json: key 'format': expected \"emcalign-trend/1\"");
  EXPECT_EQ(refusal([](Json& j) { j["steps"][0]["parameter"] = "gamma"; }),
            "d/trend.json: key 'steps[0].parameter': unknown parameter 'gamma'");
  EXPECT_EQ(refusal([](Json& j) {
              j["segments"][0]["drifting"] = {"dx", 3};
            }),
            "d/trend.json: key 'segments[0].drifting[1]': expected a string");
  EXPECT_EQ(refusal([](Json& j) { j["drifts"][0]["first_run"] = "5"; }),
            "d/trend.json: key 'drifts[0].first_run': expected an integer, got string");
}

}  // namespace
}  // namespace emcalign::validation

namespace emcalign::validation {
namespace {

// A series of IOVs of `runsPerIov` runs from run 1 on, each run with `eventsPerRun` selected
// events: an IOV's value is the mean of truth(run) over its runs plus noise of its statistical
// error perEvent/√(its events), which is what it records (statistical errors).
template <class F>
TrendSeries ofRuns(int runs, int runsPerIov, double eventsPerRun, double perEvent, std::mt19937_64& rng, F truth,
                   Quantity name = Param::Alpha) {
  std::normal_distribution<double> noise(0.0, 1.0);
  TrendSeries s{name, {}, true};
  for (int first = 1; first <= runs; first += runsPerIov) {
    const int last = std::min(runs, first + runsPerIov - 1);
    double sum = 0.0;
    for (int r = first; r <= last; ++r) sum += truth(r);
    const double events = eventsPerRun * (last - first + 1), error = perEvent / std::sqrt(events);
    s.points.push_back({first, last, sum / (last - first + 1) + error * noise(rng), error, 3.0 * error,
                        static_cast<std::int64_t>(events)});
  }
  return s;
}

// The issue-43 newcomer's α: flat, a ramp of 0.105° from run 8 to run 27 (6.5 statistical
// errors of one IOV), flat again; IOVs of 2 runs (20 000 events), 60 runs.
double newcomerAlpha(int run) { return 2.9 + 0.0055 * std::clamp(run - 8, 0, 19); }

// A drift inside flat runs is found with its start and its end, no step alternative, and the
// flat runs around it are periods of their own, stable (issue 43: "drift alpha runs 1-28 … or a
// step", the flat runs after it called drifting). A knee is seen by the few IOVs around it: its
// own uncertainty is about 1.5 IOVs here (3 runs), so both ends are within ±3 runs in half the
// series, and the truth within the ranges given in about 2 of 3 (bench/trend_study.cpp). The
// rates below are those measured on these 100 series (fixed seed), less a margin.
TEST(Trend, ADriftInsideFlatRunsIsFoundWithItsEnds) {
  std::mt19937_64 rng(43);
  const int trials = 100;
  int found = 0, ends = 0, slopes = 0, orStep = 0, steps = 0, flatDrifting = 0, flatUnstable = 0, ends6 = 0,
      covered = 0, open = 0;
  for (int k = 0; k < trials; ++k) {
    const auto alpha = ofRuns(60, 2, 10000.0, 2.26, rng, newcomerAlpha);
    const Trend t = analyseTrend({alpha});
    steps += t.steps.empty() ? 0 : 1;
    if (t.drifts.size() != 1) continue;
    const TrendDrift& d = t.drifts[0];
    ++found;
    ends += d.startRun && d.endRun && std::abs(*d.startRun - 8) <= 3 && std::abs(*d.endRun - 27) <= 3 ? 1 : 0;
    ends6 += d.startRun && d.endRun && std::abs(*d.startRun - 8) <= 6 && std::abs(*d.endRun - 27) <= 6 ? 1 : 0;
    covered += d.startRange.first <= 8 && 8 <= d.startRange.second ? 1 : 0;
    covered += d.endRange.first <= 27 && 27 <= d.endRange.second ? 1 : 0;
    open += d.startRun ? 0 : 1;
    slopes += std::abs(d.slopePerRun - 0.0055) < 3.0 * d.error ? 1 : 0;
    orStep += d.orStep ? 1 : 0;
    for (const auto& g : t.segments) {
      if (g.firstRun < 33) continue;  // the flat runs after the ramp
      flatDrifting += g.drifting.empty() ? 0 : 1;
      flatUnstable += g.stable() ? 0 : 1;
    }
  }
  EXPECT_GE(found, 95);                                               // measured 98
  EXPECT_GE(ends, 40) << "ends within ±3";                            // 50
  EXPECT_GE(ends6, 50) << "within ±6";                                // 62
  EXPECT_GE(covered, 100) << "of 2 x 100 knees within their ranges";  // 124 (Δχ² < 1: about 68 %)
  EXPECT_GE(slopes, 75);                                              // 84
  EXPECT_LE(orStep, 20);                                              // 12
  EXPECT_LE(steps, 8);                                                // 4
  EXPECT_EQ(flatDrifting, 0);
  EXPECT_LE(flatUnstable, 5);  // 0
  EXPECT_LE(open, 45);         // 35: the start's knee not worth its place
  // One series in full: the periods are the flat runs, the drift, the flat runs.
  std::mt19937_64 one(7);
  const auto alpha = ofRuns(60, 2, 10000.0, 2.26, one, newcomerAlpha);
  const Trend t = analyseTrend({alpha});
  ASSERT_EQ(t.drifts.size(), 1u);
  const TrendDrift& d = t.drifts[0];
  ASSERT_TRUE(d.startRun && d.endRun);
  const std::string extent = driftExtentText(d);
  EXPECT_EQ(extent.rfind(fmt::format("from run {} (", *d.startRun), 0), 0u) << extent;
  EXPECT_NE(extent.find(fmt::format(" to run {} (", *d.endRun)), std::string::npos) << extent;
  ASSERT_EQ(t.segments.size(), 3u) << trendMarkdown(t, {alpha}, {"test"});
  EXPECT_TRUE(t.segments[0].stable());
  EXPECT_EQ(t.segments[1].drifting, std::vector<Quantity>{Param::Alpha});
  EXPECT_FALSE(t.segments[1].refittable());
  EXPECT_TRUE(t.segments[2].stable());
  const Json j = trendJson(t, {alpha});
  EXPECT_EQ(j["drifts"][0]["start_run"], *d.startRun);
  EXPECT_EQ(j["drifts"][0]["end_run"], *d.endRun);
  // The figure: flat, the ramp (a drift), flat.
  const auto figures = trendFigures(t, {alpha});
  ASSERT_EQ(figures[0].segments.size(), 3u);
  EXPECT_FALSE(figures[0].segments[0].drift);
  EXPECT_TRUE(figures[0].segments[1].drift);
  EXPECT_FALSE(figures[0].segments[2].drift);
}

// A ramp inside flat runs is not a plain step: where the change-point analysis cuts it, the
// step is either dropped (the drift fits better by 9) or reported with the drift beside it, and
// the IOVs a drift would span are no stable period.
TEST(Trend, ARampIsNeverAPlainStep) {
  std::mt19937_64 rng(44);
  int plain = 0, withDrift = 0;
  for (int k = 0; k < 100; ++k) {
    // 60 IOVs of 10 runs, a ramp of 5 errors over runs 201-300.
    const auto s = ofRuns(
        600, 10, 1.0, 1.0 * std::sqrt(10.0), rng, [](int r) { return 5.0 * std::clamp((r - 200) / 100.0, 0.0, 1.0); },
        Param::Dx);
    const Trend t = analyseTrend({s});
    for (const auto& st : t.steps) {
      if (!st.orDrift) {
        ++plain;
        continue;
      }
      ++withDrift;
      for (const auto& g : t.segments) {
        if (g.firstRun >= st.orDrift->firstRun && g.lastRun <= st.orDrift->lastRun) {
          EXPECT_FALSE(g.stable());
        }
      }
    }
  }
  EXPECT_LE(plain, 5);
  EXPECT_GT(withDrift, 0);
}

// Stability is judged on the statistical errors: IOVs that scatter twice their statistical
// errors make no stable period (and no refit), whatever their quoted errors say; quoted errors
// (a tag of older payloads) are brought to the measured scatter first.
TEST(Trend, StabilityIsJudgedOnTheStatisticalErrors) {
  std::mt19937_64 rng(45);
  auto scattering = ofRuns(
      40, 1, 20000.0, 2.26, rng, [](int) { return 0.3; }, Param::Dx);
  std::normal_distribution<double> extra(0.0, 1.0);
  for (auto& p : scattering.points) p.value += std::sqrt(3.0) * p.error * extra(rng);  // scatter 2σ in all
  const Trend t = analyseTrend({scattering});
  ASSERT_EQ(t.segments.size(), 1u);
  ASSERT_EQ(t.segments[0].scattering.size(), 1u);
  EXPECT_NEAR(t.segments[0].scattering[0].ratio(), 2.0, 0.6);
  EXPECT_FALSE(t.segments[0].stable());
  EXPECT_FALSE(t.segments[0].refittable());
  EXPECT_NE(trendMarkdown(t, {scattering}, {"test"}).find("scatter beyond their statistical errors in dx"),
            std::string::npos);
  EXPECT_EQ(trendJson(t, {scattering})["segments"][0]["scattering"][0]["parameter"], "dx");
  // The same values with their quoted errors only: the scale takes the measured scatter.
  TrendSeries quoted = scattering;
  quoted.statistical = false;
  for (auto& p : quoted.points) p.error = p.quotedError;
  const Trend u = analyseTrend({quoted});
  ASSERT_EQ(u.segments.size(), 1u);
  EXPECT_TRUE(u.segments[0].stable());
  // Statistical errors that describe the scatter: stable.
  const auto fine = ofRuns(
      40, 1, 20000.0, 2.26, rng, [](int) { return 0.3; }, Param::Dx);
  EXPECT_TRUE(analyseTrend({fine}).segments[0].stable());
}

// What tells a drift from a step, as the advice says, is true. A drift over two IOVs of 20
// runs (runs 101-140, 0.03 cm): these IOVs rarely tell it from a step whose IOV between is set
// aside; the advice names the campaign --min-events of IOVs that would, and with those the
// trend does tell in most series. A long, shallow drift (0.012 cm over runs 81-180): the
// advice says no grouping will, and indeed IOVs of 2 runs do not.
TEST(Trend, TheAdviceToTellADriftFromAStepIsTrue) {
  const double perEvent = 0.5;  // cm: an IOV of 20 runs (40 000 events) has an error of 0.0025 cm
  const auto told = [](const Trend& t) { return t.drifts.size() == 1 && !t.drifts[0].orStep && t.steps.empty(); };
  const auto adviceOf = [](const Trend& t) {
    std::vector<std::optional<std::int64_t>> out;
    for (const auto& d : t.drifts) {
      if (d.orStep) out.push_back(d.tellApart ? d.tellApart->minEvents : std::nullopt);
    }
    for (const auto& st : t.steps) {
      if (st.orDrift) out.push_back(st.orDrift->tellApart.minEvents);
    }
    return out;
  };
  std::mt19937_64 rng(47);
  const auto shortRamp = [](int r) { return 0.3 + 0.03 * std::clamp((r - 100) / 40.0, 0.0, 1.0); };
  std::map<std::int64_t, int> advised;
  int cases = 0, toldNow = 0;
  for (int k = 0; k < 50; ++k) {
    const Trend t = analyseTrend({ofRuns(240, 20, 2000.0, perEvent, rng, shortRamp, Param::Dx)});
    toldNow += told(t) ? 1 : 0;
    for (const auto& a : adviceOf(t)) {
      ++cases;
      if (a) ++advised[*a];
    }
  }
  ASSERT_FALSE(advised.empty());
  const auto most = std::max_element(advised.begin(), advised.end(),
                                     [](const auto& a, const auto& b) { return a.second < b.second; });
  EXPECT_GE(2 * most->second, cases / 2) << "alternatives with a grouping advised, of " << cases;
  const int runsPerIov = static_cast<int>(most->first / 2000);
  ASSERT_GE(runsPerIov, 1);
  ASSERT_LT(runsPerIov, 20);
  int toldThen = 0;
  for (int k = 0; k < 50; ++k) {
    toldThen += told(analyseTrend({ofRuns(240, runsPerIov, 2000.0, perEvent, rng, shortRamp, Param::Dx)})) ? 1 : 0;
  }
  EXPECT_GE(toldThen, 35) << "of 50 series with IOVs of " << most->first << " events (" << toldNow
                          << " with those of 40 000)";
  EXPECT_GT(toldThen, toldNow);

  const auto longRamp = [](int r) { return 0.3 + 0.012 * std::clamp((r - 80) / 100.0, 0.0, 1.0); };
  int alternatives = 0, noGrouping = 0;
  for (int k = 0; k < 40; ++k) {
    const Trend t = analyseTrend({ofRuns(240, 20, 2000.0, perEvent, rng, longRamp, Param::Dx)});
    for (const auto& a : adviceOf(t)) {
      ++alternatives;
      noGrouping += a ? 0 : 1;
    }
    for (const auto& d : t.drifts) {
      if (d.orStep && d.tellApart && !d.tellApart->minEvents) {
        EXPECT_NE(stepAlternativeText(t, d).find("no grouping of these runs will"), std::string::npos)
            << stepAlternativeText(t, d);
      }
    }
  }
  ASSERT_GT(alternatives, 20);
  EXPECT_GE(noGrouping, alternatives * 9 / 10);
  int toldFinest = 0;  // the finest grouping: IOVs of 2 runs (4000 events)
  for (int k = 0; k < 40; ++k) {
    toldFinest += told(analyseTrend({ofRuns(240, 2, 2000.0, perEvent, rng, longRamp, Param::Dx)})) ? 1 : 0;
  }
  EXPECT_LE(toldFinest, 8) << "of 40 series with IOVs of 4000 events";
}

// A step a few IOVs after a drift in the same parameter, or right at its end, is found with its
// size, and the drift with its ends (issue 43's review: the single ramp across both swallowed the
// step, reporting a false drift over both with confidence). dx drifts +0.06 cm over runs 8-27,
// then steps +0.10 cm; IOVs of 2 runs with errors of 0.0025 cm. The rates are those measured on
// these series (fixed seed), less a margin.
TEST(Trend, AStepBesideADriftIsFoundAndTheDriftWithItsEnds) {
  for (const int stepRun : {28, 36}) {
    std::mt19937_64 rng(431 + stepRun);
    const auto dx = [&](int r) { return 0.3 + 0.003 * std::clamp(r - 7, 0, 20) + (r >= stepRun ? 0.1 : 0.0); };
    int steps = 0, sizes = 0, drifts = 0, starts = 0, falseDrifts = 0;
    const int trials = 40;
    for (int k = 0; k < trials; ++k) {
      const Trend t = analyseTrend({ofRuns(60, 2, 10000.0, 0.354, rng, dx, Param::Dx)});
      for (const TrendStep& st : t.steps) {
        if (std::abs(st.firstRunAfter - stepRun) > 2) continue;
        ++steps;
        sizes += std::abs(st.size - 0.1) < 3.0 * st.error ? 1 : 0;
      }
      for (const TrendDrift& d : t.drifts) {
        if (d.lastRun < stepRun && d.firstRun <= 12) {
          ++drifts;
          starts += d.startRun && std::abs(*d.startRun - 7) <= 4 ? 1 : 0;
        } else {
          ++falseDrifts;  // one across the step, or in the flat runs after it
        }
      }
    }
    EXPECT_GE(steps, trials * 9 / 10) << "step at run " << stepRun;
    EXPECT_GE(sizes, steps * 8 / 10) << "step at run " << stepRun;
    EXPECT_GE(drifts, trials * 8 / 10) << "step at run " << stepRun;
    EXPECT_GE(starts, drifts * 6 / 10) << "step at run " << stepRun;
    EXPECT_LE(falseDrifts, trials / 10) << "step at run " << stepRun;
  }
}

// Where a stretch has too few IOVs on one side of a drift for a step to be tried there, the
// drift does not claim that "a step does not fit" there (issue 43's review: 6 IOVs, a step in
// the last but one).
TEST(Trend, ADriftSaysWhereNoStepCouldBeTried) {
  TrendDrift d{.parameter = Param::Alpha};
  d.firstRun = 31;
  d.lastRun = 60;
  EXPECT_EQ(noStepText(d), "no: a step does not fit");
  d.stepUntriedFrom = 42;
  EXPECT_NE(noStepText(d).find("none could be tried from run 42 on"), std::string::npos) << noStepText(d);
  d.stepUntriedFrom = 31;
  EXPECT_NE(noStepText(d).find("untried: its stretch has too few IOVs for a step"), std::string::npos);

  // Twelve IOVs of 5 runs, α drifting from run 1 (under way) to run 24: a step before run 11
  // cannot be tried (two IOVs each side), and the drift says so.
  std::mt19937_64 rng(7);
  const auto alpha = ofRuns(60, 5, 10000.0, 1.0, rng, [](int r) { return 2.9 + 0.005 * std::clamp(r, 0, 24); });
  const Trend t = analyseTrend({alpha});
  ASSERT_EQ(t.drifts.size(), 1u) << trendMarkdown(t, {alpha}, {});
  ASSERT_FALSE(t.drifts[0].orStep);
  ASSERT_TRUE(t.drifts[0].stepUntriedBefore);
  EXPECT_EQ(*t.drifts[0].stepUntriedBefore, 11);
  EXPECT_FALSE(t.drifts[0].stepUntriedFrom);
  EXPECT_NE(noStepText(t.drifts[0]).find("before run 11"), std::string::npos) << noStepText(t.drifts[0]);
}

}  // namespace
}  // namespace emcalign::validation
