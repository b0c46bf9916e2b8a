// The e+e- → e+e- selection of docs/contract.md §7 and the residuals of docs/contract.md §5: one hand-built event
// that passes every cut, and the same event altered to fail exactly one cut. selectEvent
// names the first cut an event fails (so the cuts before it passed), the same event passes
// once that cut alone is relaxed (so no later cut fails), and the profile filler's cut flow
// counts each event up to its first failed cut.

#include "emcalign/calib/selection.hpp"

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/detector.hpp"
#include "event_builders.hpp"

namespace emcalign::calib {
namespace {

using testing::bhabhaEvent;
using testing::chargedRow;
using testing::kNaN;
using testing::photonRow;
using units::deg;

// selectEvent's answer: the index of the first failed cut in CutFlow::kNames, 0 if none.
enum Cut : int { kSelected = 0, kMuonVeto = 1, kMultiplicity = 2, kTrack = 3, kEnergy = 4, kAcollinearity = 5 };

int select(const std::vector<ParticleRow>& rows, const SelectionOptions& options = {}) {
  return selectEvent(rows, options);
}

// The reference event altered, by one field, to fail exactly one cut.
std::vector<ParticleRow> failing(Cut cut) {
  std::vector<ParticleRow> e = bhabhaEvent();
  switch (cut) {
    case kMuonVeto:
      for (ParticleRow& r : e) r.muonVeto = 1;
      break;
    case kMultiplicity:
      e.push_back(photonRow(100.0 * deg, 60.0 * deg, 300.0));
      break;
    case kTrack:
      e[1].z0 = 10.5;
      break;
    case kEnergy:
      e[0].energy = 0.75 * 600.0;
      break;
    case kAcollinearity:
      e[1].phiTs = e[0].phiTs + 192.0 * deg;
      break;
    case kSelected:
      break;
  }
  return e;
}

TEST(Selection, ReferenceEventPassesEveryCutAndCutNamesFollowTheSpecOrder) {
  EXPECT_EQ(select(bhabhaEvent()), kSelected);
  EXPECT_STREQ(CutFlow::kNames[kMuonVeto], "no muon veto");
  EXPECT_STREQ(CutFlow::kNames[kMultiplicity], "2 charged, 0 photons");
  EXPECT_STREQ(CutFlow::kNames[kTrack], "track |z0|, |rho|");
  EXPECT_STREQ(CutFlow::kNames[kEnergy], "cluster energies");
  EXPECT_STREQ(CutFlow::kNames[kAcollinearity], "acollinearity");
}

TEST(Selection, MuonVetoRejects) {
  EXPECT_EQ(select(failing(kMuonVeto)), kMuonVeto);
  // The veto is the first cut: an event that would also fail every other cut is a veto.
  std::vector<ParticleRow> worst = failing(kAcollinearity);
  for (ParticleRow& r : worst) {
    r.muonVeto = 1;
    r.z0 = 50.0;
    r.energy = 10.0;
  }
  EXPECT_EQ(select(worst), kMuonVeto);
}

TEST(Selection, ExactlyTwoChargedAndNoPhoton) {
  EXPECT_EQ(select(failing(kMultiplicity)), kMultiplicity);  // + a photon

  std::vector<ParticleRow> one = bhabhaEvent();
  one.pop_back();
  EXPECT_EQ(select(one), kMultiplicity);

  std::vector<ParticleRow> three = bhabhaEvent();
  three.push_back(chargedRow(130.0 * deg, 90.0 * deg, 590.0, 1.0, 0.1));
  EXPECT_EQ(select(three), kMultiplicity);

  // One charged particle and one photon: two rows, still not two charged.
  std::vector<ParticleRow> mixed = bhabhaEvent();
  mixed[1] = photonRow(mixed[1].phiEmc, mixed[1].thetaEmc, mixed[1].energy);
  EXPECT_EQ(select(mixed), kMultiplicity);

  EXPECT_EQ(select({}), kMultiplicity);  // no particle at all
}

TEST(Selection, TracksNeedAbsZ0Below10AndAbsRhoBelow1) {
  EXPECT_EQ(select(failing(kTrack)), kTrack);
  SelectionOptions wide;
  wide.maxAbsZ0 = 20.0;
  EXPECT_EQ(select(failing(kTrack), wide), kSelected);  // only the track cut failed

  auto withTrack = [](int which, double z0, double rho) {
    std::vector<ParticleRow> e = bhabhaEvent();
    e[static_cast<std::size_t>(which)].z0 = z0;
    e[static_cast<std::size_t>(which)].rho = rho;
    return select(e);
  };
  // Either track, either sign; the bounds are strict (|z0| < 10 cm, |rho| < 1 cm).
  EXPECT_EQ(withTrack(0, -10.5, 0.0), kTrack);
  EXPECT_EQ(withTrack(0, 10.0, 0.0), kTrack);
  EXPECT_EQ(withTrack(0, 9.9, 0.0), kSelected);
  EXPECT_EQ(withTrack(1, -9.9, -0.95), kSelected);
  EXPECT_EQ(withTrack(1, 0.0, 1.2), kTrack);
  EXPECT_EQ(withTrack(0, 0.0, -1.2), kTrack);
  EXPECT_EQ(withTrack(1, 0.0, 1.0), kTrack);
  // A charged row without a track (empty fields) fails the track cut, never passes it.
  EXPECT_EQ(withTrack(1, kNaN, kNaN), kTrack);
  EXPECT_EQ(withTrack(0, 0.0, kNaN), kTrack);

  SelectionOptions tight;
  tight.maxAbsRho = 0.25;  // the reference event has |rho| = 0.2 and 0.3
  EXPECT_EQ(select(bhabhaEvent(), tight), kTrack);
}

TEST(Selection, ClusterEnergiesWithin08And11BeamEnergies) {
  EXPECT_EQ(select(failing(kEnergy)), kEnergy);
  SelectionOptions wide;
  wide.minEnergyFraction = 0.5;
  EXPECT_EQ(select(failing(kEnergy), wide), kSelected);  // only the energy cut failed

  auto withEnergy = [](int which, double energy) {
    std::vector<ParticleRow> e = bhabhaEvent();
    e[static_cast<std::size_t>(which)].energy = energy;
    return select(e);
  };
  // E_beam = 600 MeV: the window is (480, 660) MeV.
  EXPECT_EQ(withEnergy(1, 470.0), kEnergy);
  EXPECT_EQ(withEnergy(1, 490.0), kSelected);
  EXPECT_EQ(withEnergy(0, 650.0), kSelected);
  EXPECT_EQ(withEnergy(0, 670.0), kEnergy);
  EXPECT_EQ(withEnergy(1, kNaN), kEnergy);  // a track without its cluster

  // The window follows the event's own beam energy (clusters of 570 and 612 MeV)...
  auto atBeam = [](double beamEnergy) {
    std::vector<ParticleRow> e = bhabhaEvent();
    for (ParticleRow& r : e) r.beamEnergy = beamEnergy;
    return e;
  };
  EXPECT_EQ(select(atBeam(540.0)), kEnergy);    // window (432, 594)
  EXPECT_EQ(select(atBeam(700.0)), kSelected);  // window (560, 770)
  EXPECT_EQ(select(atBeam(760.0)), kEnergy);    // window (608, 836)
  // ... unless the options override it, whatever the rows say.
  SelectionOptions beam;
  beam.beamEnergy = 540.0;
  EXPECT_EQ(select(atBeam(600.0), beam), kEnergy);
  beam.beamEnergy = 580.0;  // window (464, 638)
  EXPECT_EQ(select(atBeam(540.0), beam), kSelected);
  EXPECT_EQ(select(atBeam(760.0), beam), kSelected);
}

TEST(Selection, AcollinearityInPhiBelow10Degrees) {
  EXPECT_EQ(select(failing(kAcollinearity)), kAcollinearity);
  SelectionOptions wide;
  wide.maxAcollinearity = 15.0 * deg;
  EXPECT_EQ(select(failing(kAcollinearity), wide), kSelected);  // only this cut failed

  auto withPhi = [](double phi1Deg, double phi2Deg) {
    std::vector<ParticleRow> e = bhabhaEvent();
    e[0].phiTs = phi1Deg * deg;
    e[1].phiTs = phi2Deg * deg;
    return select(e);
  };
  // |180° − |φ1 − φ2||, whichever track comes first and across φ = 0.
  EXPECT_EQ(withPhi(40.0, 229.0), kSelected);       // 9°
  EXPECT_EQ(withPhi(40.0, 231.0), kAcollinearity);  // 11°
  EXPECT_EQ(withPhi(40.0, 211.0), kSelected);       // −9°
  EXPECT_EQ(withPhi(40.0, 209.0), kAcollinearity);  // −11°
  EXPECT_EQ(withPhi(229.0, 40.0), kSelected);
  EXPECT_EQ(withPhi(231.0, 40.0), kAcollinearity);
  EXPECT_EQ(withPhi(2.0, 178.0), kSelected);         // 4°
  EXPECT_EQ(withPhi(355.0, 172.0), kSelected);       // 3°
  EXPECT_EQ(withPhi(2.0, 170.0), kAcollinearity);    // 12°
  EXPECT_EQ(withPhi(358.0, 190.0), kAcollinearity);  // 12°
  // The cut looks at the tracks, not at the clusters.
  std::vector<ParticleRow> clusters = bhabhaEvent();
  clusters[1].phiEmc = clusters[0].phiEmc + 150.0 * deg;
  EXPECT_EQ(select(clusters), kSelected);
}

// Each event adds one to every counter up to its first failed cut: events failing cut k are
// counted in events[0..k-1]. Different numbers of events per cut make every counter distinct.
TEST(Selection, CutFlowCountsEachEventUpToItsFirstFailedCut) {
  const geometry::ShowerDepth depth = geometry::ShowerDepth::of(geometry::DetectorDescription::sndDefault());
  ProfileFiller filler(depth, SelectionOptions{});
  std::vector<ParticleRow> rows;
  std::int64_t event = 0;
  auto add = [&](std::vector<ParticleRow> e, int copies) {
    for (int i = 0; i < copies; ++i) {
      testing::renumber(e, ++event);
      rows.insert(rows.end(), e.begin(), e.end());
    }
  };
  add(failing(kMuonVeto), 1);
  add(failing(kMultiplicity), 2);  // three rows each
  add(failing(kTrack), 3);
  add(failing(kEnergy), 4);
  add(failing(kAcollinearity), 5);
  add(bhabhaEvent(), 6);
  filler.addEvents(rows);

  const CutFlow& flow = filler.fill().cutFlow;
  EXPECT_EQ(flow.rows, 2 * 21 + 2);
  EXPECT_THAT(flow.events, ::testing::ElementsAre(21, 20, 18, 15, 11, 6));
  EXPECT_EQ(filler.fill().particlesSelected, 12);
  EXPECT_TRUE(filler.checkSelected().ok());
}

TEST(Selection, NoSelectedEventIsAnErrorThatGivesTheCutFlow) {
  const geometry::ShowerDepth depth = geometry::ShowerDepth::of(geometry::DetectorDescription::sndDefault());
  ProfileFiller filler(depth, SelectionOptions{});
  std::vector<ParticleRow> rows = failing(kEnergy);
  std::vector<ParticleRow> second = failing(kAcollinearity);
  testing::renumber(second, 2);
  rows.insert(rows.end(), second.begin(), second.end());
  filler.addEvents(rows);
  const Status s = filler.checkSelected();
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.error().message, ::testing::HasSubstr("events read 2"));
  EXPECT_THAT(s.error().message, ::testing::HasSubstr("cluster energies 1"));
  EXPECT_THAT(s.error().message, ::testing::HasSubstr("acollinearity 0"));
}

// docs/contract.md §5 shower depth, written out: R(E, θ) = R0 + X0·(ln(E/Ec) − 0.5 − x_pre/sinθ).
double depthOf(double energy, double theta) {
  return 32.8 + 2.56 * (std::log(energy / 13.16) - 0.5 - 0.13 / std::sin(theta));
}

TEST(Selection, ResidualsOfARadialTrackAreTheClusterOffsets) {
  const geometry::ShowerDepth depth = geometry::ShowerDepth::of(geometry::DetectorDescription::sndDefault());
  ParticleRow r = chargedRow(100.0 * deg, 65.0 * deg, 600.0);
  auto y = residualOf(r, depth);
  ASSERT_TRUE(y);
  EXPECT_NEAR(y->yPhi, 0.0, 1e-14);
  EXPECT_NEAR(y->yTheta, 0.0, 1e-14);
  // y_φ = sin(φ_TS,R − φ_emc), y_θ = θ_TS,R − θ_emc; the EMC values are passed on.
  r.phiEmc = 101.5 * deg;
  r.thetaEmc = 64.0 * deg;
  y = residualOf(r, depth);
  ASSERT_TRUE(y);
  EXPECT_NEAR(y->yPhi, std::sin(-1.5 * deg), 1e-14);
  EXPECT_NEAR(y->yTheta, 1.0 * deg, 1e-14);
  EXPECT_EQ(y->phiEmc, r.phiEmc);
  EXPECT_EQ(y->thetaEmc, r.thetaEmc);
  EXPECT_EQ(y->energy, r.energy);
}

TEST(Selection, ResidualsUseTheTrackPointOnTheShowerSphere) {
  const geometry::ShowerDepth depth = geometry::ShowerDepth::of(geometry::DetectorDescription::sndDefault());
  // A displaced track: closest approach c = (−rho·sinφ, rho·cosφ, z0), direction d; the point
  // p = c + s·d on |p| = R(E, θ_ts) with s > 0 solves s² + 2(c·d)s + |c|² − R² = 0.
  const double phi = 300.0 * deg, theta = 120.0 * deg, z0 = 4.0, rho = -0.7, energy = 450.0;
  const ParticleRow r = chargedRow(phi, theta, energy, z0, rho);
  const Vec3 c(-rho * std::sin(phi), rho * std::cos(phi), z0);
  const Vec3 d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
  const double radius = depthOf(energy, theta);
  const double s = -c.dot(d) + std::sqrt(c.dot(d) * c.dot(d) - c.squaredNorm() + radius * radius);
  const Vec3 p = c + s * d;
  ASSERT_NEAR(p.norm(), radius, 1e-12);
  const double phiR = std::atan2(p.y(), p.x()) + 2.0 * std::numbers::pi;  // p is at φ ≈ 300°
  const double thetaR = std::acos(p.z() / p.norm());

  const auto y = residualOf(r, depth);
  ASSERT_TRUE(y);
  EXPECT_NEAR(y->yPhi, std::sin(phiR - phi), 1e-12);
  EXPECT_NEAR(y->yTheta, thetaR - theta, 1e-12);
  // The displacement matters: z0 = 4 cm at R ≈ 40 cm moves θ by several degrees.
  EXPECT_GT(std::abs(y->yTheta), 3.0 * deg);
}

TEST(Selection, ResidualIsNoneWhenTheTrackMissesTheShowerSphere) {
  const geometry::ShowerDepth depth = geometry::ShowerDepth::of(geometry::DetectorDescription::sndDefault());
  const double radius = depthOf(600.0, 90.0 * deg);  // ≈ 41 cm
  EXPECT_TRUE(residualOf(chargedRow(0.0, 90.0 * deg, 600.0, 0.0, radius - 0.5), depth));
  EXPECT_FALSE(residualOf(chargedRow(0.0, 90.0 * deg, 600.0, 0.0, radius + 0.5), depth));
}

// Track lengths in mm refuse most events at the track cuts: said, with the unit.
TEST(Selection, TrackCutsRefusingMostTwoTrackEventsAreSaid) {
  CutFlow flow;
  flow.events = {20000, 19833, 17597, 17596, 15948, 15924};  // a simulated sample: none refused
  EXPECT_EQ(trackCutWarning(flow), "");
  flow.events = {20000, 19833, 17597, 5300, 4800, 4790};  // z0 written in mm
  const std::string w = trackCutWarning(flow);
  EXPECT_NE(w.find("refused 70 % of the events with two tracks"), std::string::npos) << w;
  EXPECT_NE(w.find("z0_cm and rho_cm in mm?"), std::string::npos) << w;
  flow.events = {60, 60, 50, 10, 10, 10};  // too few to say
  EXPECT_EQ(trackCutWarning(flow), "");
}

}  // namespace
}  // namespace emcalign::calib
