// The systematic variations (validation/variations.hpp): every one changes the simulation,
// pairs share a quantity, and the patterns (gains, dead counters) are drawn anew per sample,
// the same for the same seed.

#include "emcalign/validation/variations.hpp"

#include <algorithm>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "emcalign/validation/systematics.hpp"

namespace emcalign::validation {
namespace {

TEST(Variations, ComeInPairsOfOneQuantityWithUniqueNames) {
  std::set<std::string> names;
  for (std::size_t k = 0; k < variations().size(); ++k) {
    const Variation& v = variations()[k];
    EXPECT_TRUE(names.insert(v.name).second) << v.name;
    EXPECT_EQ(findVariation(v.name), &v);
    EXPECT_FALSE(v.why.empty()) << v.name;
    if (k % 2 == 1) {
      EXPECT_EQ(v.quantity, variations()[k - 1].quantity) << v.name;
    }
  }
  EXPECT_EQ(names.size(), 20u);
  EXPECT_EQ(findVariation("gravity"), nullptr);
  const auto listed = variationNames();  // what --variation takes, in the documented order
  ASSERT_EQ(listed.size(), variations().size());
  for (std::size_t k = 0; k < listed.size(); ++k) EXPECT_EQ(listed[k], variations()[k].name);
}

TEST(Variations, DeadCounterPatternsAreDrawnPerSampleAndRepeatable) {
  const Variation* v = findVariation("dead-double");
  ASSERT_NE(v, nullptr);
  ASSERT_NE(v->pattern, nullptr);
  constexpr int kCounters = 1680;
  const auto draw = [&](std::uint64_t seed) {
    sim::SimulationOptions o;
    v->apply(o);
    v->pattern(o, seed, kCounters);
    return o.emc.deadCounters;
  };
  const std::vector<int> defaults = sim::SimulationOptions{}.emc.deadCounters;
  const std::vector<int> a = draw(11), b = draw(12);
  EXPECT_EQ(draw(11), a);
  EXPECT_NE(a, b);
  for (const auto& list : {a, b}) {
    ASSERT_EQ(list.size(), 2 * defaults.size());
    EXPECT_TRUE(std::equal(defaults.begin(), defaults.end(), list.begin()));  // the default ones stay dead
    EXPECT_EQ(std::set<int>(list.begin(), list.end()).size(), list.size());   // no counter twice
    for (int c : list) EXPECT_TRUE(c >= 0 && c < kCounters) << c;
  }
}

TEST(Variations, GainPatternsFollowTheSampleSeedAndRecordThemselves) {
  const Variation* v = findVariation("gains-5pc");
  ASSERT_NE(v, nullptr);
  CampaignOptions o = withVariation(CampaignOptions{}, *v);
  EXPECT_DOUBLE_EQ(o.simulation.emc.counterGainSpread, 0.05);
  EXPECT_EQ(o.settings["variation"], "gains-5pc");
  ASSERT_TRUE(o.samplePattern);
  // The gains come from Rng(gainSeed, counter): a seed of their own per sample, not the
  // sample's (whose streams are its events').
  const auto seedOf = [&](std::uint64_t sampleSeed) {
    sim::SimulationOptions s = o.simulation;
    o.samplePattern(s, sampleSeed, 1680);
    return s.emc.gainSeed;
  };
  EXPECT_EQ(seedOf(77), seedOf(77));
  EXPECT_NE(seedOf(77), seedOf(78));
  EXPECT_NE(seedOf(77), 77u);
  EXPECT_EQ(o.settings["variation_pattern"], "drawn per sample from its own stream");
  // A variation that is no pattern leaves the samples alike.
  const CampaignOptions t = withVariation(CampaignOptions{}, *findVariation("tmax-up"));
  EXPECT_FALSE(t.samplePattern);
  EXPECT_FALSE(t.settings.contains("variation_pattern"));
}

}  // namespace
}  // namespace emcalign::validation
