// The points CSV of `emcalign transform` (io/points_csv.hpp): what it reads, and each refusal
// naming the line and the column.

#include "emcalign/io/points_csv.hpp"

#include <gtest/gtest.h>

#include <sstream>

namespace emcalign::io {
namespace {

Result<std::vector<Vec3>> read(const std::string& text) {
  std::istringstream in(text);
  return readPointsCsv(in, "stdin");
}

TEST(PointsCsv, ReadsPointsSkippingBlankAndCommentLines) {
  auto p = read("# a comment\nx_cm,y_cm,z_cm\n41,0,0\n\n-0.5, 41 ,2.5e1\n# end\n");
  ASSERT_TRUE(p) << p.error().message;
  ASSERT_EQ(p->size(), 2U);
  EXPECT_DOUBLE_EQ((*p)[0].x(), 41.0);
  EXPECT_DOUBLE_EQ((*p)[1].y(), 41.0);
  EXPECT_DOUBLE_EQ((*p)[1].z(), 25.0);
}

TEST(PointsCsv, AHeaderAloneIsNoPoint) {
  auto p = read("x_cm,y_cm,z_cm");
  ASSERT_TRUE(p) << p.error().message;
  EXPECT_TRUE(p->empty());
}

TEST(PointsCsv, RefusalsNameTheLineAndTheColumn) {
  auto noHeader = read("");
  ASSERT_FALSE(noHeader);
  EXPECT_EQ(noHeader.error().message, "stdin: no header line x_cm,y_cm,z_cm");
  auto wrongHeader = read("x,y,z\n1,2,3\n");
  ASSERT_FALSE(wrongHeader);
  EXPECT_NE(wrongHeader.error().message.find("stdin, line 1: expected the header"), std::string::npos);
  auto columns = read("x_cm,y_cm,z_cm\n1,2\n");
  ASSERT_FALSE(columns);
  EXPECT_EQ(columns.error().message, "stdin, line 2: expected 3 columns (x_cm,y_cm,z_cm), got 2");
  auto notANumber = read("x_cm,y_cm,z_cm\n1,2,3\n1,nan,3\n");
  ASSERT_FALSE(notANumber);
  EXPECT_NE(notANumber.error().message.find("stdin, line 3, column 'y_cm': not a finite number"), std::string::npos);
}

TEST(PointsCsv, ALineWithoutEndIsRefusedBeforeItFillsTheMemory) {
  auto p = read("x_cm,y_cm,z_cm\n" + std::string(kMaxPointLine + 1, '1'));
  ASSERT_FALSE(p);
  EXPECT_NE(p.error().message.find("stdin, line 2: longer than 1 MiB"), std::string::npos);
}

}  // namespace
}  // namespace emcalign::io
