// The report figures: histogram arithmetic, and writeFitPlots on synthetic profiles that
// follow the model (the PNGs exist and are real PNGs; the curves written are the model;
// unwritable places, empty input and a missing gnuplot are errors that say so).

#include "emcalign/report/campaign_plots.hpp"
#include "emcalign/report/fit_plots.hpp"
#include "emcalign/report/histogram.hpp"
#include "emcalign/report/residual_plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "synthetic_bins.hpp"
#include "test_support.hpp"

namespace emcalign::report {
namespace {

namespace fs = std::filesystem;
using geometry::AlignmentParameters;
using testing::HasSubstr;
using units::deg;

// ---- Histogram

TEST(Histogram, FillsBinsAndCountsUnderAndOverflowApart) {
  Histogram h(0.0, 10.0, 10);
  ASSERT_EQ(h.counts.size(), 10u);
  EXPECT_DOUBLE_EQ(h.binWidth(), 1.0);
  EXPECT_DOUBLE_EQ(h.binCenter(3), 3.5);
  h.fill(0.0);                                       // first bin: the low edge is inside
  h.fill(9.999);                                     // last bin
  h.fill(5.5, 2.0);                                  // weighted
  h.fill(10.0);                                      // the high edge is overflow
  h.fill(-0.001);                                    // underflow
  h.fill(1e9, 3.0);                                  // overflow, weighted
  h.fill(std::numeric_limits<double>::quiet_NaN());  // overflow, not lost
  EXPECT_DOUBLE_EQ(h.counts[0], 1.0);
  EXPECT_DOUBLE_EQ(h.counts[9], 1.0);
  EXPECT_DOUBLE_EQ(h.counts[5], 2.0);
  EXPECT_DOUBLE_EQ(h.underflow, 1.0);
  EXPECT_DOUBLE_EQ(h.overflow, 5.0);
  EXPECT_DOUBLE_EQ(h.entries(), 4.0);  // in range only
}

TEST(Histogram, MeanAndRmsUseTheExactValuesOfInRangeFills) {
  Histogram h(0.0, 10.0, 10);
  for (double x : {1.0, 2.0, 3.0, 4.0}) h.fill(x);
  h.fill(-50.0);  // outside: ignored by mean and rms
  h.fill(50.0);
  EXPECT_DOUBLE_EQ(h.mean(), 2.5);
  EXPECT_DOUBLE_EQ(h.rms(), std::sqrt(1.25));  // standard deviation, not √⟨x²⟩

  Histogram single(0.0, 10.0, 10);
  single.fill(1.23);
  EXPECT_DOUBLE_EQ(single.mean(), 1.23);  // not the bin centre 1.5
  EXPECT_DOUBLE_EQ(single.rms(), 0.0);

  Histogram weighted(0.0, 10.0, 5);
  weighted.fill(1.0, 3.0);
  weighted.fill(5.0, 1.0);
  EXPECT_DOUBLE_EQ(weighted.mean(), 2.0);
  EXPECT_NEAR(weighted.rms(), std::sqrt(3.0), 1e-12);
}

TEST(Histogram, GaussianSampleHasItsMeanAndWidth) {
  Histogram h(-10.0, 10.0, 200);
  Rng rng(7, 0);
  for (int i = 0; i < 20000; ++i) h.fill(rng.normal(0.7, 1.5));
  EXPECT_NEAR(h.mean(), 0.7, 0.05);
  EXPECT_NEAR(h.rms(), 1.5, 0.05);
  EXPECT_DOUBLE_EQ(h.entries() + h.underflow + h.overflow, 20000.0);
}

TEST(Histogram, EmptyOrDegenerateIsHarmless) {
  Histogram empty(-1.0, 1.0, 4);
  EXPECT_EQ(empty.entries(), 0.0);
  EXPECT_EQ(empty.mean(), 0.0);
  EXPECT_EQ(empty.rms(), 0.0);
  Histogram none(0.0, 1.0, 0);
  none.fill(0.5);
  none.fill(-0.5);
  EXPECT_EQ(none.entries(), 0.0);
  EXPECT_EQ(none.overflow, 1.0);
  EXPECT_EQ(none.underflow, 1.0);
}

TEST(Histogram, ResidualHistogramsAreTenDegreesEitherSideInTenthsOfADegree) {
  const ResidualHistograms r;
  for (const Histogram* h : {&r.dPhiBefore, &r.dPhiAfter, &r.dThetaBefore, &r.dThetaAfter}) {
    EXPECT_EQ(h->low, -10.0);
    EXPECT_EQ(h->high, 10.0);
    EXPECT_EQ(h->counts.size(), 200u);
  }
}

// ---- writeFitPlots

const calib::FitGeometry kGeometry = calib::FitGeometry::of(geometry::DetectorDescription::sndDefault());

using geometry::testing::paperLike;

// 160 bins whose means follow the model at η, scattered inside their bins, plus noise of
// σ = 0.2°; two bins have too few entries (drawn grey), one none at all.
std::vector<calib::ProfileBin> syntheticBins(const AlignmentParameters& eta) {
  Rng rng(11, 0);
  calib::testing::SyntheticBinOptions o;
  o.noise = &rng;
  o.entries = 100;
  o.phiPosition = [](int, Rng* r) { return 0.5 + 0.2 * r->uniform(-1.0, 1.0); };
  o.thetaPosition = [](int, Rng* r) { return 0.5 + 0.1 * r->uniform(-1.0, 1.0); };
  std::vector<calib::ProfileBin> bins = calib::testing::syntheticBins(kGeometry, eta.values, o);
  bins[3].n = 5;
  bins[77].n = 8;
  bins[150].n = 0;
  bins[150].phiMean = bins[150].thetaMean = bins[150].yPhi = bins[150].yTheta = bins[150].energyMean =
      std::numeric_limits<double>::quiet_NaN();
  calib::markUsedBins(bins, 10);
  return bins;
}

calib::FitResult fitAt(const AlignmentParameters& eta, const std::vector<calib::ProfileBin>& bins) {
  calib::FitResult fit;
  fit.parameters = eta;
  fit.binsUsed = 157;
  fit.chi2 = calib::chi2At(bins, kGeometry, eta.values);
  fit.ndf = 2 * fit.binsUsed - 12;
  fit.status = emcalign::FitStatus::Converged;
  return fit;
}

ResidualHistograms residuals() {
  ResidualHistograms r;
  Rng rng(5, 1);
  for (int i = 0; i < 20000; ++i) {
    r.dPhiBefore.fill(rng.normal(1.5, 1.2));
    r.dPhiAfter.fill(rng.normal(0.0, 1.0));
    r.dThetaBefore.fill(rng.normal(-0.6, 1.4));
    r.dThetaAfter.fill(rng.normal(0.0, 1.3));
  }
  return r;
}

class PlotTest : public testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("emcalign_plots_test_" + std::string(testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
  }
  void TearDown() override {
    if (std::getenv("EMCALIGN_KEEP_TEST_PLOTS") == nullptr) fs::remove_all(dir_);
  }
  fs::path dir_;
};

std::string readBytes(const fs::path& p, std::size_t n) {
  std::ifstream in(p, std::ios::binary);
  std::string s(n, '\0');
  in.read(s.data(), static_cast<std::streamsize>(n));
  s.resize(static_cast<std::size_t>(in.gcount()));
  return s;
}

TEST_F(PlotTest, WritesFourPngFiguresWithTheirDataAndScripts) {
  const auto eta = paperLike();
  const auto bins = syntheticBins(eta);
  const auto hist = residuals();
  auto r = writeFitPlots((dir_ / "plots").string(), bins, kGeometry, fitAt(eta, bins), &hist);
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_EQ(r->size(), 4u);
  const std::string names[] = {"profile_phi", "profile_theta_vs_phi", "profile_theta", "residuals_before_after"};
  for (int k = 0; k < 4; ++k) {
    const fs::path png = dir_ / "plots" / (names[k] + ".png");
    EXPECT_EQ(fs::path((*r)[static_cast<std::size_t>(k)]), png);
    ASSERT_TRUE(fs::exists(png)) << png;
    EXPECT_EQ(readBytes(png, 8), std::string("\x89PNG\r\n\x1a\n", 8)) << png;
    EXPECT_GT(fs::file_size(png), 20000u) << png;  // a drawn figure, not an empty canvas
    EXPECT_TRUE(fs::exists(dir_ / "plots" / (names[k] + ".gp"))) << names[k];
  }
  for (const char* data :
       {"profile_bins.dat", "profile_model_vs_phi.dat", "profile_model_vs_theta.dat", "residuals_before_after.dat"})
    EXPECT_TRUE(fs::exists(dir_ / "plots" / data)) << data;
}

// A sample's name is the user's text: mc_nominal is drawn as mc_nominal (not mc with a
// subscript n), and quotes, backslashes and braces neither break the script nor vanish.
TEST_F(PlotTest, UserTextIsDrawnLiterally) {
  apply::ResidualSummary s;
  s.particles = 100;
  s.dPhiCounts.assign(apply::ResidualSummary::kBins, 1.0);
  s.dThetaCounts.assign(apply::ResidualSummary::kBins, 1.0);
  s.columnMeanDeg.fill(0.5);
  s.columnEntries.fill(6);
  auto r = writeResidualPlots(dir_.string(), {{"mc_nominal", s}, {"run^2 \"@data\" {x}\\", s}});
  ASSERT_TRUE(r.ok()) << r.error().message;
  std::ifstream in(dir_ / "residuals.gp");
  const std::string script((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(script.find("title \"mc\\\\_nominal: mean"), std::string::npos) << script;
  EXPECT_NE(script.find("title \"run\\\\^2 \\\"\\\\@data\\\" \\\\{x\\\\}\\\\\\\\: mean"), std::string::npos) << script;
  EXPECT_GT(fs::file_size(dir_ / "residuals.png"), 10000u);
}

TEST_F(PlotTest, WithoutResidualsDrawsTheThreeProfileFigures) {
  const auto eta = paperLike();
  const auto bins = syntheticBins(eta);
  auto r = writeFitPlots(dir_.string(), bins, kGeometry, fitAt(eta, bins), nullptr);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->size(), 3u);
  EXPECT_FALSE(fs::exists(dir_ / "residuals_before_after.png"));
}

TEST_F(PlotTest, DataFilesHoldTheBinsAndTheModelSplitAtTheHemisphereEdges) {
  const auto eta = paperLike();
  const auto bins = syntheticBins(eta);
  auto r = writeFitPlots(dir_.string(), bins, kGeometry, fitAt(eta, bins), nullptr);
  ASSERT_TRUE(r.ok()) << r.error().message;

  // One row per bin with entries, flagged used or not.
  std::ifstream binsIn(dir_ / "profile_bins.dat");
  int rows = 0, leftOut = 0;
  for (std::string line; std::getline(binsIn, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream row(line);
    double phi, theta, yPhi, sPhi, yTheta, sTheta;
    int used;
    row >> phi >> theta >> yPhi >> sPhi >> yTheta >> sTheta >> used;
    ++rows;
    leftOut += used == 0 ? 1 : 0;
  }
  EXPECT_EQ(rows, 159);
  EXPECT_EQ(leftOut, 2);

  // The curve is modelAt at the slice's mean θ; it never joins across 90° or 270°.
  double thetaSlice0 = 0.0;
  long n0 = 0;
  for (const auto& b : bins)
    if (b.iTheta == 0 && b.n > 0) {
      thetaSlice0 += static_cast<double>(b.n) * b.thetaMean;
      n0 += b.n;
    }
  thetaSlice0 /= static_cast<double>(n0);
  std::ifstream modelIn(dir_ / "profile_model_vs_phi.dat");
  int segments = 0, checked = 0;
  bool inSegment = false;
  double segmentLo = 0.0, previous = 0.0;
  for (std::string line; std::getline(modelIn, line);) {
    if (line.empty()) {
      if (inSegment) {
        ++segments;
        EXPECT_FALSE(segmentLo < 90.0 && previous > 90.0) << segmentLo << "–" << previous;
        EXPECT_FALSE(segmentLo < 270.0 && previous > 270.0) << segmentLo << "–" << previous;
      }
      inSegment = false;
      continue;
    }
    if (line[0] == '#') continue;
    std::istringstream row(line);
    double phiDeg, fPhiDeg, fThetaDeg, f0Phi, f0Theta;
    int slice;
    row >> phiDeg >> fPhiDeg >> fThetaDeg >> f0Phi >> f0Theta >> slice;
    if (!inSegment) segmentLo = phiDeg;
    inSegment = true;
    previous = phiDeg;
    EXPECT_NEAR(f0Phi, 0.0, 1e-9);  // η = 0 is the nominal geometry
    if (slice == 0) {
      const auto f = calib::modelAt(kGeometry, eta.values, phiDeg * deg, thetaSlice0, 600.0);
      EXPECT_NEAR(fPhiDeg, f.phi / deg, 1e-5);
      EXPECT_NEAR(fThetaDeg, f.theta / deg, 1e-5);
      ++checked;
    }
  }
  EXPECT_EQ(segments, 3 * 10);
  EXPECT_GT(checked, 700);
}

TEST_F(PlotTest, UnwritableDirectoryIsAnErrorNamingIt) {
  const auto eta = paperLike();
  const auto bins = syntheticBins(eta);
  auto r = writeFitPlots("/proc/emcalign_plots", bins, kGeometry, fitAt(eta, bins), nullptr);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("/proc/emcalign_plots"));
}

TEST_F(PlotTest, NoEntriesIsAnError) {
  std::vector<calib::ProfileBin> bins(160);
  auto r = writeFitPlots(dir_.string(), bins, kGeometry, calib::FitResult{}, nullptr);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("no bin has entries"));
}

TEST_F(PlotTest, HistogramWithoutBinsIsAnError) {
  const auto eta = paperLike();
  const auto bins = syntheticBins(eta);
  ResidualHistograms hist;
  hist.dThetaAfter = Histogram(0.0, 1.0, 0);
  auto r = writeFitPlots(dir_.string(), bins, kGeometry, fitAt(eta, bins), &hist);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("dThetaAfter"));
}

// PATH without gnuplot, restored on the way out.
class PathGuard {
 public:
  explicit PathGuard(const std::string& path) {
    if (const char* old = std::getenv("PATH")) old_ = old;
    setenv("PATH", path.c_str(), 1);
  }
  ~PathGuard() { setenv("PATH", old_.c_str(), 1); }
  PathGuard(const PathGuard&) = delete;
  PathGuard& operator=(const PathGuard&) = delete;

