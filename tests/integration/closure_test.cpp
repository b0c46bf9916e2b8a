// Closure: events from the project's simulation with a known misalignment are selected,
// profiled and fitted back.
//
// * In the idealised limit of the simulation (SimulationOptions::setIdealised: point
//   showers at R(E, θ), cluster directions from the deposit, no radiation, noise, dead
//   counters, background, layer-3 offset, cosmics, multiple scattering) the docs/contract.md §5 model is
//   exact up to the track resolution: every parameter must be within 3σ of the truth.
// * With full realism the fit must converge, and the differences are the biases of what
//   the model leaves out. The largest, measured with this simulation: the hemisphere gaps
//   come out low (dp_k by ~0.15 cm, dx_rel by ~0.07 cm). Its cause is the smearing of the
//   reconstructed direction across the parting plane: a particle of one hemisphere
//   reconstructed on the other side of φ = 90° or 270° enters a bin whose model has the
//   other sign of the relative terms (the idealised simulation with a 1.5° direction
//   smearing shows the same effect; without smearing it is gone). The paper's Table 1 has
//   the same sign (dp −0.03…−0.05 cm, dx_rel −0.021 cm). The tolerances below are about
//   twice the differences measured on several seeds; the validation campaign measures the
//   biases properly.

#include <cmath>

#include <gtest/gtest.h>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/sigma_sys.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/sim/simulation.hpp"
#include "test_support.hpp"

namespace emcalign {
namespace {

using geometry::AlignmentParameters;
using geometry::testing::paperLike;
using units::deg;

const geometry::Calorimeter& calorimeter() {
  static const auto calo = *geometry::Calorimeter::create(geometry::DetectorDescription::sndDefault());
  return calo;
}

calib::FitResult simulateAndFit(const AlignmentParameters& truth, sim::SimulationOptions o, std::int64_t events,
                                calib::ProfileOptions profile = {}) {
  o.generator.thetaMin = 40.0 * deg;  // e+e- -> e+e- is forward-peaked: keep the events useful
  o.generator.thetaMax = 140.0 * deg;
  auto simulation = sim::Simulation::create(calorimeter(), truth, o);
  EXPECT_TRUE(simulation.ok()) << simulation.error().message;
  const auto geometry = calib::FitGeometry::of(calorimeter().description());
  calib::ProfileFiller filler(geometry.depth, calib::SelectionOptions{}, profile);
  const Status run = simulation->run(
      events, 0, [&](std::span<const ParticleRow> rows, std::span<const TruthRow>, std::span<const Hit>) {
        filler.addEvents(rows);
        return Status{};
      });
  EXPECT_TRUE(run.ok());
  EXPECT_TRUE(filler.checkSelected().ok());
  auto fit = calib::fitProfiles(filler.fill().profiles.bins(), geometry);
  EXPECT_TRUE(fit.ok()) << fit.error().message;
  return *fit;
}

AlignmentParameters large() {
  AlignmentParameters eta;
  eta[Param::Alpha] = 5.0 * deg;
  eta[Param::Beta1] = -0.4 * deg;
  eta[Param::Beta2] = 0.3 * deg;
  eta[Param::Dx] = -0.5;
  eta[Param::Dy] = 0.4;
  eta[Param::Dz] = -0.5;
  eta[Param::Dp1] = 0.8;
  eta[Param::Dp2] = 0.1;
  eta[Param::Dp3] = 0.5;
  eta[Param::DyRel] = -0.2;
  eta[Param::DzRel] = 0.2;
  eta[Param::BetaRel] = -0.2 * deg;
  return eta;
}

TEST(Closure, IdealisedSimulationIsFittedBackWithin3Sigma) {
  sim::SimulationOptions o;
  o.setIdealised();
  int seed = 10;
  for (const AlignmentParameters& truth : {AlignmentParameters{}, paperLike(), large()}) {
    o.seed = static_cast<std::uint64_t>(++seed);
    const auto r = simulateAndFit(truth, o, 20000);
    EXPECT_EQ(r.status, emcalign::FitStatus::Converged);
    for (Param p : kAllParams) {
      const double e = r.errors[p];
      EXPECT_NEAR(r.parameters[p], truth[p], 3.0 * e) << name(p) << ", truth set " << seed;
    }
  }
}

TEST(Closure, FullRealismConvergesWithTheKnownBiases) {
  sim::SimulationOptions o;  // every realism effect on
  o.seed = 21;
  const AlignmentParameters truth = paperLike();
  const auto r = simulateAndFit(truth, o, 30000);
  EXPECT_EQ(r.status, emcalign::FitStatus::Converged);
  auto diff = [&](Param p) { return r.parameters[p] - truth[p]; };
  EXPECT_LT(std::abs(diff(Param::Alpha)), 0.15 * deg);
  for (Param p : {Param::Beta1, Param::Beta2, Param::BetaRel}) EXPECT_LT(std::abs(diff(p)), 0.12 * deg) << name(p);
  for (Param p : {Param::Dx, Param::Dy, Param::Dz, Param::DyRel, Param::DzRel}) {
    EXPECT_LT(std::abs(diff(p)), 0.08) << name(p);
  }
  for (Param p : {Param::Dp1, Param::Dp2, Param::Dp3}) EXPECT_LT(std::abs(diff(p)), 0.35) << name(p);
  // dx_rel: low, as explained above.
  const double dxRel = r.derived[Physical::DxRel].value;
  EXPECT_LT(dxRel - 0.2, 0.0);
  EXPECT_GT(dxRel - 0.2, -0.15);
}

}  // namespace
}  // namespace emcalign

