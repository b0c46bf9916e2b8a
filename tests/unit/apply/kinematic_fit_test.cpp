// The π+π−π0 kinematic fit on events from the generator: exact measurements give χ² = 0 and
// the true momenta; Gaussian smearing with the fit's own errors gives ⟨χ²⟩ = ndf = 2 and flat
// p-values, every fit converged.

#include "emcalign/apply/kinematic_fit.hpp"

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/sim/generators.hpp"

namespace emcalign::apply {
namespace {

struct Truth {
  ThreePionEvent event;  // exact measurements, errors set
  double pPlus = 0.0, pMinus = 0.0;
};

// One generated φ → π+π−π0 event with exact measurements and realistic errors.
Truth generated(Rng& rng) {
  sim::GeneratorOptions g;
  g.process = sim::Process::ThreePion;
  g.beamEnergy = 510.0 * units::MeV;
  sim::GeneratedEvent ev;
  const sim::Collision c = sim::generate(g, rng, ev);
  Truth t;
  t.event.totalEnergy = c.energy();
  t.event.totalMomentum = Vec3(0.0, 0.0, c.momentumZ());
  int photon = 0;
  for (const auto& p : ev.particles) {
    const double theta = std::acos(p.momentum.z() / p.momentum.norm());
    const double phi = std::atan2(p.momentum.y(), p.momentum.x());
    if (p.pdg == sim::pdg::Photon && photon < 2) {
      const double e = p.energy;
      t.event.photons[static_cast<std::size_t>(photon++)] = {
          e, theta, phi, 0.042 * e / std::pow(e / 1000.0, 0.25), 1.5 * units::deg, 1.5 * units::deg / std::sin(theta)};
    } else if (p.pdg == sim::pdg::PiPlus || p.pdg == sim::pdg::PiMinus) {
      const std::size_t j = p.pdg == sim::pdg::PiPlus ? 0 : 1;
      t.event.pions[j] = {theta, phi, 0.3 * units::deg, 0.26 * units::deg / std::sin(theta)};
      (j == 0 ? t.pPlus : t.pMinus) = p.momentum.norm();
    }
  }
  return t;
}

TEST(KinematicFit, ExactMeasurementsGiveZeroChi2AndTheTrueMomenta) {
  Rng rng(1, 0);
  for (int k = 0; k < 200; ++k) {
    const Truth t = generated(rng);
    const KinematicFitResult r = fitThreePion(t.event);
    ASSERT_TRUE(r.converged) << k;
    EXPECT_LT(r.chi2, 1e-8);
    EXPECT_NEAR(r.pionMomenta[0], t.pPlus, 1e-5 * t.pPlus);
    EXPECT_NEAR(r.pionMomenta[1], t.pMinus, 1e-5 * t.pMinus);
    EXPECT_LT(r.maxConstraint, 1e-6);
  }
}

// Consistency: measurements smeared by exactly the errors the fit is told.
TEST(KinematicFit, GaussianSmearingGivesChi2OfNdfAndFlatPValues) {
  Rng rng(2, 0);
  std::mt19937_64 smear(3);
  std::normal_distribution<double> gauss;
  constexpr int kEvents = 20000;
  double sum = 0.0;
  int converged = 0;
  std::vector<int> pBins(10, 0);
  for (int k = 0; k < kEvents; ++k) {
    Truth t = generated(rng);
    for (auto& g : t.event.photons) {
      g.energy += g.sigmaEnergy * gauss(smear);
      g.theta += g.sigmaTheta * gauss(smear);
      g.phi += g.sigmaPhi * gauss(smear);
    }
    for (auto& p : t.event.pions) {
      p.theta += p.sigmaTheta * gauss(smear);
      p.phi += p.sigmaPhi * gauss(smear);
    }
    const KinematicFitResult r = fitThreePion(t.event);
    if (!r.converged) continue;
    ++converged;
    sum += r.chi2;
    ++pBins[static_cast<std::size_t>(std::min(9, static_cast<int>(r.pValue * 10.0)))];
  }
  EXPECT_GE(converged, kEvents - 10);  // linearisation may fail only far in the tails
  const double mean = sum / converged;
  std::printf("kinematic fit on %d Gaussian events: %d converged, mean chi2 %.4f, p-value tenths:", kEvents, converged,
              mean);
  for (int b : pBins) std::printf(" %d", b);
  std::printf("\n");
  EXPECT_NEAR(mean, 2.0, 0.08) << mean;  // σ(⟨χ²⟩) = 2/√20000 = 0.014, plus the non-linearity
  // Flat p-values: each tenth holds 10 % ± 4σ of a binomial.
  const double expected = converged / 10.0, tolerance = 4.0 * std::sqrt(expected * 0.9);
  for (int b = 0; b < 10; ++b) EXPECT_NEAR(pBins[static_cast<std::size_t>(b)], expected, tolerance) << "bin " << b;
}

TEST(KinematicFit, BadInputIsNotConverged) {
  Rng rng(4, 0);
  Truth t = generated(rng);
  t.event.photons[0].sigmaEnergy = 0.0;
  EXPECT_FALSE(fitThreePion(t.event).converged);
  t = generated(rng);
  t.event.pions[1].theta = std::nan("");
  EXPECT_FALSE(fitThreePion(t.event).converged);
}

}  // namespace
}  // namespace emcalign::apply
