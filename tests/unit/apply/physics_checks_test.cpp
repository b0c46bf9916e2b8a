// The pieces of the physics checks: the Gaussian core width on known distributions.

#include "emcalign/apply/physics_checks.hpp"

#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace emcalign::apply {
namespace {

TEST(GaussianCore, MeasuresAGaussianAndItsError) {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g(0.3, 1.2);
  std::vector<double> widths;
  double errorSum = 0.0;
  for (int k = 0; k < 40; ++k) {
    std::vector<double> v(20000);
    for (double& x : v) x = g(rng);
    const CoreWidth w = gaussianCore(v);
    ASSERT_TRUE(w.fitted);
    EXPECT_NEAR(w.mean, 0.3, 5.0 * w.meanError);
    EXPECT_NEAR(w.rms, 1.2, 0.03);
    widths.push_back(w.width);
    errorSum += w.widthError;
  }
  double mean = 0.0, ss = 0.0;
  for (double w : widths) mean += w / widths.size();
  for (double w : widths) ss += (w - mean) * (w - mean);
  const double spread = std::sqrt(ss / (widths.size() - 1)), quoted = errorSum / widths.size();
  EXPECT_NEAR(mean, 1.2, 3.0 * quoted / std::sqrt(40.0) + 0.005);
  EXPECT_NEAR(spread / quoted, 1.0, 0.3);  // the quoted error is the real spread
}

TEST(GaussianCore, IgnoresTailsThatTheRmsSees) {
  std::mt19937_64 rng(2);
  std::normal_distribution<double> core(0.0, 1.0), tail(0.0, 8.0);
  std::vector<double> v;
  for (int k = 0; k < 30000; ++k) v.push_back(k % 10 == 0 ? tail(rng) : core(rng));
  const CoreWidth w = gaussianCore(v);
  ASSERT_TRUE(w.fitted);
  EXPECT_NEAR(w.width, 1.0, 0.1);  // a little wider: the tail under the core
  EXPECT_GT(w.rms, 2.0);
}

TEST(GaussianCore, TooFewValuesAreNotFitted) {
  const std::vector<double> v = {1.0, 2.0, 3.0};
  const CoreWidth w = gaussianCore(v);
  EXPECT_FALSE(w.fitted);
  EXPECT_EQ(w.entries, 3);
  EXPECT_NEAR(w.rms, std::sqrt(2.0 / 3.0), 1e-12);
}

}  // namespace
}  // namespace emcalign::apply
