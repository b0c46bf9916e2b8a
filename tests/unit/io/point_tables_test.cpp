// The geometry commands' tables and texts in the library (io/point_tables.hpp,
// io/geometry_text.hpp): the header lines, a fixed hemisphere, the detector in words.

#include "emcalign/io/point_tables.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"
#include "emcalign/io/geometry_text.hpp"
#include "test_support.hpp"

namespace emcalign::io {
namespace {

using geometry::testing::sndCalorimeter;
using ::testing::HasSubstr;
using ::testing::StartsWith;

geometry::AlignmentTransform nominal() {
  return *geometry::AlignmentTransform::create(geometry::AlignmentParameters{},
                                               geometry::AlignmentRadii::of(sndCalorimeter().description()));
}

TEST(PointTables, TheNominalTransformKeepsAPointAndItsHemisphere) {
  const std::vector<Vec3> points = {Vec3(-40.0 * units::cm, 1.0 * units::cm, 2.0 * units::cm)};
  const TransformedPoints auto_ = transformPoints(nominal(), points, TransformGiven{});
  EXPECT_EQ(auto_.csv, "x_cm,y_cm,z_cm,hemisphere\n-40,1,2,-1\n");
  EXPECT_TRUE(auto_.warnings.empty());
  const TransformedPoints plus = transformPoints(nominal(), points, TransformGiven{.hemisphere = "+1"});
  EXPECT_THAT(plus.csv, HasSubstr(",1\n"));
}

TEST(PointTables, CountersAndLocatedPointsHaveTheirHeaders) {
  const auto& calo = sndCalorimeter();
  const auto geometry = geometry::CounterGeometry::nominal(calo);
  EXPECT_THAT(countersCsv(calo, geometry, ""),
              StartsWith("index,layer,ring,iphi,hemisphere,theta_deg,phi_deg,x_cm,y_cm,z_cm\n0,1,"));
  EXPECT_THAT(countersCsv(calo, geometry, "spherical"), StartsWith("index,layer,ring,iphi,hemisphere,r_cm,theta_deg"));
  const std::string located = locatedPointsCsv(calo, geometry, {Vec3::Zero()});
  EXPECT_THAT(located, StartsWith("x_cm,y_cm,z_cm,region,counter,"));
  EXPECT_THAT(located, HasSubstr("\n0,0,0,inside,"));
}

TEST(GeometryText, TheDetectorAndAnAlignmentInWords) {
  const auto& calo = sndCalorimeter();
  const std::string summary = detectorSummaryText(calo);
  EXPECT_THAT(summary, StartsWith("Detector: "));
  EXPECT_THAT(summary, HasSubstr("  support sphere 1 "));
  EXPECT_THAT(summary, HasSubstr("\nRings (counters per ring): "));
  EXPECT_EQ(detectorSummaryJson(calo)["counters"], calo.size());
  auto table = alignmentTableText(geometry::testing::paperLike(), calo.description());
  ASSERT_TRUE(table) << table.error().message;
  EXPECT_THAT(*table, StartsWith("fit set             value  unit    physical            value  unit\n"));
  EXPECT_THAT(*table, HasSubstr("(beta1, beta2 are sin(beta)cos(psi)"));
}

}  // namespace
}  // namespace emcalign::io
