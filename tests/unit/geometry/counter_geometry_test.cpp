// The geometry database: counter centres, nominal and aligned, and locating points.

#include "emcalign/geometry/counter_geometry.hpp"

#include <random>

#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"
#include "test_support.hpp"

namespace emcalign::geometry {
namespace {

const Calorimeter& snd() { return testing::sndCalorimeter(); }

AlignmentTransform transformOf(const AlignmentParameters& eta) {
  return *AlignmentTransform::create(eta, AlignmentRadii::of(snd().description()));
}

void expectEveryCentreLocatesItsCounter(const CounterGeometry& g) {
  for (const Counter& c : snd().counters()) {
    const PointLocation loc = g.locate(g.centre(c.index));
    ASSERT_EQ(loc.region, PointRegion::Counter) << "counter " << c.index;
    ASSERT_EQ(loc.counter, c.index);
    EXPECT_EQ(loc.hemisphere, c.hemisphere);
    EXPECT_LT((loc.nominal - c.centre()).norm(), 1e-9) << "counter " << c.index;
  }
}

TEST(CounterGeometry, NominalCentresAreTheCountersOwn) {
  const CounterGeometry g = CounterGeometry::nominal(snd());
  ASSERT_EQ(g.centres().size(), 1632u);
  for (const Counter& c : snd().counters()) EXPECT_EQ(g.centre(c.index), c.centre());
  expectEveryCentreLocatesItsCounter(g);
}

TEST(CounterGeometry, AlignedCentresAreTheTransformOfSpec9) {
  const AlignmentTransform t = transformOf(testing::paperLike());
  const CounterGeometry g = CounterGeometry::aligned(snd(), t);
  for (const Counter& c : snd().counters()) {
    const Vec3 expected = t.forward(c.centre(), c.hemisphere, supportOfLayer(c.layer));
    EXPECT_LT((g.centre(c.index) - expected).norm(), 1e-12) << c.index;
  }
  expectEveryCentreLocatesItsCounter(g);
}

TEST(CounterGeometry, EveryCentreRoundTripsForRandomAlignments) {
  std::mt19937_64 rng(11);
  for (int k = 0; k < 5; ++k) {
    const AlignmentTransform t = transformOf(testing::randomParameters(rng));  // overlaps and the μ3 rule included
    SCOPED_TRACE(k);
    expectEveryCentreLocatesItsCounter(CounterGeometry::aligned(snd(), t));
  }
}

TEST(CounterGeometry, GapsAndOverlapsBetweenTheHemispheres) {
  AlignmentParameters apart;  // 2 cm between the hemispheres everywhere
  apart[Param::Dp1] = apart[Param::Dp2] = apart[Param::Dp3] = 2.0;
  const CounterGeometry open = CounterGeometry::aligned(snd(), transformOf(apart));
  EXPECT_EQ(open.locate(Vec3(0.0, 45.0, 3.0)).region, PointRegion::Gap);
  EXPECT_EQ(open.locate(Vec3(1.5, 45.0, 3.0)).region, PointRegion::Counter);
  EXPECT_EQ(open.locate(Vec3(1.5, 45.0, 3.0)).hemisphere, Hemisphere::Plus);

  AlignmentParameters pressed;  // −1 cm: the hemispheres overlap
  pressed[Param::Dp1] = pressed[Param::Dp2] = pressed[Param::Dp3] = -1.0;
  const CounterGeometry closed = CounterGeometry::aligned(snd(), transformOf(pressed));
  const PointLocation both = closed.locate(Vec3(0.0, 45.0, 3.0));
  ASSERT_EQ(both.region, PointRegion::Overlap);
  EXPECT_EQ(snd().counter(both.counter).hemisphere, Hemisphere::Plus);
  EXPECT_EQ(snd().counter(both.otherCounter).hemisphere, Hemisphere::Minus);
}

TEST(CounterGeometry, PointsOutsideTheCountersKeepTheirRegion) {
  const CounterGeometry g = CounterGeometry::aligned(snd(), transformOf(testing::paperLike()));
  EXPECT_EQ(g.locate(Vec3(5.0, 1.0, 0.0)).region, PointRegion::Inside);
  EXPECT_EQ(g.locate(Vec3(150.0, 1.0, 0.0)).region, PointRegion::Outside);
  EXPECT_EQ(g.locate(Vec3(3.0, 2.0, 45.0)).region, PointRegion::Uncovered);
  EXPECT_EQ(g.locate(Vec3(53.2, 1.0, 0.0)).region, PointRegion::SupportSphere);
}

}  // namespace
}  // namespace emcalign::geometry
