#include "emcalign/io/json_files.hpp"

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"

namespace emcalign::io {
namespace {

using geometry::AlignmentParameters;
using units::deg;
constexpr double kR1 = 53.7;

const char* kGood = R"({ "format": "emcalign-alignment/1",
  "units": {"angle": "deg", "length": "cm"},
  "parameters": {"alpha": 3.0, "beta1": 0.1, "beta2": -0.05, "dx": 0.3, "dy": 0.0, "dz": 0.0,
                 "dp1": 0.4, "dp2": 0.5, "dp3": 0.6, "dy_rel": 0.01, "dz_rel": 0.0, "beta_rel": 0.02} })";

Result<AlignmentParameters> parse(const std::string& text) {
  auto j = parseJson(text, "test.json");
  if (!j) return j.error();
  return parseAlignment(*j, kR1, "test.json");
}

std::string errorOf(const std::string& text) {
  auto r = parse(text);
  EXPECT_FALSE(r.ok()) << "accepted: " << text;
  return r.ok() ? "" : r.error().message;
}

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const auto pos = s.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  return s.replace(pos, from.size(), to);
}

TEST(AlignmentFile, ReadsFileUnits) {
  auto eta = parse(kGood);
  ASSERT_TRUE(eta.ok()) << eta.error().message;
  EXPECT_DOUBLE_EQ((*eta)[Param::Alpha], 3.0 * deg);
  EXPECT_DOUBLE_EQ((*eta)[Param::Beta1], 0.1 * deg);  // sinβcosψ written ×180/π
  EXPECT_DOUBLE_EQ((*eta)[Param::Dx], 0.3);
  EXPECT_DOUBLE_EQ((*eta)[Param::BetaRel], 0.02 * deg);
}

TEST(AlignmentFile, WriteReadRoundTripIsExact) {
  auto eta = parse(kGood);
  ASSERT_TRUE(eta.ok());
  auto written = alignmentToJsonWithPhysical(*eta, kR1);
  ASSERT_TRUE(written.ok());
  auto back = parse(written->dump());
  ASSERT_TRUE(back.ok()) << back.error().message;
  for (Param p : kAllParams) EXPECT_DOUBLE_EQ((*back)[p], (*eta)[p]) << name(p);
}

TEST(AlignmentFile, PhysicalFormGivesTheSameParameters) {
  auto eta = parse(kGood);
  auto written = alignmentToJsonWithPhysical(*eta, kR1);
  Json physicalOnly = *written;
  physicalOnly.erase("parameters");
  auto back = parseAlignment(physicalOnly, kR1, "phys.json");
  ASSERT_TRUE(back.ok()) << back.error().message;
  for (Param p : kAllParams) EXPECT_NEAR((*back)[p], (*eta)[p], 1e-12) << name(p);

  Json inconsistent = *written;
  inconsistent["physical"]["alpha"] = 4.0;
  auto bad = parseAlignment(inconsistent, kR1, "both.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("disagrees"), std::string::npos);
}

TEST(AlignmentFile, StrictValidationNamesTheKey) {
  EXPECT_NE(errorOf(replace(kGood, "\"alpha\"", "\"alfa\"")).find("parameters.alfa"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"dz\": 0.0,", "")).find("parameters.dz"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"dx\": 0.3", "\"dx\": \"0.3\"")).find("parameters.dx"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"dx\": 0.3", "\"dx\": 1e999")).find("out of range"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"dx\": 0.3", "\"dx\": NaN")).find("not valid JSON"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"dy\": 0.0", "\"dy\": 0.0, \"dx\": 0.1")).find("'dx' appears twice"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"deg\"", "\"rad\"")).find("units.angle"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"format\"", "\"comment\": 1, \"format\"")).find("comment"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "alignment/1", "alignment/2")).find("format"), std::string::npos);
  EXPECT_NE(errorOf(R"({"format": "emcalign-alignment/1"})").find("parameters"), std::string::npos);
  EXPECT_NE(errorOf("[1, 2]").find("expected an object"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"beta1\": 0.1", "\"beta1\": 70.0")).find("beta1"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "} }", "}")).find("not valid JSON"), std::string::npos);
}

