#include "emcalign/apply/check_record.hpp"

#include <fmt/format.h>

#include "emcalign/io/strict_json.hpp"

namespace emcalign::apply {

namespace {

using io::Json;
using io::numberOrNull;
using io::strict::StrictObject;

// A distribution's core as a side writes it: "dphi_width_deg", "dphi_width_error_deg", …
constexpr std::array<std::string_view, 4> kWidthKeys = {"width", "width_error", "mean", "rms"};

std::string widthKey(std::string_view distribution, std::string_view what) {
  return fmt::format("{}_{}_deg", distribution, what);
}

void writeWidth(Json& side, const CheckWidth& w, std::string_view distribution) {
  const std::array<double, 4> values = {w.width, w.widthError, w.mean, w.rms};
  for (std::size_t k = 0; k < kWidthKeys.size(); ++k)
    side[widthKey(distribution, kWidthKeys[k])] = numberOrNull(values[k]);
}

CheckWidth readWidth(const StrictObject& side, std::string_view distribution) {
  std::array<double, 4> v{};
  for (std::size_t k = 0; k < kWidthKeys.size(); ++k)
    v[k] = side.numberOrNullIfGiven(widthKey(distribution, kWidthKeys[k]));
  return {.width = v[0], .widthError = v[1], .mean = v[2], .rms = v[3]};
}

Json sideJson(CheckProcess process, const CheckSide& s) {
  Json side = Json::object();
  if (process == CheckProcess::GammaGamma) {
    writeWidth(side, s.dphi, "dphi");
    writeWidth(side, s.dtheta, "dtheta");
    return side;
  }
  side["chi2_mean"] = numberOrNull(s.chi2Mean);
  side["chi2_median"] = numberOrNull(s.chi2Median);
  side["chi2_mean_below_20"] = numberOrNull(s.chi2MeanBelow20);
  side["fraction_above_20"] = numberOrNull(s.fractionAbove20);
  side["p_value_mean"] = numberOrNull(s.pValueMean);
  side["converged"] = s.converged;
  side["not_converged"] = s.notConverged;
  return side;
}

CheckSide readSide(CheckProcess process, const StrictObject& o) {
  CheckSide s;
  if (process == CheckProcess::GammaGamma) {
    s.dphi = readWidth(o, "dphi");
    s.dtheta = readWidth(o, "dtheta");
    return s;
  }
  s.chi2Mean = o.numberOrNullIfGiven("chi2_mean");
  s.chi2Median = o.numberOrNullIfGiven("chi2_median");
  s.chi2MeanBelow20 = o.numberOrNullIfGiven("chi2_mean_below_20");
  s.fractionAbove20 = o.numberOrNullIfGiven("fraction_above_20");
  s.pValueMean = o.numberOrNullIfGiven("p_value_mean");
  if (o.has("converged")) s.converged = o.integer("converged");
  if (o.has("not_converged")) s.notConverged = o.integer("not_converged");
  return s;
}

Json improvementJson(CheckProcess process, const CheckImprovement& i) {
  if (process == CheckProcess::GammaGamma) {
    return {{"dphi_width", numberOrNull(i.dphiWidth)},
            {"dphi_rms", numberOrNull(i.dphiRms)},
            {"dtheta_width", numberOrNull(i.dthetaWidth)},
            {"dtheta_rms", numberOrNull(i.dthetaRms)}};
  }
  return {{"chi2_mean", numberOrNull(i.chi2Mean)}, {"chi2_median", numberOrNull(i.chi2Median)}};
}

CheckImprovement readImprovement(const StrictObject& o) {
  return {.dphiWidth = o.numberOrNullIfGiven("dphi_width"),
          .dphiRms = o.numberOrNullIfGiven("dphi_rms"),
          .dthetaWidth = o.numberOrNullIfGiven("dtheta_width"),
          .dthetaRms = o.numberOrNullIfGiven("dtheta_rms"),
          .chi2Mean = o.numberOrNullIfGiven("chi2_mean"),
          .chi2Median = o.numberOrNullIfGiven("chi2_median")};
}

// The cut flow: "cut_order" the cuts in order, "cut_flow" each one's events.
CheckCutFlow readCutFlow(const StrictObject& top) {
  CheckCutFlow flow;
  const StrictObject counts = top.object("cut_flow");
  if (top.has("cut_order")) {
    flow.names = top.strings("cut_order");
  } else {
    for (const auto& [name, n] : top.at("cut_flow").items()) flow.names.push_back(name);
  }
  for (const auto& name : flow.names) flow.events.push_back(counts.integer(name));
  return flow;
}

}  // namespace

std::string CheckRecord::alignmentFile() const { return io::stringAt(alignment, "file").value_or(""); }
std::string CheckRecord::alignmentTag() const { return io::stringAt(alignment, "tag").value_or(""); }
std::string CheckRecord::alignmentConditions() const { return io::stringAt(alignment, "conditions").value_or(""); }

Json checkJson(const CheckRecord& r) {
  Json j = {{"process", name(r.process)}, {"selected", r.selected}};
  if (r.process == CheckProcess::ThreePion) j["ndf"] = r.ndf;
  j["cut_flow"] = r.cutFlow.json();
  j["cut_order"] = r.cutFlow.names;
  j["vertex"] = r.vertex;
  j["before"] = sideJson(r.process, r.before);
  j["after"] = sideJson(r.process, r.after);
  j["improvement_percent"] = improvementJson(r.process, r.improvement);
  if (!r.alignment.is_null()) j["alignment"] = r.alignment;
  if (!r.correctionMethod.empty()) j["correction_method"] = r.correctionMethod;
  if (!r.inputs.empty()) j["inputs"] = r.inputs;
  if (!r.software.empty()) j["software"] = r.software;
  return j;
}

Result<CheckRecord> parseCheckRecord(const Json& j, std::string_view source) {
  return io::strict::guarded([&] {
    const StrictObject top(j, "", source);
    CheckRecord r;
    const std::string process = top.string("process");
    const auto p = checkProcessFromName(process);
    if (!p) top.fail("process", fmt::format("unknown process '{}' (gg, 3pi)", process));
    r.process = *p;
    r.selected = top.integer("selected");
    if (top.has("ndf")) r.ndf = top.integer("ndf");
    r.cutFlow = readCutFlow(top);
    if (top.has("vertex")) r.vertex = top.string("vertex");
    r.before = readSide(r.process, top.object("before"));
    r.after = readSide(r.process, top.object("after"));
    r.improvement = readImprovement(top.object("improvement_percent"));
    if (top.has("alignment")) {
      (void)top.object("alignment");
      r.alignment = top.at("alignment");
    }
    if (top.has("correction_method")) r.correctionMethod = top.string("correction_method");
    if (top.has("inputs")) r.inputs = top.strings("inputs");
    if (top.has("software")) r.software = top.string("software");
    return r;
  });
}

}  // namespace emcalign::apply
