#include "emcalign/geometry/detector.hpp"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/track.hpp"

namespace emcalign::geometry {
namespace {

using units::deg;

Calorimeter defaultCalorimeter() {
  auto c = Calorimeter::create(DetectorDescription::sndDefault());
  EXPECT_TRUE(c.ok());
  return std::move(*c);
}

TEST(Detector, DefaultMatchesSpec) {
  const auto d = DetectorDescription::sndDefault();
  ASSERT_TRUE(d.validate().ok());
  EXPECT_DOUBLE_EQ(d.r0(), 32.8);
  EXPECT_DOUBLE_EQ(d.r1(), 53.7);
  EXPECT_DOUBLE_EQ(d.rp3(), 69.5);
  EXPECT_EQ(d.ringCount(), 16);
  EXPECT_NEAR(d.ringWidth(), 9.0 * deg, 1e-15);
  EXPECT_DOUBLE_EQ(d.layers[2].rOuter - d.layers[0].rInner, 68.5 - 32.8);
}

TEST(Detector, Has1632CountersWithSpecIndexing) {
  const auto calo = defaultCalorimeter();
  ASSERT_EQ(calo.size(), 1632);
  EXPECT_EQ(calo.countersPerLayer(), 544);
  int lowerRings = 0;
  for (int ring = 0; ring < 16; ++ring) {
    const int n = (ring >= 2 && ring <= 13) ? 40 : 16;
    for (int layer = 1; layer <= 3; ++layer) {
      for (int iphi = 0; iphi < n; ++iphi) {
        const int index = 544 * (layer - 1) + lowerRings + iphi;
        ASSERT_EQ(calo.counterIndex(layer, ring, iphi), index);
        const Counter& c = calo.counter(index);
        EXPECT_EQ(c.layer, layer);
        EXPECT_EQ(c.ring, ring);
        EXPECT_EQ(c.iphi, iphi);
        EXPECT_NEAR(c.theta(), (18.0 + 9.0 * ring + 4.5) * deg, 1e-12);
        EXPECT_NEAR(c.phi(), (iphi + 0.5) * 2.0 * M_PI / n, 1e-12);
        EXPECT_EQ(sign(c.hemisphere), std::cos(c.phi()) > 0 ? 1 : -1);
      }
    }
    lowerRings += n;
  }
  EXPECT_EQ(calo.counterIndex(1, 16, 0), -1);
  EXPECT_EQ(calo.counterIndex(4, 0, 0), -1);
  EXPECT_EQ(calo.counterIndex(1, 0, 16), -1);
}

TEST(Detector, HemispheresSplitEveryRingInHalves) {
  const auto calo = defaultCalorimeter();
  int plus = 0;
  for (const Counter& c : calo.counters()) plus += c.hemisphere == Hemisphere::Plus;
  EXPECT_EQ(plus, 816);
}

TEST(Detector, LookupRoundTripForEveryCounter) {
  const auto calo = defaultCalorimeter();
  for (const Counter& c : calo.counters()) {
    const Location loc = calo.locate(c.centre());
    ASSERT_EQ(loc.region, Region::Counter) << c.index;
    EXPECT_EQ(loc.counter, c.index);
    // Points just inside each corner of the counter belong to it too.
    const double e = 1e-9;
    for (double t : {c.thetaMin + e, c.thetaMax - e}) {
      for (double p : {c.phiMin + e, c.phiMax - e}) {
        for (double r : {c.rInner + e, c.rOuter - e}) {
          EXPECT_EQ(calo.locate(pointAt(r, t, p)).counter, c.index) << c.index;
        }
      }
    }
  }
}

// locate starts from table guesses (detector.hpp): on random points, of the SND-like
// detector and of a fine one whose rings and cells are narrower than the table bins, it
// must agree with the counter found from the angles themselves.
TEST(Detector, LocateAgreesWithTheAnglesOnRandomPoints) {
  DetectorDescription fine = DetectorDescription::sndDefault();
  fine.thetaMin = 0.5 * deg;
  fine.thetaMax = 179.5 * deg;
  fine.countersPerRing.assign(179, 400);  // 1° rings: near the poles narrower than a cos θ bin
  for (const DetectorDescription& d : {DetectorDescription::sndDefault(), fine}) {
    const auto calo = Calorimeter::create(d);
    ASSERT_TRUE(calo.ok());
    Rng rng(7, 0);
    int checked = 0;
    for (int i = 0; i < 200000; ++i) {
      const double theta = d.thetaMin + (d.thetaMax - d.thetaMin) * rng.uniform();
      const double phi = 2.0 * std::numbers::pi * rng.uniform();
      const double r = d.layers[0].rInner + (d.layers[2].rOuter - d.layers[0].rInner) * rng.uniform();
      const double ringAt = (theta - d.thetaMin) / d.ringWidth();
      const int ring = static_cast<int>(ringAt);
      const int n = d.countersPerRing[static_cast<std::size_t>(ring)];
      const double phiAt = phi / (2.0 * std::numbers::pi / n);
      // Far enough from every edge that rounding cannot decide.
      if (std::abs(ringAt - std::round(ringAt)) < 1e-6 || std::abs(phiAt - std::round(phiAt)) < 1e-6) continue;
      int layer = 0;
      for (int l = 0; l < 3; ++l) {
        if (d.layers[static_cast<std::size_t>(l)].contains(r)) layer = l + 1;
      }
      const Location loc = calo->locate(pointAt(r, theta, phi));
      if (layer == 0) {
        EXPECT_EQ(loc.region, Region::SupportSphere) << r;
        continue;
      }
      ASSERT_EQ(loc.region, Region::Counter) << theta << " " << phi << " " << r;
      ASSERT_EQ(loc.counter, calo->counterIndex(layer, ring, static_cast<int>(phiAt))) << theta << " " << phi;
      ++checked;
    }
    EXPECT_GT(checked, 150000);
  }
}

TEST(Detector, PointsOutsideCountersAreClassified) {
  const auto calo = defaultCalorimeter();
  EXPECT_EQ(calo.locate(pointAt(20.0, 1.0, 0.3)).region, Region::Inside);
  EXPECT_EQ(calo.locate(pointAt(53.2, 1.0, 0.3)).region, Region::SupportSphere);
  EXPECT_EQ(calo.locate(pointAt(69.0, 1.0, 0.3)).region, Region::SupportSphere);
  EXPECT_EQ(calo.locate(pointAt(80.0, 1.0, 0.3)).region, Region::Outside);
  EXPECT_EQ(calo.locate(pointAt(45.0, 10.0 * deg, 0.3)).region, Region::Uncovered);
  EXPECT_EQ(calo.locate(pointAt(45.0, 170.0 * deg, 0.3)).region, Region::Uncovered);
}

TEST(Detector, PartingPlanePointsStayOnTheirSide) {
  const auto calo = defaultCalorimeter();
  for (double y : {40.0, -40.0}) {
    const Location onPlane = calo.locate(Vec3(0.0, y, 5.0));
    ASSERT_EQ(onPlane.region, Region::Counter);
    EXPECT_EQ(calo.counter(onPlane.counter).hemisphere, Hemisphere::Plus);  // x = 0 is s = +1
    const Location left = calo.locate(Vec3(-1e-13, y, 5.0));
    EXPECT_EQ(calo.counter(left.counter).hemisphere, Hemisphere::Minus);
  }
}

TEST(Detector, ValidateNamesTheBadKey) {
  auto d = DetectorDescription::sndDefault();
  d.countersPerRing[3] = 42;
  auto s = d.validate();
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("counters_per_ring[3]"), std::string::npos);

  d = DetectorDescription::sndDefault();
  d.layers[2].rInner = 50.0;  // inside support sphere 1
  s = d.validate();
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("layers[2]"), std::string::npos);

  d = DetectorDescription::sndDefault();
  d.material.radiationLength = -1.0;
  EXPECT_FALSE(d.validate());
  EXPECT_FALSE(Calorimeter::create(d).ok());
}

}  // namespace
}  // namespace emcalign::geometry
