#include "emcalign/apply/residual_record.hpp"

#include <limits>

#include <fmt/format.h>

#include "emcalign/core/version.hpp"
#include "emcalign/io/strict_json.hpp"

namespace emcalign::apply {

using io::Json;
using io::strict::StrictObject;

Json residualsJson(const ResidualRecord& record) {
  Json samples = Json::array();
  for (const ResidualSample& s : record.samples) {
    const ResidualSummary& r = s.summary;
    Json columns = Json::array();
    for (double m : r.columnMeanDeg) columns.push_back(io::numberOrNull(m));
    samples.push_back({{"name", s.name},
                       {"files", s.files},
                       {"events", r.events},
                       {"particles", r.particles},
                       {"mean_sin_dphi_deg", io::numberOrNull(r.meanSinDphiDeg)},
                       {"mean_sin_dphi_error_deg", io::numberOrNull(r.meanSinDphiErrorDeg)},
                       {"mean_dtheta_deg", io::numberOrNull(r.meanDthetaDeg)},
                       {"mean_dtheta_error_deg", io::numberOrNull(r.meanDthetaErrorDeg)},
                       {"rms_dphi_deg", io::numberOrNull(r.rmsDphiDeg)},
                       {"rms_dtheta_deg", io::numberOrNull(r.rmsDthetaDeg)},
                       {"phi_column_mean_sin_dphi_deg", columns},
                       {"phi_irregularity_deg", io::numberOrNull(r.irregularityDeg)}});
  }
  return {{"software", record.software.empty() ? fmt::format("emcalign {}", kVersion) : record.software},
          {"depth_offset_cm", io::numberOrNull(record.depthOffsetCm)},
          {"samples", samples}};
}

std::string residualsTable(const std::vector<ResidualSample>& samples) {
  std::string table =
      "| sample | events | particles | mean sin Δφ (deg) | mean Δθ (deg) | rms Δφ (deg) | rms Δθ (deg) | "
      "φ irregularity (deg) |\n|---|---|---|---|---|---|---|---|\n";
  for (const ResidualSample& s : samples) {
    const ResidualSummary& r = s.summary;
    table += fmt::format("| {} | {} | {} | {:+.4f} ± {:.4f} | {:+.4f} ± {:.4f} | {:.3f} | {:.3f} | {:.4f} |\n", s.name,
                         r.events, r.particles, r.meanSinDphiDeg, r.meanSinDphiErrorDeg, r.meanDthetaDeg,
                         r.meanDthetaErrorDeg, r.rmsDphiDeg, r.rmsDthetaDeg, r.irregularityDeg);
  }
  return table;
}

std::string residualsMarkdown(const std::vector<ResidualSample>& samples) {
  return "# Residuals of the selected e+e- → e+e- particles (θ_EMC 45°–135°)\n\n" + residualsTable(samples) +
         "\nsin Δφ and its means are shown as sin Δφ · 180/π; the φ irregularity is max − min of the "
         "mean sin Δφ of the 16 φ columns.\n";
}

namespace {

ResidualSample readSample(const StrictObject& o) {
  o.allowOnly({"name", "files", "events", "particles", "mean_sin_dphi_deg", "mean_sin_dphi_error_deg",
               "mean_dtheta_deg", "mean_dtheta_error_deg", "rms_dphi_deg", "rms_dtheta_deg",
               "phi_column_mean_sin_dphi_deg", "phi_irregularity_deg"});
  ResidualSample s;
  s.name = o.string("name");
  s.files = o.strings("files");
  ResidualSummary& r = s.summary;
  r.events = o.integer("events");
  r.particles = o.integer("particles");
  r.meanSinDphiDeg = o.numberOrNull("mean_sin_dphi_deg");
  r.meanSinDphiErrorDeg = o.numberOrNull("mean_sin_dphi_error_deg");
  r.meanDthetaDeg = o.numberOrNull("mean_dtheta_deg");
  r.meanDthetaErrorDeg = o.numberOrNull("mean_dtheta_error_deg");
  r.rmsDphiDeg = o.numberOrNull("rms_dphi_deg");
  r.rmsDthetaDeg = o.numberOrNull("rms_dtheta_deg");
  r.irregularityDeg = o.numberOrNull("phi_irregularity_deg");
  const Json& columns = o.array("phi_column_mean_sin_dphi_deg");
  if (columns.size() != r.columnMeanDeg.size()) {
    o.fail(o.pathOf("phi_column_mean_sin_dphi_deg"),
           fmt::format("expected {} columns, got {}", r.columnMeanDeg.size(), columns.size()));
  }
  for (std::size_t k = 0; k < columns.size(); ++k) {
    const Json& v = columns[k];
    if (!v.is_null() && !v.is_number()) {
      o.fail(fmt::format("{}[{}]", o.pathOf("phi_column_mean_sin_dphi_deg"), k), "expected a number or null");
    }
    r.columnMeanDeg[k] = v.is_null() ? std::numeric_limits<double>::quiet_NaN() : v.get<double>();
  }
  return s;
}

}  // namespace

Result<ResidualRecord> parseResiduals(const Json& j, std::string_view source) {
  return io::strict::guarded([&] {
    const StrictObject top(j, "", source);
    top.allowOnly({"software", "depth_offset_cm", "samples"});
    ResidualRecord record;
    record.software = top.string("software");
    record.depthOffsetCm = top.numberOrNull("depth_offset_cm");
    const Json& samples = top.array("samples");
    for (std::size_t k = 0; k < samples.size(); ++k) {
      record.samples.push_back(readSample(top.nested(samples[k], fmt::format("samples[{}]", k))));
    }
    return record;
  });
}

}  // namespace emcalign::apply
