// Correcting event files (apply/correct.hpp) through the library: the method by name, the
// options a user gives, the alignment of each run, one output per input, and what a
// correction with the true alignment does to the clusters' directions.

#include "emcalign/apply/correct.hpp"

#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include "emcalign/core/units.hpp"
#include "emcalign/validation/simulate_file.hpp"
#include "event_files.hpp"
#include "test_support.hpp"

namespace emcalign::apply {
namespace {

namespace fs = std::filesystem;
using emcalign::testing::rowsOf;
using geometry::AlignmentParameters;
using geometry::AlignmentTransform;
using geometry::testing::sndCalorimeter;

std::shared_ptr<const AlignmentTransform> transformOf(const AlignmentParameters& eta) {
  auto t = AlignmentTransform::create(eta, geometry::AlignmentRadii::of(sndCalorimeter().description()));
  if (!t.ok()) throw std::runtime_error(t.error().message);  // GoogleTest reports it, the test fails
  return std::make_shared<const AlignmentTransform>(*t);
}

// The mean of φ_EMC − φ_TS over the charged particles that reached the EMC, and its
// standard error.
std::pair<double, double> meanPhiResidual(const std::vector<ParticleRow>& rows) {
  double sum = 0.0, sum2 = 0.0;
  int n = 0;
  for (const ParticleRow& r : rows) {
    if (r.charged == 0 || std::isnan(r.energy)) continue;
    const double d = std::remainder(r.phiEmc - r.phiTs, 2 * M_PI);
    sum += d;
    sum2 += d * d;
    ++n;
  }
  if (n < 2) return {std::nan(""), std::nan("")};
  const double mean = sum / n;
  return {mean, std::sqrt((sum2 / n - mean * mean) / (n - 1))};
}

class CorrectFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("emcalign-correct-{}", ::getpid());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // `events` of run `run` simulated with the misalignment `truth`, with hits.
  std::string simulated(const std::string& name, const AlignmentParameters& truth, std::int32_t run,
                        std::int64_t events = 3000) const {
    validation::SimulateRequest r;
    r.options.seed = 7 + static_cast<std::uint64_t>(run);
    r.options.run = run;
    r.events = events;
    r.threads = 1;
    const std::string file = path(name);
    auto done = validation::simulateFile(sndCalorimeter(), truth, r, file);
    EXPECT_TRUE(done.ok()) << (done.ok() ? "" : done.error().message);
    return file;
  }

  fs::path dir_;
};

TEST(CorrectionMethod, NamesRoundTripAndAnUnknownOneIsNone) {
  for (const CorrectionMethod m : {CorrectionMethod::Auto, CorrectionMethod::Hits, CorrectionMethod::Clusters}) {
    EXPECT_EQ(correctionMethodFromName(name(m)), m) << name(m);
  }
  EXPECT_FALSE(correctionMethodFromName("hit").has_value());
  EXPECT_FALSE(correctionMethodFromName("").has_value());
}

TEST(CorrectOptions, TheMethodByNameAndTheDepthOffsetOfTheClusterMethod) {
  const auto& calo = sndCalorimeter();
  auto clusters = correctOptionsOf("clusters", 0.7, "", calo);
  ASSERT_TRUE(clusters.ok()) << clusters.error().message;
  EXPECT_EQ(clusters->method, CorrectionMethod::Clusters);
  EXPECT_DOUBLE_EQ(clusters->depth.offset, 0.7);
  EXPECT_DOUBLE_EQ(clusters->depth.r0, geometry::ShowerDepth::of(calo.description()).r0);

  auto bad = correctOptionsOf("nearest", 0.0, "", calo);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("nearest"), std::string::npos) << bad.error().message;

  const std::string missing = "/nonexistent/corrections.json";
  auto noFile = correctOptionsOf("clusters", 0.0, missing, calo);
  ASSERT_FALSE(noFile.ok());
  EXPECT_NE(noFile.error().message.find(missing), std::string::npos) << noFile.error().message;
}

