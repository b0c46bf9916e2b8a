// The series a trend reads from a tag: a tilt through zero is a signed β through zero with ψ
// steady, never a 180° step of ψ (issue 43's review: "step psi +179.95 (z 181)"); a period's
// truth is taken the same way.

#include "emcalign/validation/trend_series.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/validation/period.hpp"
#include "emcalign/validation/trend.hpp"
#include "test_support.hpp"

namespace emcalign::validation {
namespace {

namespace fs = std::filesystem;
using io::Json;

// A payload whose tilt is β1 = `beta1` deg about ψ = 0 (β2 = 0): stored as its magnitude β =
// |β1| and its direction ψ = 0° or 180°, as a fit records them.
conddb::Payload tiltOf(double beta1) {
  auto eta = geometry::testing::paperLike();
  eta[Param::Beta1] = beta1 * units::deg;
  eta[Param::Beta2] = 0.0;
  Json j = io::alignmentToJson(eta);
  Json errors = Json::object();
  for (Param p : kAllParams) errors[std::string(name(p))] = 0.01;
  j["errors"] = errors;
  j["statistical_errors"] = errors;
  const double beta = std::abs(beta1);
  j["derived"] = {{"beta", {{"value", beta}, {"error", 0.01}, {"statistical_error", 0.01}}},
                  {"psi",
                   {{"value", beta1 >= 0.0 ? 0.0 : 180.0},
                    {"error", beta > 0.0 ? 0.01 / beta * 57.3 : 180.0},
                    {"statistical_error", beta > 0.0 ? 0.01 / beta * 57.3 : 180.0}}}};
  j["chi2"] = 308.0;
  j["ndf"] = 308;
  j["status"] = "converged";
  auto p = conddb::makePayload(j, geometry::DetectorDescription::sndDefault().r1(), "test", Json{{"note", "unit"}});
  EXPECT_TRUE(p) << p.error().message;
  return *p;
}

const TrendSeries& named(const std::vector<TrendSeries>& all, std::string_view n) {
  return *std::find_if(all.begin(), all.end(), [&](const TrendSeries& s) { return s.parameter.name() == n; });
}

TEST(TrendSeries, ATiltThroughZeroIsASignedBetaNotAPsiStep) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("emcalign-trend-series-{}", ::getpid());
  fs::create_directories(dir);
  {
    auto db = conddb::Database::open("sqlite:" + (dir / "c.db").string(), conddb::IfMissing::Create);
    ASSERT_TRUE(db) << db.error().message;
    for (int i = 0; i < 21; ++i) {  // β1 from +0.25° to −0.25°, through 0 at IOV 10
      ASSERT_TRUE((*db)->put("t", 10 * i + 1, 10 * i + 10, tiltOf(0.25 - 0.025 * i),
                             i == 0 ? conddb::IfMissing::Create : conddb::IfMissing::Refuse));
    }
    auto snapshot = conddb::TagSnapshot::load(**db, "t", true);
    ASSERT_TRUE(snapshot) << snapshot.error().message;
    auto series = seriesOfTag(*snapshot);
    ASSERT_TRUE(series) << series.error().message;
    const TrendSeries &beta = named(*series, "beta"), &psi = named(*series, "psi");
    ASSERT_EQ(beta.points.size(), 21u);
    EXPECT_NEAR(beta.points.front().value, 0.25, 1e-9);
    EXPECT_NEAR(beta.points.back().value, -0.25, 1e-9) << "the tilt's other side: β signed";
    EXPECT_LT(psi.points.size(), 21u) << "ψ undefined where β is within 3σ of 0";
    for (const TrendPoint& p : psi.points) EXPECT_NEAR(p.value, 0.0, 1e-9) << "run " << p.firstRun;
    const Trend t = analyseTrend(*series);
    EXPECT_TRUE(
        std::none_of(t.steps.begin(), t.steps.end(), [](const TrendStep& s) { return s.parameter.name() == "psi"; }));
  }
  // The truth of a simulated period, the same way.
  Json runs = Json::array();
  for (int r = 1; r <= 5; ++r) {
    const double beta1 = 0.2 - 0.1 * (r - 1);
    runs.push_back({{"run", r},
                    {"parameters", {{"beta1", beta1}}},
                    {"derived", {{"beta", std::abs(beta1)}, {"psi", beta1 >= 0 ? 10.0 : -170.0}}}});
  }
  std::ofstream(dir / "truth.json") << Json{{"format", "emcalign-period-truth/1"}, {"runs", runs}}.dump();
  auto truth = readPeriodTruth((dir / "truth.json").string());
  ASSERT_TRUE(truth) << truth.error().message;
  EXPECT_NEAR(truth->mean(Physical::Beta, 5, 5), -0.2, 1e-9);
  EXPECT_NEAR(truth->mean(Physical::Psi, 5, 5), 10.0, 1e-9);
  EXPECT_NEAR(truth->mean(Physical::Psi, 1, 1), 10.0, 1e-9);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace emcalign::validation
