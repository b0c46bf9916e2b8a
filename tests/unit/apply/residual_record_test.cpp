// residuals.json: written and read back the same (an empty column's null included), and a
// file with a key missing, unknown or of the wrong type refused naming the key.

#include "emcalign/apply/residual_record.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace {

using emcalign::apply::parseResiduals;
using emcalign::apply::ResidualRecord;
using emcalign::apply::residualsJson;

ResidualRecord record() {
  ResidualRecord r;
  r.depthOffsetCm = 0.5;
  r.samples.push_back({"before", {"a.h5", "b.h5"}, {}});
  auto& s = r.samples.back().summary;
  s.events = 1200;
  s.particles = 2100;
  s.meanSinDphiDeg = 2.91;
  s.meanSinDphiErrorDeg = 0.02;
  s.meanDthetaDeg = -0.11;
  s.meanDthetaErrorDeg = 0.03;
  s.rmsDphiDeg = 1.4;
  s.rmsDthetaDeg = 1.9;
  for (int k = 0; k < 16; ++k) s.columnMeanDeg[k] = 0.1 * k;
  s.columnMeanDeg[7] = std::numeric_limits<double>::quiet_NaN();  // an empty column
  s.irregularityDeg = 1.5;
  return r;
}

TEST(ResidualRecord, ReadsBackWhatItWrites) {
  const auto j = residualsJson(record());
  EXPECT_TRUE(j["samples"][0]["phi_column_mean_sin_dphi_deg"][7].is_null());
  auto back = parseResiduals(j, "residuals.json");
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(residualsJson(*back), j);
  ASSERT_EQ(back->samples.size(), 1U);
  EXPECT_EQ(back->samples[0].files.size(), 2U);
  EXPECT_TRUE(std::isnan(back->samples[0].summary.columnMeanDeg[7]));
  EXPECT_DOUBLE_EQ(back->depthOffsetCm, 0.5);
  EXPECT_NE(emcalign::apply::residualsMarkdown(back->samples).find("| before | 1200 | 2100 |"), std::string::npos);
}

TEST(ResidualRecord, RefusesNamingTheKey) {
  const auto good = residualsJson(record());
  const auto refused = [](const emcalign::io::Json& j, const std::string& key) {
    auto r = parseResiduals(j, "r.json");
    ASSERT_FALSE(r) << "accepted: " << j.dump();
    EXPECT_NE(r.error().message.find(key), std::string::npos) << r.error().message;
  };
  auto j = good;
  j["samples"][0].erase("events");
  refused(j, "samples[0].events");
  j = good;
  j["samples"][0]["rms_dphi_deg"] = "wide";
  refused(j, "samples[0].rms_dphi_deg");
  j = good;
  j["samples"][0]["phi_column_mean_sin_dphi_deg"].erase(0);
  refused(j, "samples[0].phi_column_mean_sin_dphi_deg");
  j = good;
  j["extra"] = 1;
  refused(j, "extra");
}

}  // namespace