TEST(AlignmentFile, AcceptsFitResultKeys) {
  std::string withResult = replace(kGood, "\"format\"", "\"chi2\": 301.5, \"ndf\": 308, \"status\": \"converged\", \"format\"");
  EXPECT_TRUE(parse(withResult).ok());
}

TEST(AlignmentFile, ReadFileReportsMissingFile) {
  auto r = readAlignment("/nonexistent/p.json", kR1);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("/nonexistent/p.json"), std::string::npos);
}

TEST(DetectorFile, DefaultRoundTrips) {
  const auto d = geometry::DetectorDescription::sndDefault();
  auto back = parseDetectorDescription(toJson(d), "default");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->countersPerRing, d.countersPerRing);
  for (int i = 0; i < 3; ++i) {
    EXPECT_DOUBLE_EQ(back->layers[i].rInner, d.layers[i].rInner);
    EXPECT_DOUBLE_EQ(back->layers[i].rOuter, d.layers[i].rOuter);
  }
  EXPECT_DOUBLE_EQ(back->rp3(), d.rp3());
  EXPECT_NEAR(back->thetaMin, d.thetaMin, 1e-15);
  EXPECT_DOUBLE_EQ(back->material.criticalEnergy, d.material.criticalEnergy);
}

TEST(DetectorFile, PartialOverrideKeepsTheRest) {
  auto j = parseJson(R"({"format": "emcalign-detector/1", "support_spheres": [
      {"r_inner_cm": 52.7, "r_outer_cm": 54.0}, {"r_inner_cm": 68.5, "r_outer_cm": 70.0}],
      "layers": [{"r_inner_cm": 32.8, "r_outer_cm": 40.3}, {"r_inner_cm": 40.3, "r_outer_cm": 52.7},
                 {"r_inner_cm": 54.0, "r_outer_cm": 68.5}]})", "d.json");
  ASSERT_TRUE(j.ok());
  auto d = parseDetectorDescription(*j, "d.json");
  ASSERT_TRUE(d.ok()) << d.error().message;
  EXPECT_DOUBLE_EQ(d->r1(), 54.0);
  EXPECT_DOUBLE_EQ(d->rp3(), 70.0);
  EXPECT_EQ(d->countersPerRing.size(), 16u);
}

TEST(DetectorFile, BadFilesNameTheKey) {
  auto check = [](const std::string& text, const std::string& key) {
    auto j = parseJson(text, "d.json");
    ASSERT_TRUE(j.ok());
    auto d = parseDetectorDescription(*j, "d.json");
    ASSERT_FALSE(d.ok()) << text;
    EXPECT_NE(d.error().message.find(key), std::string::npos) << d.error().message;
  };
  check(R"({"name": "x"})", "format");
  check(R"({"format": "emcalign-detector/1", "rings": 16})", "rings");
  check(R"({"format": "emcalign-detector/1", "counters_per_ring": [16, 18]})", "counters_per_ring[1]");
  check(R"({"format": "emcalign-detector/1", "counters_per_ring": [16, 1.5]})", "counters_per_ring[1]");
  check(R"({"format": "emcalign-detector/1", "layers": [{"r_inner_cm": 1, "r_outer_cm": 2}]})", "layers");
  check(R"({"format": "emcalign-detector/1", "shower": {"x0_cm": -2}})", "shower.x0_cm");
  check(R"({"format": "emcalign-detector/1", "shower": {"X0": 2}})", "shower.X0");
  check(R"({"format": "emcalign-detector/1", "theta_min_deg": 170})", "theta_min_deg");
}

TEST(AtomicWrite, WritesWholeFileAndLeavesNoTemporary) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / "emcalign_atomic_test";
  fs::create_directories(dir);
  const fs::path file = dir / "out.json";
  ASSERT_TRUE(writeOutputFile(file.string(), "{\"a\": 1}\n").ok());
  auto text = readTextFile(file.string());
  ASSERT_TRUE(text.ok());
  EXPECT_EQ(*text, "{\"a\": 1}\n");
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++entries;
  EXPECT_EQ(entries, 1);
  EXPECT_FALSE(writeOutputFile((dir / "missing" / "x.json").string(), "x").ok());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace emcalign::io