TEST_F(CorrectFiles, TheTrueAlignmentTakesTheRotationOutOfTheClusters) {
  AlignmentParameters truth;
  truth[Param::Alpha] = 3.0 * units::deg;
  const std::string in = simulated("ev.h5", truth, 1);
  const auto rows = rowsOf(in);
  // The events of a detector in its nominal place: what the correction should give back.
  const auto [nominal, nominalError] = meanPhiResidual(rowsOf(simulated("nominal.h5", AlignmentParameters{}, 1)));
  const auto [before, beforeError] = meanPhiResidual(rows);
  // The EMC turned by α about the beam: its clusters' φ, read in the nominal frame, lag by α.
  EXPECT_NEAR(before - nominal, -3.0 * units::deg, 5 * std::hypot(nominalError, beforeError));
  for (const CorrectionMethod method : {CorrectionMethod::Hits, CorrectionMethod::Clusters}) {
    SCOPED_TRACE(std::string(name(method)));
    CorrectOptions o;
    o.method = method;
    o.depth = geometry::ShowerDepth::of(sndCalorimeter().description());
    const std::string out = path(fmt::format("c-{}.h5", name(method)));
    auto report = correctFiles({in}, out, sndCalorimeter(), *transformOf(truth), o);
    ASSERT_TRUE(report.ok()) << report.error().message;
    EXPECT_EQ(report->method, method);
    EXPECT_EQ(report->alignments, 1);
    EXPECT_TRUE(report->hits);
    EXPECT_TRUE(report->truth);
    const auto corrected = rowsOf(out);
    ASSERT_EQ(corrected.size(), rows.size());
    EXPECT_EQ(static_cast<std::int64_t>(corrected.size()), report->rows);
    EXPECT_GT(report->clusters, report->rows / 2);
    // A turn about the beam turns every cluster by α, by either method, and leaves θ.
    for (std::size_t i = 0; i < rows.size(); ++i) {
      if (std::isnan(rows[i].energy)) continue;
      ASSERT_NEAR(std::remainder(corrected[i].phiEmc - rows[i].phiEmc, 2 * M_PI), 3.0 * units::deg, 1e-9) << i;
      ASSERT_NEAR(corrected[i].thetaEmc, rows[i].thetaEmc, 1e-9) << i;
    }
    const auto [after, afterError] = meanPhiResidual(corrected);
    EXPECT_NEAR(after, nominal, 5 * std::hypot(nominalError, afterError))
        << "nominal " << nominal / units::deg << " deg, before " << before / units::deg << " deg";
  }
}

TEST_F(CorrectFiles, EachRunWithItsOwnAlignmentAsIfCorrectedAlone) {
  AlignmentParameters a = geometry::testing::paperLike(), b;
  b[Param::Dx] = -0.4;
  b[Param::Alpha] = -1.0 * units::deg;
  const std::string one = simulated("run1.h5", a, 1, 1500), two = simulated("run2.h5", b, 2, 1500);
  const std::map<std::int64_t, std::shared_ptr<const AlignmentTransform>> byRun = {{1, transformOf(a)},
                                                                                   {2, transformOf(b)}};
  std::set<std::int64_t> asked;
  const AlignmentOfRun alignmentOf = [&](std::int64_t run) -> Result<std::shared_ptr<const AlignmentTransform>> {
    asked.insert(run);
    if (auto it = byRun.find(run); it != byRun.end()) return it->second;
    return Error{fmt::format("no alignment of run {}", run)};
  };
  CorrectOptions o;
  o.method = CorrectionMethod::Hits;
  auto both = correctFiles({one, two}, path("both.h5"), sndCalorimeter(), alignmentOf, o);
  ASSERT_TRUE(both.ok()) << both.error().message;
  EXPECT_EQ(both->alignments, 2);
  EXPECT_EQ(asked, (std::set<std::int64_t>{1, 2})) << "each run's alignment asked for";

  auto alone1 = correctFiles({one}, path("one.h5"), sndCalorimeter(), *byRun.at(1), o);
  auto alone2 = correctFiles({two}, path("two.h5"), sndCalorimeter(), *byRun.at(2), o);
  ASSERT_TRUE(alone1.ok() && alone2.ok());
  auto expected = rowsOf(path("one.h5"));
  const auto second = rowsOf(path("two.h5"));
  expected.insert(expected.end(), second.begin(), second.end());
  const auto got = rowsOf(path("both.h5"));
  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].run, expected[i].run);
    ASSERT_EQ(got[i].event, expected[i].event);
    const bool same = (got[i].phiEmc == expected[i].phiEmc && got[i].thetaEmc == expected[i].thetaEmc) ||
                      (std::isnan(got[i].phiEmc) && std::isnan(expected[i].phiEmc));
    ASSERT_TRUE(same) << "row " << i << " of run " << got[i].run;
  }

  // A run without an alignment is an error naming it, and no output is left.
  const std::map<std::int64_t, std::shared_ptr<const AlignmentTransform>> onlyFirst = {{1, transformOf(a)}};
  auto partial = correctFiles(
      {one, two}, path("partial.h5"), sndCalorimeter(),
      [&](std::int64_t run) -> Result<std::shared_ptr<const AlignmentTransform>> {
        if (auto it = onlyFirst.find(run); it != onlyFirst.end()) return it->second;
        return Error{fmt::format("no alignment of run {}", run)};
      },
      o);
  ASSERT_FALSE(partial.ok());
  EXPECT_NE(partial.error().message.find("run 2"), std::string::npos) << partial.error().message;
  EXPECT_FALSE(fs::exists(path("partial.h5")));
}