 private:
  std::string old_;
};

TEST_F(PlotTest, MissingGnuplotSaysHowToInstallIt) {
  const auto eta = paperLike();
  const auto bins = syntheticBins(eta);
  fs::create_directories(dir_ / "empty_bin");
  Result<std::vector<std::string>> r = Error{""};
  {
    const PathGuard noGnuplot((dir_ / "empty_bin").string());
    r = writeFitPlots((dir_ / "plots").string(), bins, kGeometry, fitAt(eta, bins), nullptr);
  }
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("gnuplot was not found"));
  EXPECT_THAT(r.error().message, HasSubstr("apt-get install gnuplot-nox"));
}

// ---- writeCampaignPlots

// 17 quantities (12 "deg"/"cm" parameters, then 5 derived, two of them wrapping angles) over
// 40 samples: truth uniform, fit = truth + bias + Gaussian noise of the stated error.
std::vector<CampaignSeries> syntheticCampaign() {
  std::vector<Quantity> names(kAllParams.begin(), kAllParams.end());
  names.insert(names.end(), kDerivedParams.begin(), kDerivedParams.end());
  Rng rng(23, 0);
  std::vector<CampaignSeries> series;
  for (int k = 0; k < 17; ++k) {
    CampaignSeries s{names[static_cast<std::size_t>(k)], {}, {}, {}};
    const bool wraps = s.name.isDirection();
    const double sigma = 0.01 * (1 + k % 4), bias = 0.3 * sigma * (k % 3 - 1);
    for (int i = 0; i < 40; ++i) {
      const double truth = wraps ? rng.uniform(-180.0, 180.0) : rng.uniform(-0.5, 0.5);
      double fit = truth + bias + sigma * rng.normal();
      if (wraps && fit > 180.0) fit -= 360.0;  // as a fit reports it
      s.truth.push_back(truth);
      s.fit.push_back(fit);
      s.error.push_back(sigma);
    }
    series.push_back(std::move(s));
  }
  series[16].error[3] = std::numeric_limits<double>::quiet_NaN();  // no pull, still a point
  return series;
}

