#include "emcalign/calib/fit_record.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/io/strict_json.hpp"

namespace emcalign::calib {

namespace {

using io::Json;
using io::strict::StrictObject;

// A number, or null for NaN (what io::numberOrNull wrote).
double numberOrNull(const StrictObject& o, std::string_view key) {
  const Json& v = o.at(key);
  if (v.is_null()) return kNotGiven;
  if (!v.is_number()) o.fail(o.pathOf(key), fmt::format("expected a number or null, got {}", v.type_name()));
  return v.get<double>();
}

double numberOrNullIfGiven(const StrictObject& o, std::string_view key) {
  return o.has(key) ? numberOrNull(o, key) : kNotGiven;
}

std::int64_t integer(const StrictObject& o, std::string_view key) {
  const Json& v = o.at(key);
  if (!v.is_number_integer()) o.fail(o.pathOf(key), fmt::format("expected an integer, got {}", v.type_name()));
  return v.get<std::int64_t>();
}

const Json& arrayAt(const StrictObject& o, std::string_view key) {
  const Json& v = o.at(key);
  if (!v.is_array()) o.fail(o.pathOf(key), fmt::format("expected an array, got {}", v.type_name()));
  return v;
}

std::vector<std::string> strings(const StrictObject& o, std::string_view key) {
  std::vector<std::string> out;
  const Json& list = arrayAt(o, key);
  for (std::size_t k = 0; k < list.size(); ++k) {
    if (!list[k].is_string()) o.fail(fmt::format("{}[{}]", o.pathOf(key), k), "expected a string");
    out.push_back(list[k].get<std::string>());
  }
  return out;
}

std::optional<std::string> optionalString(const StrictObject& o, std::string_view key) {
  if (!o.has(key) || o.at(key).is_null()) return std::nullopt;
  return o.string(key);
}

Param paramNamed(const StrictObject& o, const std::string& where, const Json& v) {
  const auto p = v.is_string() ? paramFromName(v.get<std::string>()) : std::nullopt;
  if (!p) o.fail(where, fmt::format("not a fit parameter (the 12 are: {})", fmt::join(kParamNames, ", ")));
  return *p;
}

// "parameters", "errors" and, when written, "systematic_errors": each of the 12 by name.
void readParameters(const StrictObject& top, FitRecord& r) {
  const StrictObject values = top.object("parameters"), errors = top.object("errors");
  for (Param p : kAllParams) {
    r.parameters[index(p)].value = values.number(name(p));
    r.parameters[index(p)].error = numberOrNull(errors, name(p));
  }
  if (top.has("systematic_errors") && !top.at("systematic_errors").is_null()) {
    const StrictObject systematic = top.object("systematic_errors");
    r.hasSystematics = true;
    for (Param p : kAllParams) r.parameters[index(p)].systematic = numberOrNullIfGiven(systematic, name(p));
  }
}

void readDerived(const StrictObject& top, FitRecord& r) {
  if (!top.has("derived")) return;
  const StrictObject derived = top.object("derived");
  for (const auto& [key, entry] : top.at("derived").items()) {
    const auto q = quantityFromName(key);
    if (!q) derived.fail(derived.pathOf(key), "not a parameter of the physical set");
    const StrictObject d = derived.object(key);
    r.derived.emplace_back(*q, calib::RecordedValue{.value = numberOrNull(d, "value"),
                                                    .error = numberOrNullIfGiven(d, "error"),
                                                    .systematic = numberOrNullIfGiven(d, "systematic_error")});
  }
}

void readCorrelation(const StrictObject& top, FitRecord& r) {
  if (!top.has("correlation") || top.at("correlation").is_null()) return;
  const Json& rows = arrayAt(top, "correlation");
  if (rows.size() != kNumParams) top.fail("correlation", fmt::format("expected {} rows", kNumParams));
  auto& m = r.correlation.emplace();
  for (std::size_t i = 0; i < kNumParams; ++i) {
    if (!rows[i].is_array() || rows[i].size() != kNumParams) {
      top.fail(fmt::format("correlation[{}]", i), fmt::format("expected {} numbers", kNumParams));
    }
    for (std::size_t k = 0; k < kNumParams; ++k) {
      const Json& v = rows[i][k];
      if (!v.is_null() && !v.is_number()) top.fail(fmt::format("correlation[{}][{}]", i, k), "expected a number");
      m[i][k] = v.is_number() ? v.get<double>() : kNotGiven;
    }
  }
}

RecordedSigmaSys readSigmaSys(const StrictObject& s) {
  RecordedSigmaSys out{.method = s.has("method") ? s.string("method") : std::string("?"),
                       .valueDeg = numberOrNullIfGiven(s, "value_deg")};
  if (s.has("interval_deg")) {
    const Json& interval = arrayAt(s, "interval_deg");
    if (interval.size() != 2) s.fail(s.pathOf("interval_deg"), "expected [lower, upper]");
    const auto bound = [&](std::size_t k) {
      if (!interval[k].is_null() && !interval[k].is_number())
        s.fail(fmt::format("{}[{}]", s.pathOf("interval_deg"), k), "expected a number or null");
      return interval[k].is_number() ? interval[k].get<double>() : kNotGiven;
    };
    out.intervalDeg = {bound(0), bound(1)};
  }
  if (s.has("chi2_statistical_errors")) out.chi2Statistical = numberOrNull(s, "chi2_statistical_errors");
  out.pValueStatistical = numberOrNullIfGiven(s, "p_value_statistical_errors");
  return out;
}

std::vector<RecordedStage> readStages(const StrictObject& top) {
  std::vector<RecordedStage> stages;
  if (!top.has("stages")) return stages;
  const Json& list = arrayAt(top, "stages");
  for (std::size_t k = 0; k < list.size(); ++k) {
    const StrictObject s = top.nested(list[k], fmt::format("stages[{}]", k));
    RecordedStage stage{.stage = integer(s, "stage"),
                        .chi2 = numberOrNull(s, "chi2"),
                        .iterations = integer(s, "iterations"),
                        .converged = s.has("converged") && s.at("converged") == true};
    const Json& free = arrayAt(s, "free");
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
    const Json& points = arrayAt(i, "points");
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
  if (in.has("files")) out.files = strings(in, "files");
  out.fromProfile = in.has("from_profile") && in.at("from_profile") == true;
  if (in.has("detector")) out.detector = in.string("detector");
  if (in.has("bins_used")) out.binsUsed = integer(in, "bins_used");
  if (in.has("model_corrections")) out.modelCorrections = readCorrections(in.object("model_corrections"));
  if (in.has("beam_energies_mev")) {
    const Json& energies = arrayAt(in, "beam_energies_mev");
    for (std::size_t k = 0; k < energies.size(); ++k) {
      out.beamEnergiesMev.push_back(in.numberValue(energies[k], fmt::format("input.beam_energies_mev[{}]", k)));
    }
  }
  if (in.has("cut_flow")) {
    const StrictObject flow = in.object("cut_flow");
    for (const auto& [cut, events] : in.at("cut_flow").items()) out.cutFlow.emplace_back(cut, integer(flow, cut));
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

Result<FitRecord> parseFitRecord(const io::Json& j, std::string_view source) {
  if (!j.is_object() || !j.contains("parameters") || !j.contains("chi2") || !j.contains("input")) {
    return Error{fmt::format("{}: not a fit result (emcalign fit -o)", source)};
  }
  return io::strict::guarded([&] {
    const StrictObject top(j, "", source);
    FitRecord r;
    readParameters(top, r);
    readDerived(top, r);
    readCorrelation(top, r);
    r.chi2 = numberOrNull(top, "chi2");
    r.ndf = integer(top, "ndf");
    r.pValue = numberOrNullIfGiven(top, "p_value");
    const std::string status = top.string("status");
    const auto s = fitStatusFromName(status);
    if (!s) {
      top.fail("status",
               fmt::format("unknown status '{}' (converged, poor fit, not converged, covariance singular)", status));
    }
    r.status = *s;
    r.warnings = strings(top, "warnings");
    if (top.has("notes")) r.notes = strings(top, "notes");
    if (top.has("sigma_sys")) r.sigmaSys = readSigmaSys(top.object("sigma_sys"));
    r.stages = readStages(top);
    r.input = readInput(top.object("input"));
    if (top.has("software")) r.software = top.string("software");
    return r;
  });
}

}  // namespace emcalign::calib
