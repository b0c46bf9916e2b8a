// Hemisphere placements: the four rigid transforms, Geant4's angle convention, the file.

#include "emcalign/apply/placements.hpp"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"
#include "test_support.hpp"

namespace emcalign::apply {
namespace {

using ::testing::HasSubstr;

const geometry::Calorimeter& snd() {
  static const geometry::Calorimeter calo = *geometry::Calorimeter::create(geometry::DetectorDescription::sndDefault());
  return calo;
}

TEST(Placements, AreTheTransformsOfEachHemisphereAndSupport) {
  const auto t = *geometry::AlignmentTransform::create(geometry::testing::paperLike(),
                                                       geometry::AlignmentRadii::of(snd().description()));
  const Placements p = placementsOf(t);
  EXPECT_EQ(p.placements[0].name(), "sphere1_plus");
  EXPECT_EQ(p.placements[3].name(), "sphere2_minus");
  for (const Placement& q : p.placements) {
    const auto support = q.support == 1 ? geometry::Support::Inner : geometry::Support::Outer;
    const Vec3 p0(40.0, -12.0, 7.0);
    EXPECT_LT((q.transform.apply(p0) - t.forward(p0, q.hemisphere, support)).norm(), 1e-14);
  }
}

// `emcalign export`'s file and line: JSON unless GDML is asked for, standard output said as such.
TEST(Placements, ExportWritesTheFormatAskedForAndSaysSo) {
  const auto t = *geometry::AlignmentTransform::create(geometry::testing::paperLike(),
                                                       geometry::AlignmentRadii::of(snd().description()));
  EXPECT_EQ(io::Json::parse(placementsFile(t, snd().description(), "json"))["format"], kPlacementsFormat);
  EXPECT_THAT(placementsFile(t, snd().description(), "gdml"), HasSubstr("<physvol"));
  EXPECT_EQ(placementsWrittenText("-", "gdml", true),
            "wrote the placements to standard output (gdml placements: sphere1_plus, sphere1_minus, sphere2_plus, "
            "sphere2_minus; layer 3 with the mu3 rule)\n");
}

TEST(Placements, GeantAnglesRoundTrip) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> a(-3.0, 3.0);
  for (int k = 0; k < 200; ++k) {
    const Vec3 angles(a(rng), a(rng) / 2.0, a(rng));  // y within (−π/2, π/2): a unique decomposition
    const Mat3 m = gdmlMatrix(angles);
    EXPECT_LT((gdmlMatrix(gdmlAngles(m)) - m).cwiseAbs().maxCoeff(), 1e-13);
    EXPECT_LT((gdmlAngles(m) - angles).cwiseAbs().maxCoeff(), 1e-12);
  }
  // Rz(90°) takes x to y (active, right-handed), as CLHEP's rotateZ.
  EXPECT_LT((gdmlMatrix(Vec3(0.0, 0.0, std::numbers::pi / 2)) * Vec3::UnitX() - Vec3::UnitY()).norm(), 1e-15);
}

class PlacementsFile : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = (std::filesystem::temp_directory_path() / ("emcalign_placements_" + std::to_string(::getpid()) + ".json"))
                .string();
  }
  void TearDown() override { std::filesystem::remove(path_); }
  std::string path_;
};

TEST_F(PlacementsFile, ReadsBackItsAlignmentAndRefusesAnEditedPlacement) {
  const auto t = *geometry::AlignmentTransform::create(geometry::testing::paperLike(),
                                                       geometry::AlignmentRadii::of(snd().description()));
  io::Json j = placementsJson(placementsOf(t));
  std::ofstream(path_) << j.dump(2);
  auto back = readPlacements(path_, snd());
  ASSERT_TRUE(back.ok()) << back.error().message;
  for (Param p : kAllParams) EXPECT_NEAR(back->alignment[p], geometry::testing::paperLike()[p], 1e-15) << name(p);

  j["placements"][2]["translation_cm"][1] = j["placements"][2]["translation_cm"][1].get<double>() + 0.01;
  std::ofstream(path_, std::ios::trunc) << j.dump(2);
  auto edited = readPlacements(path_, snd());
  ASSERT_FALSE(edited.ok());
  EXPECT_THAT(edited.error().message, HasSubstr("placements[2]"));
  EXPECT_THAT(edited.error().message, HasSubstr("was it edited?"));
}

}  // namespace
}  // namespace emcalign::apply
