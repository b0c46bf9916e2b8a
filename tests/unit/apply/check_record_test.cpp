// What a physics check found (apply/check_record.hpp): check.json written and read back gives
// the same record and the same file, for either process; nulls are NaN; a file that is not a
// check, or a value of the wrong type, is refused naming the key.

#include "emcalign/apply/check_record.hpp"

#include <cmath>
#include <string>

#include <gtest/gtest.h>

namespace emcalign::apply {
namespace {

using io::Json;

CheckRecord gammaGamma() {
  CheckRecord r{.process = CheckProcess::GammaGamma,
                .selected = 6020,
                .cutFlow = {.names = {"events", "two photons", "selected"}, .events = {18955, 9000, 6020}},
                .vertex = "the origin"};
  r.before.dphi = {.width = 1.176, .widthError = 0.02, .mean = 0.01, .rms = 1.9};
  r.before.dtheta = {.width = 5.597, .widthError = 0.1, .mean = -0.2, .rms = 7.0};
  r.after.dphi = {.width = 1.096, .widthError = 0.019, .mean = 0.0, .rms = 1.8};
  r.after.dtheta = {.rms = 6.9};  // the core not fitted: null
  r.improvement = {.dphiWidth = 6.8, .dphiRms = 5.3, .dthetaWidth = kNotMeasured, .dthetaRms = 1.4};
  r.alignment = {{"file", "a.json"}, {"sha256", "abc"}};
  r.correctionMethod = "exact";
  r.inputs = {"gg.h5"};
  r.software = "emcalign test";
  return r;
}

CheckRecord threePion() {
  CheckRecord r{.process = CheckProcess::ThreePion,
                .selected = 1000,
                .ndf = 2,
                .cutFlow = {.names = {"events", "selected"}, .events = {4000, 1000}},
                .vertex = "z"};
  r.before = {.chi2Mean = 3.2,
              .chi2Median = 1.9,
              .chi2MeanBelow20 = 2.5,
              .fractionAbove20 = 0.02,
              .pValueMean = 0.4,
              .converged = 990,
              .notConverged = 10};
  r.after = {.chi2Mean = 2.8,
             .chi2Median = 1.6,
             .chi2MeanBelow20 = 2.2,
             .fractionAbove20 = 0.01,
             .pValueMean = 0.45,
             .converged = 995,
             .notConverged = 5};
  r.improvement = {.chi2Mean = 12.5, .chi2Median = 15.8};
  r.alignment = {{"conditions", "sqlite:c.db"}, {"tag", "t"}};
  return r;
}

TEST(CheckRecord, WrittenAndReadBackIsTheSameFile) {
  for (const CheckRecord& r : {gammaGamma(), threePion()}) {
    const Json written = checkJson(r);
    auto read = parseCheckRecord(written, "check.json");
    ASSERT_TRUE(read.ok()) << read.error().message;
    EXPECT_EQ(checkJson(*read).dump(), written.dump()) << name(r.process);
    EXPECT_EQ(read->process, r.process);
    EXPECT_EQ(read->selected, r.selected);
    EXPECT_EQ(read->cutFlow.names, r.cutFlow.names);
    EXPECT_EQ(read->cutFlow.events, r.cutFlow.events);
  }
  auto gg = parseCheckRecord(checkJson(gammaGamma()), "check.json");
  ASSERT_TRUE(gg.ok());
  EXPECT_DOUBLE_EQ(gg->before.dphi.width, 1.176);
  EXPECT_DOUBLE_EQ(gg->after.dphi.width, 1.096);
  EXPECT_TRUE(std::isnan(gg->after.dtheta.width)) << "written as null";
  EXPECT_DOUBLE_EQ(gg->after.dtheta.rms, 6.9);
  EXPECT_TRUE(std::isnan(gg->improvement.dthetaWidth));
  EXPECT_EQ(gg->alignmentFile(), "a.json");
  EXPECT_EQ(gg->alignmentTag(), "");
  EXPECT_EQ(checkJson(*gg).at("before").size(), 8u) << "the γγ keys only";
  auto pi = parseCheckRecord(checkJson(threePion()), "check.json");
  ASSERT_TRUE(pi.ok());
  EXPECT_EQ(pi->after.notConverged, 5);
  EXPECT_DOUBLE_EQ(pi->improvement.chi2Median, 15.8);
  EXPECT_EQ(pi->alignmentTag(), "t");
  EXPECT_EQ(pi->alignmentConditions(), "sqlite:c.db");
  EXPECT_FALSE(checkJson(*pi).contains("software")) << "nothing recorded, nothing written";
}

TEST(CheckRecord, RefusesWhatIsNotACheckNamingTheKey) {
  const Json good = checkJson(threePion());
  const auto refusal = [&](auto change) {
    Json j = good;
    change(j);
    auto r = parseCheckRecord(j, "d/check.json");
    return r.ok() ? std::string("accepted") : r.error().message;
  };
  EXPECT_EQ(refusal([](Json&) {}), "accepted");
  EXPECT_EQ(refusal([](Json& j) { j["process"] = "mumu"; }),
            "d/check.json: key 'process': unknown process 'mumu' (gg, 3pi)");
  EXPECT_EQ(refusal([](Json& j) { j.erase("before"); }), "d/check.json: key 'before': missing");
  EXPECT_EQ(refusal([](Json& j) { j["selected"] = "<script>"; }),
            "d/check.json: key 'selected': expected an integer, got string");
  EXPECT_EQ(refusal([](Json& j) { j["after"]["chi2_mean"] = "low"; }),
            "d/check.json: key 'after.chi2_mean': expected a number or null, got string");
  EXPECT_EQ(refusal([](Json& j) { j["cut_order"].push_back("vertex"); }),
            "d/check.json: key 'cut_flow.vertex': missing");
  EXPECT_EQ(refusal([](Json& j) { j["inputs"] = {1}; }), "d/check.json: key 'inputs[0]': expected a string");
  EXPECT_EQ(refusal([](Json& j) { j = Json::array(); }),
            "d/check.json: key 'the document': expected an object, got array");
}

}  // namespace
}  // namespace emcalign::apply