namespace emcalign {
namespace {

TEST(Closure, PullsOfSmallIdealisedSamplesHaveUnitWidth) {
  // 24 samples of 4000 events; without σ_sys the bin errors are the statistical ones, so
  // (fit − truth)/error must be a unit Gaussian. Widths: within 0.35 of 1 (a 24-entry
  // sample's width scatters by ≈ 0.15; measured 0.86–1.25). Means: within 1.0 of 0, i.e.
  // 5σ of a 24-sample mean: at this precision (errors ~5× smaller than with σ_sys) the
  // idealised limit shows a residual mismatch of a few 10⁻³ cm (measured: dx pull mean
  // −0.7, others within ±0.4) — the model puts the shower at R(E, θ_EMC) seen from the
  // origin, the simulation at the shower depth along the particle's line from the vertex.
  sim::SimulationOptions o;
  o.setIdealised();
  calib::ProfileOptions noSys;
  noSys.sigmaSys = 0.0;
  constexpr int kSamples = 24;
  std::array<double, kNumParams> sum{}, sum2{};
  for (int s = 0; s < kSamples; ++s) {
    o.seed = 1000 + static_cast<std::uint64_t>(s);
    const auto r = simulateAndFit(paperLike(), o, 4000, noSys);
    ASSERT_EQ(r.status, emcalign::FitStatus::Converged);
    for (std::size_t k = 0; k < kNumParams; ++k) {
      const auto i = static_cast<Eigen::Index>(k);
      const double pull = (r.parameters.values[i] - paperLike().values[i]) / r.errors[i];
      sum[k] += pull;
      sum2[k] += pull * pull;
    }
  }
  for (std::size_t k = 0; k < kNumParams; ++k) {
    const double mean = sum[k] / kSamples, width = std::sqrt(sum2[k] / kSamples - mean * mean);
    EXPECT_NEAR(mean, 0.0, 1.0) << kParamNames[k];
    EXPECT_NEAR(width, 1.0, 0.35) << kParamNames[k];
  }
}

}  // namespace
}  // namespace emcalign

