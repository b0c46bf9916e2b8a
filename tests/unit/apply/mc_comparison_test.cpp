// Data against simulation (apply/mc_comparison.hpp): the χ² of twin samples, of samples that
// differ, and what small bins and correlated particles do to it.

#include "emcalign/apply/mc_comparison.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"

namespace emcalign::apply {
namespace {

// Events of two particles with correlated residuals (ρ in y_φ; the simulation has 0.55, its
// two particles back to back in opposite bins), in a 4×3 grid of profile bins; `shift`
// moves every Δφ (deg). With `sameBin` both particles of an event fall in one bin: the
// strongest case for the covariance of a bin's mean.
std::vector<ComparedParticle> toySample(std::int64_t events, std::mt19937_64& rng, double shift = 0.0,
                                        double width = 1.2, double rho = 0.55, bool sameBin = false) {
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_int_distribution<int> cell(0, 11);
  std::vector<ComparedParticle> out;
  for (std::int64_t e = 0; e < events; ++e) {
    const double common = gauss(rng), commonTheta = gauss(rng);
    const int bin = cell(rng);
    for (int k = 0; k < 2; ++k) {
      const double zPhi = std::sqrt(rho) * common + std::sqrt(1.0 - rho) * gauss(rng);
      const double zTheta = 0.3 * commonTheta + std::sqrt(1.0 - 0.09) * gauss(rng);
      ComparedParticle p;
      p.event = e;
      p.dPhiDeg = 3.0 + shift + width * zPhi;
      p.dThetaDeg = 1.4 * zTheta + 0.2 * zPhi;  // y_φ and y_θ of a particle correlate too
      p.yPhi = std::sin(p.dPhiDeg * units::deg);
      p.yTheta = p.dThetaDeg * units::deg;
      p.bin = k == 0 || sameBin ? bin : 11 - bin;  // the other particle opposite
      out.push_back(p);
    }
  }
  return out;
}

ComparisonOptions toyOptions() {
  ComparisonOptions o;
  o.profilePhiBins = 4;
  o.profileThetaBins = 3;
  return o;
}

// The p-values of twin samples are uniform: their KS distance to the uniform is small, and
// about 5 % fall below 0.05. Each distribution, and all four together. The particles of an
// event share a bin and correlate by 0.9: taken as independent (each its own event), the
// profiles' p-values would pile up near 0 (McComparison.TheEventsPairsAreNeeded).
std::vector<std::vector<double>> twinPValues(bool pairsKnown) {
  std::mt19937_64 rng(30);
  const int pairs = 300;
  std::vector<std::vector<double>> p(5);
  for (int k = 0; k < pairs; ++k) {
    auto data = toySample(3000, rng, 0.0, 1.2, 0.9, true), mc = toySample(4500, rng, 0.0, 1.2, 0.9, true);
    if (!pairsKnown) {
      for (auto* s : {&data, &mc}) {
        for (std::size_t i = 0; i < s->size(); ++i) (*s)[i].event = static_cast<std::int64_t>(i);
      }
    }
    auto c = compareParticles(data, mc, toyOptions());
    EXPECT_TRUE(c) << c.error().message;
    if (!c) return p;
    for (std::size_t d = 0; d < 4; ++d) p[d].push_back(c->distributions[d].pValue);
    p[4].push_back(c->pValue);
  }
  for (auto& v : p) std::sort(v.begin(), v.end());
  return p;
}

double ksToUniform(const std::vector<double>& sorted) {
  double ks = 0.0;
  const auto n = static_cast<double>(sorted.size());
  for (std::size_t i = 0; i < sorted.size(); ++i) {
    ks = std::max(
        {ks, std::abs(sorted[i] - static_cast<double>(i) / n), std::abs(sorted[i] - static_cast<double>(i + 1) / n)});
  }
  return ks;
}

TEST(McComparison, PValuesOfTwinSamplesAreUniform) {
  const auto p = twinPValues(true);
  for (const auto& v : p) {
    // The KS distance's 0.1 % critical value for 300 samples is 1.95/sqrt(300) = 0.113.
    EXPECT_LT(ksToUniform(v), 0.113);
    const auto below = std::count_if(v.begin(), v.end(), [](double x) { return x < 0.05; });
    EXPECT_LT(below, 30) << "p < 0.05 in " << below << " of 300";
  }
}

TEST(McComparison, TheEventsPairsAreNeeded) {
  const auto p = twinPValues(false);
  EXPECT_GT(ksToUniform(p[2]), 0.2) << "profile_phi with the pairs ignored";
}

// Ignoring that an event's two particles correlate would make the profiles' χ² too large:
// the influence covariance keeps them, which the p-values above test. A shifted MC is seen.
TEST(McComparison, AShiftedSimulationIsRejected) {
  std::mt19937_64 rng(31);
  const auto data = toySample(20000, rng);
  auto same = compareParticles(data, toySample(20000, rng), toyOptions());
  ASSERT_TRUE(same) << same.error().message;
  EXPECT_GT(same->pValue, 1e-3);
  auto shifted = compareParticles(data, toySample(20000, rng, 0.1), toyOptions());
  ASSERT_TRUE(shifted);
  EXPECT_LT(shifted->pValue, 1e-6);
  EXPECT_LT(shifted->distributions[0].pValue, 1e-3) << "dphi";
  EXPECT_LT(shifted->distributions[2].pValue, 1e-6) << "profile_phi";
  EXPECT_GT(shifted->distributions[3].pValue, 1e-4) << "profile_theta: not shifted";
  // The pulls of the profile's bins all point one way (data − MC < 0).
  for (const auto& b : shifted->distributions[2].bins) EXPECT_LT(b.pull, 1.0);
  // A wider MC: the histogram sees it, the profile means do not.
  auto wider = compareParticles(data, toySample(20000, rng, 0.0, 1.35), toyOptions());
  ASSERT_TRUE(wider);
  EXPECT_LT(wider->distributions[0].pValue, 1e-6);
  EXPECT_GT(wider->distributions[2].pValue, 1e-4);
}

// Tails with few particles are merged into their neighbours; a histogram keeps its
// normalisation's lost degree of freedom; tiny samples are refused.
TEST(McComparison, SmallBinsAreMergedAndTinySamplesRefused) {
  std::mt19937_64 rng(32);
  const auto data = toySample(2000, rng), mc = toySample(2000, rng);
  auto c = compareParticles(data, mc, toyOptions());
  ASSERT_TRUE(c);
  const auto& dphi = c->distributions[0];
  EXPECT_EQ(dphi.ndf, static_cast<int>(dphi.bins.size()) - 1);
  EXPECT_LT(dphi.bins.size(), 48u);
  EXPECT_TRUE(std::isinf(dphi.bins.front().low));
  EXPECT_TRUE(std::isinf(dphi.bins.back().high));
  double dataSum = 0.0, mcSum = 0.0;
  for (const auto& b : dphi.bins) {
    dataSum += b.data;
    mcSum += b.mc;
    EXPECT_GE(b.data * 4000.0, 10.0 - 1e-9);
  }
  EXPECT_NEAR(dataSum, 1.0, 1e-12);
  EXPECT_NEAR(mcSum, 1.0, 1e-12);
  EXPECT_EQ(c->distributions[2].ndf, 12);
  const std::vector<ComparedParticle> few(toySample(5, rng));
  auto refused = compareParticles(few, mc, toyOptions());
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("data: 10 selected particles"), std::string::npos) << refused.error().message;
}

// σ_sys added to the profile means makes their χ² smaller, never the histograms'.
TEST(McComparison, SigmaSysWidensOnlyTheProfiles) {
  std::mt19937_64 rng(33);
  const auto data = toySample(20000, rng), mc = toySample(20000, rng, 0.05);
  auto plain = compareParticles(data, mc, toyOptions());
  ComparisonOptions o = toyOptions();
  o.sigmaSys = 0.05 * units::deg;
  auto wide = compareParticles(data, mc, o);
  ASSERT_TRUE(plain && wide);
  EXPECT_LT(wide->distributions[2].chi2, plain->distributions[2].chi2);
  EXPECT_DOUBLE_EQ(wide->distributions[0].chi2, plain->distributions[0].chi2);
}

// compare.json: the one writer and the one reader agree (written, read back and written again
// is the same file); what a command records beside the result comes back too; a file that is
// not a comparison, or a value of the wrong type, is refused naming the key.
TEST(McComparison, TheFileReadsBackAsWritten) {
  std::mt19937_64 rng(31);
  auto c = compareParticles(toySample(6000, rng), toySample(6000, rng), toyOptions());
  ASSERT_TRUE(c.ok()) << c.error().message;
  const io::Json written = comparisonJson(
      ComparisonRecord{.comparison = *c, .dataFiles = {"d.h5"}, .mcFiles = {"m.h5"}, .depthOffsetCm = -0.5});
  auto read = parseComparison(written, "compare.json");
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(comparisonJson(*read).dump(), written.dump());
  EXPECT_EQ(read->comparison.options.profileThetaBins, 3) << "the profile grid, from the bins' indices";
  EXPECT_EQ(read->comparison.distributions.size(), c->distributions.size());
  EXPECT_DOUBLE_EQ(read->comparison.pValue, c->pValue);
  EXPECT_EQ(read->dataFiles, std::vector<std::string>{"d.h5"});
  EXPECT_EQ(read->depthOffsetCm, -0.5);
  EXPECT_TRUE(read->software.empty());
  EXPECT_FALSE(written.contains("software")) << "nothing recorded, nothing written";

  const auto refusal = [&](auto change) {
    io::Json j = written;
    change(j);
    auto r = parseComparison(j, "c/compare.json");
    return r.ok() ? std::string("accepted") : r.error().message;
  };
  EXPECT_EQ(refusal([](io::Json& j) { j["format"] = "emcalign-trend/1"; }),
            "c/compare.json: key 'format': expected \"emcalign-compare/1\"");
  EXPECT_EQ(refusal([](io::Json& j) { j["distributions"][2]["bins"][0]["pull"] = "big"; }),
            "c/compare.json: key 'distributions[2].bins[0].pull': expected a number or null, got string");
  EXPECT_EQ(refusal([](io::Json& j) { j["mc"].erase("events"); }), "c/compare.json: key 'mc.events': missing");
}

}  // namespace
}  // namespace emcalign::apply