TEST_F(PlotTest, CampaignWritesPullAndResidualFigures) {
  auto series = syntheticCampaign();
  // A truth just below +180° fitted just above it: fit − truth is the short way round.
  series[15].truth[0] = 179.99;
  series[15].fit[0] = -179.99;
  auto r = writeCampaignPlots((dir_ / "campaign").string(), series);
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_EQ(r->size(), 2u);
  const std::string names[] = {"pulls", "residuals_vs_truth"};
  for (int k = 0; k < 2; ++k) {
    const fs::path png = dir_ / "campaign" / (names[k] + ".png");
    EXPECT_EQ(fs::path((*r)[static_cast<std::size_t>(k)]), png);
    ASSERT_TRUE(fs::exists(png)) << png;
    EXPECT_EQ(readBytes(png, 8), std::string("\x89PNG\r\n\x1a\n", 8)) << png;
    EXPECT_GT(fs::file_size(png), 50000u) << png;  // 17 drawn panels, not an empty canvas
    EXPECT_TRUE(fs::exists(dir_ / "campaign" / (names[k] + ".gp"))) << names[k];
  }

  // The samples file: one block per quantity, fit − truth and the pull per sample.
  std::ifstream in(dir_ / "campaign" / "campaign_samples.dat");
  int block = 0, rows = 0, blankRun = 0;
  for (std::string line; std::getline(in, line);) {
    if (line.empty()) {
      if (++blankRun == 2) ++block;
      continue;
    }
    blankRun = 0;
    if (line[0] == '#') continue;
    std::istringstream row(line);
    std::string cols[5];
    for (auto& c : cols) row >> c;
    ASSERT_LT(block, 17);
    const auto& s = series[static_cast<std::size_t>(block)];
    const std::size_t i = static_cast<std::size_t>(rows % 40);
    const double diff = std::stod(cols[3]);
    EXPECT_NEAR(std::stod(cols[0]), s.truth[i], 1e-8 * std::max(1.0, std::abs(s.truth[i])));
    if (block == 15 && i == 0) {
      EXPECT_NEAR(diff, 0.02, 1e-7);  // not −359.98
    } else if (block == 16 && i == 3) {
      EXPECT_EQ(cols[4], "NaN");  // no error, no pull
    } else {
      const double d = s.fit[i] - s.truth[i];
      EXPECT_NEAR(diff, s.name.isDirection() ? std::remainder(d, 360.0) : d, 1e-7);
      EXPECT_NEAR(std::stod(cols[4]), diff / s.error[i], 1e-5);
    }
    ++rows;
  }
  EXPECT_EQ(block, 16);
  EXPECT_EQ(rows, 17 * 40);
  EXPECT_TRUE(fs::exists(dir_ / "campaign" / "pulls.dat"));
}

TEST_F(PlotTest, CampaignWithoutQuantitiesIsAnError) {
  auto r = writeCampaignPlots(dir_.string(), {});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("no quantities"));
}

TEST_F(PlotTest, CampaignSeriesOfUnequalLengthsIsAnErrorNamingTheQuantity) {
  auto series = syntheticCampaign();
  series[7].fit.pop_back();
  auto r = writeCampaignPlots(dir_.string(), series);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("'dp2'"));
  EXPECT_THAT(r.error().message, HasSubstr("40, 39 and 40"));

  series = syntheticCampaign();
  series[2].truth.clear();
  series[2].fit.clear();
  series[2].error.clear();
  r = writeCampaignPlots(dir_.string(), series);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("'beta2': no samples"));
  EXPECT_FALSE(fs::exists(dir_ / "pulls.png"));  // nothing drawn from bad input
}

}  // namespace
}  // namespace emcalign::report