namespace emcalign {
namespace {

// The statistical errors of a fit with σ_sys (FitResult::statisticalErrors, the sandwich with
// σ_sys taken out of its middle) are what samples of the same detector scatter by: 32
// realistic samples of 12 000 events fitted with the contract's σ_sys = 0.2°, each parameter's spread
// about the samples' mean over its statistical error is 1 within 0.35 (a 32-sample spread
// scatters by ≈ 0.13; measured 0.91–1.20, and 0.88–1.20 with 64 samples of 16 000), while
// the quoted errors are 1.3–2.2 times the spread. With σ_sys = 0 and independent bins the two
// errors are the same.
TEST(Closure, StatisticalErrorsAreWhatSamplesScatterBy) {
  sim::SimulationOptions o;
  o.generator.thetaMin = 40.0 * deg;
  o.generator.thetaMax = 140.0 * deg;
  calib::ProfileOptions withPairs;
  withPairs.eventPairs = true;
  const auto geometry = calib::FitGeometry::of(calorimeter().description());
  constexpr int kSamples = 32, kEvents = 12000;
  std::vector<calib::FitResult> fits;
  for (int s = 0; s < kSamples; ++s) {
    o.seed = 2000 + static_cast<std::uint64_t>(s);
    auto simulation = sim::Simulation::create(calorimeter(), paperLike(), o);
    ASSERT_TRUE(simulation.ok());
    calib::ProfileFiller filler(geometry.depth, calib::SelectionOptions{}, withPairs);
    ASSERT_TRUE(simulation
                    ->run(kEvents, 0,
                          [&](std::span<const ParticleRow> rows, std::span<const TruthRow>, std::span<const Hit>) {
                            filler.addEvents(rows);
                            return Status{};
                          })
                    .ok());
    auto fit = calib::fitProfiles(filler.fill().profiles, geometry, calib::SigmaSysChoice::spec());
    ASSERT_TRUE(fit.ok()) << fit.error().message;
    ASSERT_TRUE(fit->statisticalCovariance.has_value());
    fits.push_back(*fit);
    if (s == 0) {  // σ_sys = 0 and independent bins: the statistical errors are the quoted ones
      calib::ProfileFiller plain(geometry.depth, calib::SelectionOptions{});
      auto again = sim::Simulation::create(calorimeter(), paperLike(), o);
      ASSERT_TRUE(again
                      ->run(8000, 0,
                            [&](std::span<const ParticleRow> rows, std::span<const TruthRow>, std::span<const Hit>) {
                              plain.addEvents(rows);
                              return Status{};
                            })
                      .ok());
      auto zero = calib::fitProfiles(plain.fill().profiles, geometry, calib::SigmaSysChoice::fixed(0.0));
      ASSERT_TRUE(zero.ok());
      for (Param p : kAllParams) EXPECT_NEAR(zero->statisticalErrors[p], zero->errors[p], 1e-9 * zero->errors[p]);
    }
  }
  for (Param p : kAllParams) {
    double mean = 0.0, stat = 0.0, quoted = 0.0;
    for (const auto& f : fits) {
      mean += f.parameters[p] / kSamples;
      stat += f.statisticalErrors[p] / kSamples;
      quoted += f.errors[p] / kSamples;
    }
    double ss = 0.0;
    for (const auto& f : fits) ss += std::pow(f.parameters[p] - mean, 2);
    const double spread = std::sqrt(ss / (kSamples - 1));
    EXPECT_NEAR(spread / stat, 1.0, 0.35) << name(p) << ": spread " << spread << ", statistical error " << stat;
    EXPECT_LT(stat, quoted) << name(p);
  }
  // The derived ones too, e.g. μ.
  double mean = 0.0, stat = 0.0;
  for (const auto& f : fits) {
    mean += f.derived[Physical::DxRel].value / kSamples;
    stat += f.derived[Physical::DxRel].statisticalError / kSamples;
  }
  double ss = 0.0;
  for (const auto& f : fits) ss += std::pow(f.derived[Physical::DxRel].value - mean, 2);
  EXPECT_NEAR(std::sqrt(ss / (kSamples - 1)) / stat, 1.0, 0.35);
}

}  // namespace
}  // namespace emcalign
