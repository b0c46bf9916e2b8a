// A fit result read back from its file (calib/fit_record.hpp): what fitResultJson writes comes
// back field by field, nulls as NaN, an older result's missing sections as empty, and a file
// that is not a fit result, or a key of the wrong type, refused by name.

#include "emcalign/calib/fit_record.hpp"

#include <cmath>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/core/units.hpp"

namespace emcalign::calib {
namespace {

using geometry::AlignmentParameters;
using io::Json;

// A result with a distinct value in every field the file has.
FitResult aResult() {
  FitResult r;
  for (Param p : kAllParams) {
    r.parameters[p] = (0.01 + 0.001 * static_cast<double>(index(p))) * AlignmentParameters::fileUnit(p);
    r.errors[index(p)] = (0.002 + 0.0001 * static_cast<double>(index(p))) * AlignmentParameters::fileUnit(p);
  }
  r.errors[index(Param::Dp2)] = std::nan("");  // written as null
  Covariance cov = Covariance::Identity();
  cov(index(Param::Dx), index(Param::Dy)) = cov(index(Param::Dy), index(Param::Dx)) = 0.25;
  r.covariance = cov;
  r.correlation = cov;
  for (Physical p : kDerivedParams) r.derived[p] = {0.1 * static_cast<double>(index(p)), 0.01};
  r.derived[Physical::Psi].error = std::nan("");
  r.chi2 = 321.5;
  r.ndf = 308;
  r.pValue = 0.31;
  r.binsUsed = 320;
  r.stages = {{{Param::Alpha, Param::Dx}, 400.0, 7, true, "converged"},
              {{Param::Alpha, Param::Dx, Param::DyRel}, 321.5, 12, false, "no convergence"}};
  r.status = FitStatus::PoorFit;
  r.warnings = {"a warning", "another"};
  r.sigmaSys = {.method = SigmaSysMethod::Auto,
                .value = 0.25 * units::deg,
                .lower = 0.2 * units::deg,
                .upper = std::nan(""),
                .chi2Stat = 512.0,
                .pValueStat = 1e-9,
                .fits = 4};
  return r;
}

TEST(FitRecord, ReadsBackWhatTheResultFileSays) {
  const FitResult r = aResult();
  ProfileFill fill;
  fill.beamEnergies = {612.5};
  fill.cutFlow.events[0] = 1000;
  auto systematics = std::make_shared<SystematicErrors>();
  for (Param p : kAllParams) systematics->errors[p] = 0.003;
  systematics->errors[Physical::Mu] = 0.004;
  FitInput input;
  input.files = {"a.h5", "b.h5"};
  input.fill = &fill;
  input.detector = "det.json";
  input.depthOffset = 0.31 * units::cm;
  input.response = "corr/response.json";
  input.systematics = systematics;
  input.systematicsSource = "corr";

  auto read = parseFitRecord(fitResultJson(r, input), "r.json");
  ASSERT_TRUE(read.ok()) << read.error().message;
  const FitRecord& f = *read;
  for (Param p : kAllParams) {
    EXPECT_DOUBLE_EQ(f[p].value, r.parameters[p] / AlignmentParameters::fileUnit(p)) << name(p);
    EXPECT_DOUBLE_EQ(f[p].systematic, 0.003) << name(p);
    if (p != Param::Dp2) {
      EXPECT_DOUBLE_EQ(f[p].error, r.errors[index(p)] / AlignmentParameters::fileUnit(p));
    }
  }
  EXPECT_TRUE(std::isnan(f[Param::Dp2].error)) << "a null error";
  EXPECT_TRUE(f.hasSystematics);
  ASSERT_EQ(f.derived.size(), kDerivedParams.size());
  for (std::size_t k = 0; k < kDerivedParams.size(); ++k) {
    EXPECT_EQ(f.derived[k].first, Quantity(kDerivedParams[k])) << "the file's order";
  }
  EXPECT_TRUE(std::isnan(f.derived[1].second.error)) << "ψ's null error";
  EXPECT_DOUBLE_EQ(f.derived[2].second.systematic, 0.004) << "μ's systematic error";
  EXPECT_TRUE(std::isnan(f.derived[0].second.systematic)) << "β has none";
  ASSERT_TRUE(f.correlation.has_value());
  EXPECT_DOUBLE_EQ((*f.correlation)[index(Param::Dx)][index(Param::Dy)], 0.25);
  EXPECT_DOUBLE_EQ(f.chi2, 321.5);
  EXPECT_EQ(f.ndf, 308);
  EXPECT_DOUBLE_EQ(f.pValue, 0.31);
  EXPECT_EQ(f.status, FitStatus::PoorFit);
  EXPECT_EQ(f.warnings, r.warnings);
  ASSERT_EQ(f.stages.size(), 2u);
  EXPECT_EQ(f.stages[1].stage, 2);
  EXPECT_EQ(f.stages[1].free, r.stages[1].free);
  EXPECT_EQ(f.stages[1].iterations, 12);
  EXPECT_FALSE(f.stages[1].converged);
  EXPECT_TRUE(f.stages[0].converged);
  ASSERT_TRUE(f.sigmaSys.has_value());
  EXPECT_TRUE(f.sigmaSys->isAuto());
  EXPECT_DOUBLE_EQ(f.sigmaSys->valueDeg, 0.25);
  ASSERT_TRUE(f.sigmaSys->intervalDeg.has_value());
  EXPECT_DOUBLE_EQ(f.sigmaSys->intervalDeg->first, 0.2);
  EXPECT_TRUE(std::isnan(f.sigmaSys->intervalDeg->second)) << "unbounded";
  EXPECT_EQ(f.sigmaSys->chi2Statistical, 512.0);
  EXPECT_DOUBLE_EQ(f.sigmaSys->pValueStatistical, 1e-9);
  EXPECT_EQ(f.input.files, input.files);
  EXPECT_EQ(f.input.detector, "det.json");
  EXPECT_EQ(f.input.binsUsed, 320);
  EXPECT_EQ(f.input.beamEnergiesMev, std::vector<double>{612.5});
  ASSERT_EQ(f.input.cutFlow.size(), CutFlow::kNames.size());
  EXPECT_EQ(f.input.cutFlow.front(), (std::pair<std::string, std::int64_t>{CutFlow::kNames[0], 1000}));
  ASSERT_TRUE(f.input.modelCorrections.has_value());
  EXPECT_DOUBLE_EQ(f.input.modelCorrections->depthOffsetCm, 0.31);
  EXPECT_FALSE(f.input.modelCorrections->none());
  EXPECT_EQ(f.input.modelCorrections->source(), "corr/response.json");
  EXPECT_TRUE(std::isnan(f.input.modelCorrections->interpolatedEnergyMev()));
  EXPECT_EQ(f.software.rfind("emcalign ", 0), 0u);
  // Back in internal units, the fit's own set.
  for (Param p : kAllParams) EXPECT_NEAR(f.alignment()[p], r.parameters[p], 1e-15) << name(p);
}

FitInput anInput() {
  FitInput input;
  input.files = {"a.h5"};
  input.detector = "embedded default";
  return input;
}

TEST(FitRecord, AnOlderResultLacksSectionsAndIsReadAllTheSame) {
  Json j = fitResultJson(aResult(), anInput());
  for (const char* key : {"derived", "correlation", "covariance", "stages", "sigma_sys", "software"}) j.erase(key);
  j["input"] = {{"files", {"a.h5"}}};
  auto f = parseFitRecord(j, "old.json");
  ASSERT_TRUE(f.ok()) << f.error().message;
  EXPECT_TRUE(f->derived.empty());
  EXPECT_FALSE(f->correlation.has_value());
  EXPECT_TRUE(f->stages.empty());
  EXPECT_FALSE(f->sigmaSys.has_value());
  EXPECT_FALSE(f->hasSystematics);
  EXPECT_TRUE(f->notes.empty());
  EXPECT_EQ(f->input.detector, io::kEmbeddedDetector);
  EXPECT_FALSE(f->input.binsUsed.has_value());
  EXPECT_FALSE(f->input.modelCorrections.has_value());
}

TEST(FitRecord, RefusesWhatIsNotAFitResultNamingTheKey) {
  const Json good = fitResultJson(aResult(), anInput());
  const auto refusal = [&](auto change) {
    Json j = good;
    change(j);
    auto f = parseFitRecord(j, "r.json");
    return f.ok() ? std::string("accepted") : f.error().message;
  };
  EXPECT_EQ(refusal([](Json& j) { j.erase("chi2"); }), "r.json: not a fit result (emcalign fit -o)");
  EXPECT_EQ(refusal([](Json& j) { j = Json::array(); }), "r.json: not a fit result (emcalign fit -o)");
  EXPECT_EQ(refusal([](Json& j) { j["errors"].erase("dz"); }), "r.json: key 'errors.dz': missing");
  EXPECT_EQ(refusal([](Json& j) { j["parameters"]["dx"] = "0.1"; }),
            "r.json: key 'parameters.dx': expected a number, got string");
  EXPECT_EQ(refusal([](Json& j) { j["status"] = "<b>fine</b>"; }),
            "r.json: key 'status': unknown status '<b>fine</b>' (converged, poor fit, not converged, covariance "
            "singular)");
  EXPECT_EQ(refusal([](Json& j) { j["stages"][0]["free"][1] = "gamma"; }),
            "r.json: key 'stages[0].free[1]': not a fit parameter (the 12 are: alpha, beta1, beta2, dx, dy, dz, dp1, "
            "dp2, dp3, dy_rel, dz_rel, beta_rel)");
  EXPECT_EQ(refusal([](Json& j) {
              j["derived"]["alpha"] = {{"value", 1.0}};
            }),
            "r.json: key 'derived.alpha': not one of the derived parameters (beta, psi, mu, tau, dx_rel)");
  EXPECT_EQ(refusal([](Json& j) {
              j["units"] = {{"angle", "rad"}};
            }),
            "r.json: key 'units.angle': only \"deg\" is supported");
  EXPECT_EQ(refusal([](Json& j) { j["parameters"]["gamma"] = 0.1; }),
            "r.json: key 'parameters.gamma': unknown parameter (the 12 are: alpha, beta1, beta2, dx, dy, dz, dp1, dp2, "
            "dp3, dy_rel, dz_rel, beta_rel)");
  EXPECT_EQ(refusal([](Json& j) { j["extra"] = 1; }).substr(0, 40), "r.json: key 'extra': unknown key (allowe");
  EXPECT_EQ(refusal([](Json& j) { j["input"]["bins_used"] = 1.5; }),
            "r.json: key 'input.bins_used': expected an integer, got number");
  EXPECT_EQ(refusal([](Json& j) { j["correlation"].erase(3); }), "r.json: key 'correlation': expected 12 rows");
  EXPECT_EQ(refusal([](Json& j) {
              j["input"]["model_corrections"]["interpolation"] = {{"points", 1}};
            }),
            "r.json: key 'input.model_corrections.interpolation.beam_energy_mev': missing");
  EXPECT_EQ(refusal([](Json& j) { j["warnings"] = {"w", 3}; }), "r.json: key 'warnings[1]': expected a string");
  EXPECT_EQ(refusal([](Json&) {}), "accepted");
}

}  // namespace
}  // namespace emcalign::calib
