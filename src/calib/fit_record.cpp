#include "emcalign/calib/fit_record.hpp"

#include <algorithm>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/io/strict_json.hpp"

namespace emcalign::calib {

namespace {

using io::Json;
using io::strict::StrictObject;

std::optional<std::string> optionalString(const StrictObject& o, std::string_view key) {
  if (!o.has(key) || o.at(key).is_null()) return std::nullopt;
  return o.string(key);
}

Param paramNamed(const StrictObject& o, const std::string& where, const Json& v) {
  const auto p = v.is_string() ? paramFromName(v.get<std::string>()) : std::nullopt;
  if (!p) o.fail(where, fmt::format("not a fit parameter (the 12 are: {})", fmt::join(kParamNames, ", ")));
  return *p;
}

// "parameters", "errors" and, when written, "statistical_errors" and "systematic_errors": each
// of the 12 by name.
void readParameters(const StrictObject& top, FitRecord& r) {
  const StrictObject values = top.object("parameters"), errors = top.object("errors");
  for (Param p : kAllParams) {
    r.parameters[index(p)].value = values.number(name(p));
    r.parameters[index(p)].error = errors.numberOrNull(name(p));
  }
  if (top.has("statistical_errors") && !top.at("statistical_errors").is_null()) {
    const StrictObject statistical = top.object("statistical_errors");
    for (Param p : kAllParams) r.parameters[index(p)].statistical = statistical.numberOrNullIfGiven(name(p));
  }
  if (top.has("systematic_errors") && !top.at("systematic_errors").is_null()) {
    const StrictObject systematic = top.object("systematic_errors");
    r.hasSystematics = true;
    for (Param p : kAllParams) r.parameters[index(p)].systematic = systematic.numberOrNullIfGiven(name(p));
  }
}

void readDerived(const StrictObject& top, FitRecord& r) {
  if (!top.has("derived")) return;
  const StrictObject derived = top.object("derived");
  for (const auto& [key, entry] : top.at("derived").items()) {
    const auto p = physicalFromName(key);
    if (!p || std::find(kDerivedParams.begin(), kDerivedParams.end(), *p) == kDerivedParams.end()) {
      derived.fail(derived.pathOf(key), "not one of the derived parameters (beta, psi, mu, tau, dx_rel)");
    }
    const StrictObject d = derived.object(key);
    r.derived.emplace_back(Quantity(*p), calib::RecordedValue{.value = d.numberOrNull("value"),
                                                              .error = d.numberOrNullIfGiven("error"),
                                                              .statistical = d.numberOrNullIfGiven("statistical_error"),
                                                              .systematic = d.numberOrNullIfGiven("systematic_error")});
  }
}

void readCorrelation(const StrictObject& top, FitRecord& r) {
  if (!top.has("correlation") || top.at("correlation").is_null()) return;
  const Json& rows = top.array("correlation");
  if (rows.size() != kNumParams) top.fail("correlation", fmt::format("expected {} rows", kNumParams));
  auto& m = r.correlation.emplace();
  for (std::size_t i = 0; i < kNumParams; ++i) {
    if (!rows[i].is_array() || rows[i].size() != kNumParams) {
      top.fail(fmt::format("correlation[{}]", i), fmt::format("expected {} numbers", kNumParams));
    }
    for (std::size_t k = 0; k < kNumParams; ++k) {
      const Json& v = rows[i][k];
      if (!v.is_null() && !v.is_number()) {
        top.fail(fmt::format("correlation[{}][{}]", i, k), "expected a number or null");
      }
      m[i][k] = v.is_number() ? v.get<double>() : kNotGiven;
    }
  }
}

RecordedSigmaSys readSigmaSys(const StrictObject& s) {
  RecordedSigmaSys out{.method = s.has("method") ? s.string("method") : std::string("?"),
                       .valueDeg = s.numberOrNullIfGiven("value_deg")};
  if (s.has("interval_deg")) {
    const Json& interval = s.array("interval_deg");
    if (interval.size() != 2) s.fail(s.pathOf("interval_deg"), "expected [lower, upper]");
    const auto bound = [&](std::size_t k) {
      if (!interval[k].is_null() && !interval[k].is_number())
        s.fail(fmt::format("{}[{}]", s.pathOf("interval_deg"), k), "expected a number or null");
      return interval[k].is_number() ? interval[k].get<double>() : kNotGiven;
    };
    out.intervalDeg = {bound(0), bound(1)};
  }
  if (s.has("chi2_statistical_errors")) out.chi2Statistical = s.numberOrNull("chi2_statistical_errors");
  out.pValueStatistical = s.numberOrNullIfGiven("p_value_statistical_errors");
  return out;
}

std::vector<RecordedStage> readStages(const StrictObject& top) {
  std::vector<RecordedStage> stages;
  if (!top.has("stages")) return stages;
  const Json& list = top.array("stages");
  for (std::size_t k = 0; k < list.size(); ++k) {
    const StrictObject s = top.nested(list[k], fmt::format("stages[{}]", k));
    RecordedStage stage{.stage = s.integer("stage"),
                        .chi2 = s.numberOrNull("chi2"),
                        .iterations = s.integer("iterations"),
                        .converged = s.has("converged") && s.at("converged") == true};
    const Json& free = s.array("free");
    for (std::size_t i = 0; i < free.size(); ++i) {
      stage.free.push_back(paramNamed(s, fmt::format("{}[{}]", s.pathOf("free"), i), free[i]));
    }
    stages.push_back(std::move(stage));
  }
  return stages;
}

RecordedCorrections readCorrections(const StrictObject& c) {
  RecordedCorrections out{.depthOffsetCm = c.has("depth_offset_cm") && !c.at("depth_offset_cm").is_null()
                                               ? c.number("depth_offset_cm")
                                               : 0.0,
                          .partingPlaneResponse = optionalString(c, "parting_plane_response"),
                          .nominalProfile = optionalString(c, "nominal_profile"),
                          .response = optionalString(c, "response")};
  if (c.has("interpolation") && !c.at("interpolation").is_null()) {
    const StrictObject i = c.object("interpolation");
    (void)i.number("beam_energy_mev");
    (void)i.string("directory");
    const Json& points = i.array("points");
    for (std::size_t k = 0; k < points.size(); ++k) {
      const StrictObject p = i.nested(points[k], fmt::format("{}[{}]", i.pathOf("points"), k));
      (void)p.number("beam_energy_mev");
      (void)p.number("weight");
    }
    out.interpolation = c.at("interpolation");
  }
  return out;
}

RecordedInput readInput(const StrictObject& in) {
  RecordedInput out;
  if (in.has("files")) out.files = in.strings("files");
  out.fromProfile = in.has("from_profile") && in.at("from_profile") == true;
  if (in.has("detector")) out.detector = in.string("detector");
  if (in.has("bins_used")) out.binsUsed = in.integer("bins_used");
  if (in.has("model_corrections")) out.modelCorrections = readCorrections(in.object("model_corrections"));
  if (in.has("beam_energies_mev")) {
    const Json& energies = in.array("beam_energies_mev");
    for (std::size_t k = 0; k < energies.size(); ++k) {
      out.beamEnergiesMev.push_back(in.numberValue(energies[k], fmt::format("input.beam_energies_mev[{}]", k)));
    }
  }
  if (in.has("cut_flow")) {
    const StrictObject flow = in.object("cut_flow");
    for (const auto& [cut, events] : in.at("cut_flow").items()) out.cutFlow.emplace_back(cut, flow.integer(cut));
  }
  return out;
}

}  // namespace

std::vector<std::pair<std::string_view, std::string>> RecordedCorrections::files() const {
  std::vector<std::pair<std::string_view, std::string>> out;
  if (partingPlaneResponse) out.emplace_back("parting_plane_response", *partingPlaneResponse);
  if (nominalProfile) out.emplace_back("nominal_profile", *nominalProfile);
  if (response) out.emplace_back("response", *response);
  return out;
}

double RecordedCorrections::interpolatedEnergyMev() const {
  return interpolation.is_object() ? interpolation.at("beam_energy_mev").get<double>() : kNotGiven;
}

std::string RecordedCorrections::source() const {
  if (interpolation.is_object()) return interpolation.at("directory").get<std::string>();
  for (const auto* file : {&response, &nominalProfile, &partingPlaneResponse}) {
    if (*file) return **file;
  }
  return {};
}

geometry::AlignmentParameters FitRecord::alignment() const {
  geometry::AlignmentParameters eta;
  for (Param p : kAllParams) eta[p] = (*this)[p].value * geometry::AlignmentParameters::fileUnit(p);
  return eta;
}

bool isFitResult(const io::Json& j) {
  return j.is_object() && j.contains("parameters") && j.contains("chi2") && j.contains("input");
}

Result<FitRecord> parseFitRecord(const io::Json& j, std::string_view source) {
  if (!isFitResult(j)) {
    return Error{fmt::format("{}: not a fit result (emcalign fit -o)", source)};
  }
  return io::strict::guarded([&] {
    const StrictObject top(j, "", source);
    io::strict::checkAlignmentHeader(top);
    FitRecord r;
    readParameters(top, r);
    readDerived(top, r);
    readCorrelation(top, r);
    r.chi2 = top.numberOrNull("chi2");
    r.ndf = top.integer("ndf");
    r.pValue = top.numberOrNullIfGiven("p_value");
    r.status = io::strict::fitStatusAt(top, "status");
    r.warnings = top.strings("warnings");
    if (top.has("notes")) r.notes = top.strings("notes");
    if (top.has("sigma_sys")) r.sigmaSys = readSigmaSys(top.object("sigma_sys"));
    r.stages = readStages(top);
    r.input = readInput(top.object("input"));
    if (top.has("software")) r.software = top.string("software");
    return r;
  });
}

}  // namespace emcalign::calib
