// `emcalign fit`'s options and texts in the library (calib/fit_text.hpp): a command line with
// nothing to fit refused, the options in native units, and the lines a physicist reads.

#include "emcalign/calib/fit_text.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"

namespace emcalign::calib {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

TEST(FitText, NothingToFitIsRefusedAndTheOptionsAreNative) {
  auto none = fitRequestOf(FitGiven{});
  ASSERT_FALSE(none);
  EXPECT_THAT(none.error().message, HasSubstr("give event files or --profile-in"));
  FitGiven g;
  g.events = {"a.h5"};
  g.depthOffsetCm = 0.3;
  g.beamEnergyMev = 510.0;
  g.sigmaSys = "0.15";
  auto r = fitRequestOf(g);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_DOUBLE_EQ(r->depthOffset, 0.3 * units::cm);
  EXPECT_EQ(r->beamEnergy, 510.0);
  ASSERT_TRUE(r->sigmaSys);
  EXPECT_EQ(r->sigmaSys->method, SigmaSysMethod::Fixed);
  EXPECT_DOUBLE_EQ(r->sigmaSys->value, 0.15 * units::deg);
  g.sigmaSys = "auto";
  EXPECT_EQ(fitRequestOf(g)->sigmaSys->method, SigmaSysMethod::Auto);
  g.sigmaSys = "";
  EXPECT_FALSE(fitRequestOf(g)->sigmaSys);  // the contract's
  EXPECT_EQ(fitInputs(g).front().path, "a.h5");
  EXPECT_EQ(fitInputs(g).back().option, "--detector");
}

TEST(FitText, TheResultSaysEachParameterTheChi2AndTheStatus) {
  FitResult r;
  r.parameters[Param::Dx] = 0.12345 * units::cm;
  r.errors.setConstant(0.01);
  r.chi2 = 300.0;
  r.ndf = 308;
  r.pValue = 0.6;
  r.binsUsed = 160;
  r.status = FitStatus::Converged;
  r.sigmaSys = {.method = SigmaSysMethod::Spec, .value = 0.2 * units::deg};
  const std::string text = fitResultText(r, nullptr);
  EXPECT_THAT(text, HasSubstr("\nparameter         value   error      unit\n"));
  EXPECT_THAT(text, HasSubstr("dx              0.12345 ± 0.01000    cm\n"));
  EXPECT_THAT(text, HasSubstr("chi2/ndf = 300.00/308 (p-value 0.6), 160 bins used"));
  EXPECT_THAT(text, HasSubstr("sigma_sys = 0.2000 deg (the paper's default)"));
  EXPECT_TRUE(text.ends_with("\nstatus: converged\n")) << text;
  SystematicErrors syst;
  syst.errors[Quantity(Param::Dx)] = 0.05;
  const std::string both = fitResultText(r, &syst);
  EXPECT_THAT(both, HasSubstr("stat         syst"));
  EXPECT_THAT(both, HasSubstr("± 0.05000"));
  EXPECT_THAT(both, HasSubstr("± —"));  // a parameter the corrections carry no error for
  EXPECT_THAT(text, Not(HasSubstr("syst")));
}

TEST(FitText, TheCutFlowCountsEachCut) {
  ProfileFill fill;
  fill.cutFlow.events[0] = 1000;
  fill.trackMisses = 1;
  const std::string text = cutFlowText(fill);
  EXPECT_THAT(text, HasSubstr("  events read                    1000\n"));
  EXPECT_THAT(text, HasSubstr("1 track missing the sphere"));
}

}  // namespace
}  // namespace emcalign::calib
