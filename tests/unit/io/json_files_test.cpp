#include "emcalign/io/json_files.hpp"

#include <cmath>
#include <filesystem>
#include <limits>

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
  EXPECT_NE(errorOf(replace(kGood, "\"dy\": 0.0", "\"dy\": 0.0, \"dx\": 0.1")).find("'dx' appears twice"),
            std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"deg\"", "\"rad\"")).find("units.angle"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"format\"", "\"comment\": 1, \"format\"")).find("comment"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "alignment/1", "alignment/2")).find("format"), std::string::npos);
  EXPECT_NE(errorOf(R"({"format": "emcalign-alignment/1"})").find("parameters"), std::string::npos);
  EXPECT_NE(errorOf("[1, 2]").find("expected an object"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"beta1\": 0.1", "\"beta1\": 70.0")).find("beta1"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "} }", "}")).find("not valid JSON"), std::string::npos);
}

TEST(AlignmentFile, ErrorsInsideUnitsNameTheFile) {
  // Every message starts with the file's name, also for a key of the nested "units" object.
  for (const auto& text : {replace(kGood, "\"angle\"", "\"angles\""), replace(kGood, "\"deg\"", "\"rad\""),
                           replace(kGood, "{\"angle\": \"deg\", \"length\": \"cm\"}", "3")}) {
    const std::string message = errorOf(text);
    EXPECT_EQ(message.rfind("test.json: key 'units", 0), 0u) << message;
  }
}

TEST(AlignmentFile, AcceptsFitResultKeys) {
  std::string withResult =
      replace(kGood, "\"format\"", "\"chi2\": 301.5, \"ndf\": 308, \"status\": \"converged\", \"format\"");
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
                 {"r_inner_cm": 54.0, "r_outer_cm": 68.5}]})",
                     "d.json");
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

TEST(DetectorFile, IntegersAreRangeCheckedNeverWrapped) {
  auto check = [](const std::string& ring, const std::string& words) {
    const std::string text = R"({"format": "emcalign-detector/1", "counters_per_ring": [16, )" + ring + "]}";
    auto j = parseJson(text, "d.json");
    ASSERT_TRUE(j.ok()) << j.error().message;
    auto d = parseDetectorDescription(*j, "d.json");
    ASSERT_FALSE(d.ok()) << ring;
    EXPECT_NE(d.error().message.find("counters_per_ring[1]"), std::string::npos) << d.error().message;
    EXPECT_NE(d.error().message.find(words), std::string::npos) << d.error().message;
  };
  check("10000000000", "outside");  // 1e10 once wrapped through get<int>
  check("4294967312", "outside");   // 2^32 + 16 was read as 16
  check("-16", "outside");
  check("18446744073709551615", "outside");
  check("16.0", "expected an integer");
  check("\"16\"", "expected an integer");
}

TEST(DetectorFile, UnitMistakesAreNamed) {
  auto error = [](const std::string& body) {
    auto j = parseJson(R"({"format": "emcalign-detector/1", )" + body + "}", "d.json");
    EXPECT_TRUE(j.ok());
    auto d = parseDetectorDescription(*j, "d.json");
    EXPECT_FALSE(d.ok()) << body;
    return d.ok() ? std::string() : d.error().message;
  };
  // The SND radii in mm.
  EXPECT_NE(error(R"("layers": [{"r_inner_cm": 328, "r_outer_cm": 403}, {"r_inner_cm": 403, "r_outer_cm": 527},
                                {"r_inner_cm": 537, "r_outer_cm": 685}],
                     "support_spheres": [{"r_inner_cm": 527, "r_outer_cm": 537}, {"r_inner_cm": 685, "r_outer_cm": 695}])")
                .find("given in mm?"),
            std::string::npos);
  // A radius of 1e300 cm (the tracking loop of the simulation once walked it in 2 cm steps).
  EXPECT_NE(
      error(
          R"("support_spheres": [{"r_inner_cm": 52.7, "r_outer_cm": 53.7}, {"r_inner_cm": 68.5, "r_outer_cm": 1e300}])")
          .find("support_spheres[1].r_outer_cm"),
      std::string::npos);
  EXPECT_NE(error(R"("shower": {"x0_cm": 25.6e3})").find("shower.x0_cm"), std::string::npos);
  EXPECT_NE(error(R"("shower": {"critical_energy_mev": 0.01316})").find("shower.critical_energy_mev"),
            std::string::npos);
}

TEST(Json, DeepNestingIsRefusedBeforeParsing) {
  std::string deep = R"({"derived_from": )";
  for (int i = 0; i < 100000; ++i) deep += R"({"a": )";
  deep += "1";
  for (int i = 0; i < 100000; ++i) deep += "}";
  deep += "}";
  auto j = parseJson(deep, "c.json");
  ASSERT_FALSE(j.ok());
  EXPECT_NE(j.error().message.find("nested deeper than 64 levels"), std::string::npos) << j.error().message;
  // Brackets inside strings do not count; 60 levels are fine.
  std::string text =
      R"({"s": "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[\"{{{{", "a": )";
  for (int i = 0; i < 60; ++i) text += "[";
  for (int i = 0; i < 60; ++i) text += "]";
  text += "}";
  EXPECT_TRUE(parseJson(text, "ok.json").ok()) << parseJson(text, "ok.json").error().message;
}