TEST_F(CorrectFiles, EachInputIntoTheDirectoryUnderItsNameAndTwoOfOneNameRefused) {
  const AlignmentParameters a = geometry::testing::paperLike();
  const std::string one = simulated("run1.h5", a, 1, 800), two = simulated("run2.h5", a, 2, 800);
  const auto t = transformOf(a);
  const AlignmentOfRun alignmentOf = [&](std::int64_t) -> Result<std::shared_ptr<const AlignmentTransform>> {
    return t;
  };
  fs::create_directories(dir_ / "out");
  std::vector<std::string> written;
  auto r = correctEachInto({one, two}, path("out"), sndCalorimeter(), alignmentOf, CorrectOptions{},
                           [&](const std::string& f) { written.push_back(f); });
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_EQ(written.size(), 2u);
  EXPECT_EQ(written[0], path("out/run1.h5"));
  EXPECT_EQ(written[1], path("out/run2.h5"));
  EXPECT_EQ(r->method, CorrectionMethod::Hits) << "auto takes the hits of HDF5 files";
  EXPECT_EQ(r->rows, static_cast<std::int64_t>(rowsOf(one).size() + rowsOf(two).size()));

  fs::create_directories(dir_ / "other");
  fs::copy_file(one, dir_ / "other" / "run1.h5");
  fs::create_directories(dir_ / "out2");
  auto clash = correctEachInto({two, one, path("other/run1.h5")}, path("out2"), sndCalorimeter(), alignmentOf, {});
  ASSERT_FALSE(clash.ok());
  EXPECT_NE(clash.error().message.find("the same name"), std::string::npos) << clash.error().message;
  EXPECT_TRUE(fs::is_empty(dir_ / "out2")) << "refused before any work: not even run2.h5 corrected";
}

TEST(CorrectionRecord, SaysWhatCorrectedTheFile) {
  CorrectOptions o;
  o.depth = geometry::ShowerDepth::of(sndCalorimeter().description());
  o.depth.offset = 0.5;
  const io::Json alignment = {{"file", "fit.json"}};
  const io::Json record = correctionRecord(alignment, "clusters", o, {"a.h5", "b.h5"}, "");
  EXPECT_EQ(record.at("alignment"), alignment);
  EXPECT_EQ(record.at("method"), "clusters");
  EXPECT_DOUBLE_EQ(record.at("depth_offset_cm").get<double>(), 0.5);
  EXPECT_EQ(record.at("inputs").size(), 2u);
  EXPECT_TRUE(record.contains("software"));
  EXPECT_TRUE(record.contains("log_weight_w0"));
}

}  // namespace
}  // namespace emcalign::apply
