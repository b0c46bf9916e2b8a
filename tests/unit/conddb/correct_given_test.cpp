// `emcalign correct`'s decisions in the library (conddb/correct_given.hpp): a directory output,
// the warning of clusters moved at another depth than the fit's, the line printed.

#include "emcalign/conddb/correct_given.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace emcalign::conddb {
namespace {

using ::testing::HasSubstr;

TEST(CorrectGiven, ADirectoryOutputAndTheInputsByOption) {
  CorrectGiven g;
  g.events = {"a.h5"};
  g.alignment = "fit.json";
  g.output = "corrected/";
  EXPECT_TRUE(correctsIntoDirectory(g));
  g.output = "corrected.h5";
  EXPECT_FALSE(correctsIntoDirectory(g));
  const auto inputs = correctInputs(g);
  ASSERT_EQ(inputs.size(), 4u);
  EXPECT_EQ(inputs[1].option, "--alignment");
  EXPECT_EQ(inputs[3].option, "--detector");
}

TEST(CorrectGiven, ClustersMovedAtAnotherDepthThanTheFitsAreWarnedOf) {
  CorrectGiven g;
  g.output = "out.h5";
  AlignmentSource source;
  source.fittedDepths = {{"the corrections c.json", 0.3}};
  apply::CorrectOptions options;
  apply::CorrectReport report;
  report.method = apply::CorrectionMethod::Clusters;
  report.events = 1;
  report.rows = 2;
  report.clusters = 2;
  auto warnings = clusterDepthWarnings(g, source, options, report);
  ASSERT_TRUE(warnings) << warnings.error().message;
  ASSERT_EQ(warnings->size(), 1u);
  EXPECT_THAT(warnings->front(), HasSubstr("fitted with the corrections c.json (shower depth R(E, theta) +0.3 cm)"));
  options.depth.offset = 0.3 * units::cm;
  EXPECT_TRUE(clusterDepthWarnings(g, source, options, report)->empty());
  report.method = apply::CorrectionMethod::Hits;
  options.depth.offset = 0.0;
  EXPECT_TRUE(clusterDepthWarnings(g, source, options, report)->empty());
  report.method = apply::CorrectionMethod::Clusters;
  EXPECT_EQ(correctedText(g, source, options, report, 2.0),
            "correct (clusters at R(E, theta) +0 cm): 1 event, 2 rows, 2 clusters corrected in 2.0 s -> out.h5\n");
}

}  // namespace
}  // namespace emcalign::conddb
