// The rule of prompt calibration (validation/prompt_decision.hpp): the thresholds file read
// strictly, and every branch of update / no-update / veto with the contract's strict comparisons.

#include "emcalign/validation/prompt_decision.hpp"

#include <cmath>
#include <string>

#include <gtest/gtest.h>

namespace emcalign::validation {
namespace {

using io::Json;

Json thresholdsJson() {
  return Json::parse(R"({"format": "emcalign-thresholds/1", "parameters": {
      "dx": {"min_change": 0.02, "significance": 3, "max_change": 0.5, "max_error": 0.05},
      "alpha": {"min_change": 0.01, "significance": 3, "max_change": 0.3, "max_error": 0.02}}})");
}

Thresholds thresholds() {
  auto t = parseThresholds(thresholdsJson(), "thr.json");
  EXPECT_TRUE(t.ok()) << t.error().message;
  return *t;
}

// A usable group of enough events: every parameter fitted at 0 ± 0.01, nothing in force.
GroupOutcome group() {
  GroupOutcome g;
  g.selected = 20000;
  g.minEvents = 20000;
  g.status = FitStatus::Converged;
  g.pValue = 0.5;
  for (auto& v : g.fitted) v = {0.0, 0.01, 0.01};
  return g;
}

conddb::StoredValues inForce(double dx, double alpha) {
  conddb::StoredValues v{};
  for (auto& x : v) x = {0.0, 0.01, 0.01};
  v[index(Param::Dx)].value = dx;
  v[index(Param::Alpha)].value = alpha;
  return v;
}

TEST(PromptThresholds, ReadInSpecOrderWithAHashOfTheirContent) {
  const Thresholds t = thresholds();
  ASSERT_EQ(t.parameters.size(), 2u);
  EXPECT_EQ(t.parameters[0].parameter, Param::Alpha) << "docs/contract.md §3's order, not the file's";
  EXPECT_EQ(t.parameters[1].parameter, Param::Dx);
  EXPECT_EQ(t.parameters[1].maxError, 0.05);
  EXPECT_EQ(t.sha256.size(), 64u);
  // The same thresholds written in another order or spacing: the same hash.
  Json reordered = {{"parameters", Json::object()}, {"format", "emcalign-thresholds/1"}};
  reordered["parameters"]["dx"] = thresholdsJson()["parameters"]["dx"];
  reordered["parameters"]["alpha"] = thresholdsJson()["parameters"]["alpha"];
  auto again = parseThresholds(reordered, "b.json");
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_EQ(again->sha256, t.sha256);
  Json other = thresholdsJson();
  other["parameters"]["dx"]["max_error"] = 0.06;
  EXPECT_NE(parseThresholds(other, "c.json")->sha256, t.sha256);
}

TEST(PromptThresholds, RefusedNamingTheKey) {
  const auto refused = [](const std::function<void(Json&)>& edit, const std::string& expected) {
    Json j = thresholdsJson();
    edit(j);
    auto t = parseThresholds(j, "thr.json");
    ASSERT_FALSE(t.ok()) << j.dump();
    EXPECT_NE(t.error().message.find(expected), std::string::npos) << t.error().message;
    EXPECT_NE(t.error().message.find("thr.json"), std::string::npos) << t.error().message;
  };
  refused([](Json& j) { j["format"] = "emcalign-thresholds/2"; }, "format");
  refused([](Json& j) { j["parameters"]["dxx"] = j["parameters"]["dx"]; }, "parameters.dxx");
  refused([](Json& j) { j["parameters"]["dx"].erase("max_error"); }, "parameters.dx.max_error");
  refused([](Json& j) { j["parameters"]["dx"]["significance"] = -3; }, "parameters.dx.significance");
  refused([](Json& j) { j["parameters"]["dx"]["min_change"] = "0.02"; }, "parameters.dx.min_change");
  refused([](Json& j) { j["parameters"]["dx"]["max_change"] = 0.01; }, "parameters.dx.max_change");
  refused([](Json& j) { j["parameters"]["dx"]["unit"] = "mm"; }, "parameters.dx.unit");
  refused([](Json& j) { j["parameters"] = Json::object(); }, "lists no parameter");
}

TEST(PromptThresholds, ProposedFromTheSpreadForTheFalseUpdateRate) {
  // One parameter at 1 %: z = 2.576; two at 1 %: z = 2.807 (0.5 % each).
  EXPECT_NEAR(falseUpdateQuantile(0.01, 1), 2.5758, 1e-3);
  EXPECT_NEAR(falseUpdateQuantile(0.01, 2), 2.8070, 1e-3);
  auto t = proposeThresholds({{Param::Dx, 0.01, 0.03}, {Param::Alpha, 0.02, 0.05}}, 0.01);
  ASSERT_TRUE(t.ok()) << t.error().message;
  ASSERT_EQ(t->parameters.size(), 2u);
  const ParameterThreshold& dx = t->parameters[1];
  EXPECT_EQ(dx.parameter, Param::Dx);
  EXPECT_NEAR(dx.minChange, 2.807 * std::sqrt(2.0) * 0.01, 1e-4);
  EXPECT_NEAR(dx.maxChange, 10 * dx.minChange, 1e-3);
  EXPECT_NEAR(dx.maxError, 0.06, 1e-12) << "twice the error a fit quotes";
  EXPECT_EQ(dx.significance, 3.0);
  EXPECT_FALSE(proposeThresholds({{Param::Dx, 0.0, 0.01}}, 0.01).ok());
  EXPECT_FALSE(proposeThresholds({{Param::Dx, 0.01, -1.0}}, 0.01).ok());
  EXPECT_FALSE(proposeThresholds({}, 0.01).ok());
}

