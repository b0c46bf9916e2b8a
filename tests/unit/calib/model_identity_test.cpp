// The model of a fit as data (calib/model_identity.hpp): its one wording, and "the same model"
// decided by the members, the digest only where both record it.

#include "emcalign/calib/model_identity.hpp"

#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"

namespace emcalign::calib {
namespace {

ModelIdentity corrections(const std::string& file, const std::string& sha) {
  return {.kind = ModelIdentity::Kind::Corrections, .corrections = file, .correctionsSha256 = sha};
}

TEST(ModelIdentity, IsSaidInOneWording) {
  ModelIdentity paper{.kind = ModelIdentity::Kind::Paper};
  EXPECT_EQ(paper.text(), "the paper's model");
  EXPECT_EQ(paper.brief(), "paper's model");
  paper.depthOffsetCm = -0.25;
  EXPECT_EQ(paper.text(), "the paper's model, depth offset -0.25 cm");
  paper.sigmaSys = SigmaSysChoice::automatic();
  EXPECT_EQ(paper.textWithSigmaSys(), "the paper's model, depth offset -0.25 cm; sigma_sys auto");
  const ModelIdentity file = corrections("/data/corr/612.5.json", "");
  EXPECT_EQ(file.text(), "corrections /data/corr/612.5.json");
  EXPECT_EQ(file.brief(), "612.5.json");
  EXPECT_EQ(file.textWithSigmaSys(), file.text());  // σ_sys not recorded
  EXPECT_EQ(ModelIdentity{}.text(), "");
  EXPECT_EQ(sigmaSysText(SigmaSysChoice::spec()), "0.2 deg");
  EXPECT_EQ(sigmaSysText(SigmaSysChoice::fixed(0.35 * units::deg)), "0.35 deg");
}

TEST(ModelIdentity, TheSameModelByItsMembersAndByDigestWhereBothHaveOne) {
  EXPECT_TRUE(corrections("c.json", "aa").sameModel(corrections("c.json", "aa")));
  EXPECT_FALSE(corrections("c.json", "aa").sameModel(corrections("c.json", "bb")));  // the file changed
  EXPECT_TRUE(corrections("c.json", "").sameModel(corrections("c.json", "bb")));     // one does not say
  EXPECT_FALSE(corrections("c.json", "aa").sameModel(corrections("d.json", "aa")));
  const ModelIdentity paper{.kind = ModelIdentity::Kind::Paper};
  ModelIdentity moved = paper;
  moved.depthOffsetCm = 1.0;
  EXPECT_FALSE(paper.sameModel(moved));
  EXPECT_FALSE(paper.sameModel(ModelIdentity{}));
  moved = paper;
  moved.sigmaSys = SigmaSysChoice::automatic();  // σ_sys is compared on its own
  EXPECT_TRUE(paper.sameModel(moved));
}

}  // namespace
}  // namespace emcalign::calib
