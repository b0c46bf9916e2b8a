// A study's campaign as given (validation/study_given.hpp): what is refused, naming the
// option, and what the settings record.

#include "emcalign/validation/study_given.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace emcalign::validation {
namespace {

using ::testing::HasSubstr;

TEST(StudyGiven, RefusalsNameTheOption) {
  std::vector<std::string> warnings;
  StudyGiven backwards;
  backwards.thetaMinDeg = 120.0;
  backwards.thetaMaxDeg = 60.0;
  auto theta = studyCampaign(backwards, warnings);
  ASSERT_FALSE(theta);
  EXPECT_THAT(theta.error().message, HasSubstr("--theta-min 120 must be below --theta-max 60"));
  StudyGiven effect;
  effect.off = {"gravity"};
  auto off = studyCampaign(effect, warnings);
  ASSERT_FALSE(off);
  EXPECT_THAT(off.error().message, HasSubstr("--off: "));
  StudyGiven sigma;
  sigma.sigmaSys = "11";
  auto big = studyCampaign(sigma, warnings);
  ASSERT_FALSE(big);
  EXPECT_THAT(big.error().message, HasSubstr("--sigma-sys: '11' is neither 'auto' nor a number of degrees"));
  EXPECT_TRUE(warnings.empty());
}

TEST(StudyGiven, TheSettingsRecordWhatWasGiven) {
  std::vector<std::string> warnings;
  StudyGiven g;
  g.samples = 3;
  g.beamEnergyMev = 700.0;
  g.sigmaSys = "auto";
  g.pointShowers = true;
  auto o = studyCampaign(g, warnings);
  ASSERT_TRUE(o) << o.error().message;
  EXPECT_EQ(o->samples, 3);
  EXPECT_EQ(o->sigmaSys.method, calib::SigmaSysMethod::Auto);
  EXPECT_TRUE(o->simulation.emc.pointShowers);
  EXPECT_DOUBLE_EQ(o->simulation.generator.beamEnergy, 700.0 * units::MeV);
  EXPECT_EQ(o->settings.value("sigma_sys", std::string()), "auto");
}

}  // namespace
}  // namespace emcalign::validation