TEST(Json, IntegerInNamesSourceAndKey) {
  auto j = parseJson(R"({"a": 16, "b": 1e10, "c": 16.5, "d": -3, "e": 12345678901234567890})", "x.json");
  ASSERT_TRUE(j.ok());
  EXPECT_EQ(*integerIn((*j)["a"], 16, 16, "x.json", "a"), 16);
  EXPECT_NE(integerIn((*j)["a"], 8, 8, "x.json", "a").error().message.find("x.json: key 'a': 16 must be 8"),
            std::string::npos);
  EXPECT_FALSE(integerIn((*j)["b"], 0, 100, "x.json", "b").ok());
  EXPECT_FALSE(integerIn((*j)["c"], 0, 100, "x.json", "c").ok());
  EXPECT_EQ(*integerIn((*j)["d"], -5, 5, "x.json", "d"), -3);
  EXPECT_FALSE(integerIn((*j)["d"], 0, 5, "x.json", "d").ok());
  EXPECT_FALSE(integerIn((*j)["e"], 0, std::numeric_limits<std::int64_t>::max(), "x.json", "e").ok());
}

TEST(AlignmentFile, ImplausibleValuesNameTheLikelyUnitMistake) {
  EXPECT_NE(errorOf(replace(kGood, "\"alpha\": 3.0", "\"alpha\": 1e6")).find("alpha = 1e+06 deg"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"alpha\": 3.0", "\"alpha\": 1e6")).find("degrees"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"dx\": 0.3", "\"dx\": 1e300")).find("given in mm?"), std::string::npos);
  EXPECT_NE(errorOf(replace(kGood, "\"dx\": 0.3", "\"dx\": 30")).find("dx = 30 cm"), std::string::npos)
      << "3 mm given in mm";
  EXPECT_NE(errorOf(replace(kGood, "\"beta_rel\": 0.02", "\"beta_rel\": 45")).find("beta_rel"), std::string::npos);
  EXPECT_TRUE(parse(replace(kGood, "\"dx\": 0.3", "\"dx\": 0.9")).ok()) << "9 mm is a plausible shift";
}

TEST(AlignmentFile, FitResultStatusDecidesWhetherItIsUsable) {
  auto withStatus = [](const std::string& status) {
    return replace(kGood, "\"units\"", "\"status\": \"" + status + "\", \"units\"");
  };
  EXPECT_NE(errorOf(withStatus("not converged")).find("status 'not converged'"), std::string::npos);
  EXPECT_NE(errorOf(withStatus("covariance singular")).find("not a calibration"), std::string::npos);
  EXPECT_NE(errorOf(withStatus("fine")).find("unknown status"), std::string::npos);
  auto j = parseJson(withStatus("poor fit"), "r.json");
  ASSERT_TRUE(j.ok());
  auto file = parseAlignmentFile(*j, kR1, "r.json");
  ASSERT_TRUE(file.ok()) << file.error().message;
  EXPECT_EQ(file->status, FitStatus::PoorFit);
  ASSERT_EQ(file->warnings.size(), 1u);
  EXPECT_NE(file->warnings[0].find("poor fit"), std::string::npos);
  // emcalign's own records (a campaign's samples) read back whatever the status.
  auto record = parseJson(withStatus("not converged"), "sample.json");
  ASSERT_TRUE(record.ok());
  EXPECT_TRUE(parseAlignment(*record, kR1, "sample.json", AlignmentUse::Record).ok());
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

// A file of the wrong kind is named by what it is, not by the first key that does not fit.
TEST(JsonFiles, AFileOfAnotherKindIsNamed) {
  const Json result = {{"format", "emcalign-alignment/1"}, {"chi2", 1.0}, {"parameters", Json::object()}};
  EXPECT_EQ(describeFile(result), "a fit result");
  EXPECT_EQ(describeFile(Json{{"format", "emcalign-alignment/1"}}), "a parameter file");
  EXPECT_EQ(describeFile(Json{{"format", "emcalign-corrections/1"}}), "a corrections file (derive-corrections)");
  EXPECT_EQ(describeFile(Json{{"format", "something else"}}), "");
  EXPECT_EQ(describeFile(Json::array()), "");
  const Status s = expectFormat(result, "emcalign-corrections/1", "a corrections file", "r.json");
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message,
            "r.json: this is a fit result, not a corrections file (its format: emcalign-alignment/1)");
  EXPECT_TRUE(expectFormat(result, "emcalign-alignment/1", "a fit result", "r.json"));
  EXPECT_TRUE(expectFormat(Json{{"alpha", 1}}, "emcalign-corrections/1", "x", "x.json"));  // its reader says
  // Not JSON at all: an HDF5 or an SQLite file is named.
  auto h5 = parseJson(std::string("\x89HDF\r\n\x1a\n\0\0", 10), "ev.h5");
  ASSERT_FALSE(h5);
  EXPECT_NE(h5.error().message.find("an HDF5 file"), std::string::npos);
  auto db = parseJson("SQLite format 3", "c.db");
  ASSERT_FALSE(db);
  EXPECT_NE(db.error().message.find("an SQLite database"), std::string::npos);
}

}  // namespace
}  // namespace emcalign::io