TEST(PromptDecision, TheFirstGroupIsAnUpdateWithNothingCompared) {
  const DecisionResult d = decide(thresholds(), group());
  EXPECT_EQ(d.decision, Decision::Update);
  ASSERT_EQ(d.parameters.size(), 2u);
  EXPECT_EQ(d.parameters[1].fitted, 0.0);
  EXPECT_TRUE(std::isnan(d.parameters[1].inForce));
  EXPECT_TRUE(std::isnan(d.parameters[1].change));
  EXPECT_TRUE(std::isnan(d.parameters[1].significance));
}

TEST(PromptDecision, UpdateOnlyWhenBothBeyondMinChangeAndSignificance) {
  GroupOutcome g = group();
  // dx moved by 0.05 (5 σ, beyond 0.02): update.
  g.inForce = inForce(-0.05, 0.0);
  DecisionResult d = decide(thresholds(), g);
  EXPECT_EQ(d.decision, Decision::Update);
  EXPECT_NEAR(d.parameters[1].change, 0.05, 1e-12);
  EXPECT_NEAR(d.parameters[1].significance, 5.0, 1e-9);
  EXPECT_NE(d.reasons.at(0).find("dx"), std::string::npos) << d.reasons.at(0);
  // Beyond min_change but 2.5 σ only: no-update.
  g.fitted[index(Param::Dx)].error = 0.02;
  EXPECT_EQ(decide(thresholds(), g).decision, Decision::NoUpdate);
  // Significant (10 σ) but within min_change: no-update.
  g.fitted[index(Param::Dx)].error = 0.001;
  g.inForce = inForce(-0.01, 0.0);
  EXPECT_EQ(decide(thresholds(), g).decision, Decision::NoUpdate);
  // A parameter not listed moves a lot: neither tested nor vetoed.
  g.inForce = inForce(0.0, 0.0);
  (*g.inForce)[index(Param::Dz)].value = 5.0;
  EXPECT_EQ(decide(thresholds(), g).decision, Decision::NoUpdate);
}

TEST(PromptDecision, ComparisonsAreStrict) {
  GroupOutcome g = group();
  g.fitted[index(Param::Dx)] = {0.5, 0.05, 0.05};
  g.inForce = inForce(0.0, 0.0);
  // |Δ| = max_change exactly, σ = max_error exactly: not a veto; beyond min_change, 10 σ: update.
  EXPECT_EQ(decide(thresholds(), g).decision, Decision::Update);
  g.fitted[index(Param::Dx)] = {0.02, 0.001, 0.001};
  EXPECT_EQ(decide(thresholds(), g).decision, Decision::NoUpdate) << "|Δ| = min_change is not beyond it";
}

TEST(PromptDecision, VetoesForTheFitTheEventsAndTheLimits) {
  GroupOutcome g = group();
  g.inForce = inForce(0.0, 0.0);
  g.fitted[index(Param::Dx)].value = 0.6;  // beyond max_change 0.5
  DecisionResult d = decide(thresholds(), g);
  EXPECT_EQ(d.decision, Decision::Veto);
  EXPECT_NE(d.reasons.at(0).find("max_change"), std::string::npos);

  g = group();
  g.inForce = inForce(0.0, 0.0);
  g.fitted[index(Param::Alpha)].error = 0.03;  // beyond max_error 0.02
  EXPECT_EQ(decide(thresholds(), g).decision, Decision::Veto);
  g.inForce.reset();
  EXPECT_EQ(decide(thresholds(), g).decision, Decision::Veto) << "the first group too";

  g = group();
  g.status = FitStatus::NotConverged;
  g.inForce = inForce(0.0, 0.0);
  d = decide(thresholds(), g);
  EXPECT_EQ(d.decision, Decision::Veto);
  EXPECT_TRUE(std::isnan(d.parameters[0].fitted)) << "no value of an unusable fit";
  EXPECT_FALSE(std::isnan(d.parameters[0].inForce)) << "what is in force, all the same";
  EXPECT_TRUE(std::isnan(d.parameters[0].change));

  g = group();
  g.status = FitStatus::PoorFit;
  g.pValue = 1e-9;
  d = decide(thresholds(), g);
  EXPECT_EQ(d.decision, Decision::Update) << "a poor fit is usable";
  EXPECT_NE(d.reasons.back().find("poor fit"), std::string::npos);

  g = group();
  g.selected = 9999;  // below half of 20000
  d = decide(thresholds(), g);
  EXPECT_EQ(d.decision, Decision::Veto);
  EXPECT_NE(d.reasons.at(0).find("too few events"), std::string::npos);
  g.selected = 10000;  // half exactly: decided as it is
  EXPECT_EQ(decide(thresholds(), g).decision, Decision::Update);

  g = group();
  g.status.reset();
  g.fitProblem = "no selected event";
  g.selected = 0;
  EXPECT_EQ(decide(thresholds(), g).decision, Decision::Veto);
}

}  // namespace
}  // namespace emcalign::validation
