#include <cmath>

#include <fmt/format.h>

#include "emcalign/apply/mc_comparison.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/strict_json.hpp"

namespace emcalign::apply {

namespace {

using io::Json;
using io::strict::StrictObject;

// Δφ and Δθ are histograms (bins with edges in degrees); the others profiles (bin indices).
bool isHistogram(std::string_view name) { return name == "dphi" || name == "dtheta"; }

ComparedDistribution::Bin readBin(const StrictObject& b, bool histogram, int& thetaBins) {
  ComparedDistribution::Bin bin{.data = b.numberOrNull("data"),
                                .dataError = b.numberOrNull("data_error"),
                                .mc = b.numberOrNull("mc"),
                                .mcError = b.numberOrNull("mc_error"),
                                .pull = b.numberOrNull("pull")};
  if (histogram) {
    bin.low = b.numberOrNull("low_deg");
    bin.high = b.numberOrNull("high_deg");
    return bin;
  }
  const std::int64_t index = b.integer("bin"), iPhi = b.integer("i_phi"), iTheta = b.integer("i_theta");
  if (iPhi > 0) thetaBins = static_cast<int>((index - iTheta) / iPhi);  // the file's profile grid
  bin.low = bin.high = static_cast<double>(index);
  return bin;
}

ComparedDistribution readDistribution(const StrictObject& d, int& thetaBins) {
  ComparedDistribution out{.name = d.string("name"),
                           .chi2 = d.numberOrNull("chi2"),
                           .ndf = static_cast<int>(d.integer("ndf")),
                           .pValue = d.numberOrNull("p_value")};
  const bool histogram = isHistogram(out.name);
  const Json& bins = d.array("bins");
  for (std::size_t k = 0; k < bins.size(); ++k) {
    out.bins.push_back(readBin(d.nested(bins[k], fmt::format("{}[{}]", d.pathOf("bins"), k)), histogram, thetaBins));
  }
  return out;
}

ComparisonOptions readOptions(const StrictObject& o) {
  ComparisonOptions out;
  out.histogramBins = static_cast<int>(o.integer("histogram_bins"));
  out.rangeDeg = o.number("range_deg");
  out.phiCentreDeg = o.numberOrNull("dphi_centre_deg");
  out.thetaCentreDeg = o.numberOrNull("dtheta_centre_deg");
  out.minEntries = o.integer("min_entries");
  out.sigmaSys = o.number("sigma_sys_deg") * units::deg;
  return out;
}

}  // namespace

Json comparisonJson(const ComparisonRecord& record) {
  const Comparison& c = record.comparison;
  Json distributions = Json::array();
  for (const auto& d : c.distributions) {
    Json bins = Json::array();
    const bool histogram = isHistogram(d.name);
    for (const auto& b : d.bins) {
      Json j = histogram ? Json{{"low_deg", std::isfinite(b.low) ? Json(b.low) : Json()},
                                {"high_deg", std::isfinite(b.high) ? Json(b.high) : Json()}}
                         : Json{{"bin", static_cast<int>(b.low)},
                                {"i_phi", static_cast<int>(b.low) / c.options.profileThetaBins},
                                {"i_theta", static_cast<int>(b.low) % c.options.profileThetaBins}};
      j["data"] = b.data;
      j["data_error"] = b.dataError;
      j["mc"] = b.mc;
      j["mc_error"] = b.mcError;
      j["pull"] = b.pull;
      bins.push_back(std::move(j));
    }
    distributions.push_back({{"name", d.name},
                             {"chi2", d.chi2},
                             {"ndf", d.ndf},
                             {"p_value", d.pValue},
                             {"unit", histogram ? "fraction of the particles" : "deg"},
                             {"bins", bins}});
  }
  Json j = {{"format", kComparisonFormat},
            {"p_value", c.pValue},
            {"chi2", c.chi2},
            {"ndf", c.ndf},
            {"distributions", distributions},
            {"data", {{"events", c.dataEvents}, {"particles", c.dataParticles}}},
            {"mc", {{"events", c.mcEvents}, {"particles", c.mcParticles}}},
            {"options",
             {{"histogram_bins", c.options.histogramBins},
              {"range_deg", c.options.rangeDeg},
              {"dphi_centre_deg", c.options.phiCentreDeg},
              {"dtheta_centre_deg", c.options.thetaCentreDeg},
              {"min_entries", c.options.minEntries},
              {"sigma_sys_deg", c.options.sigmaSys / units::deg}}},
            {"method",
             "chi2 of the difference with the covariance of both samples from the events' influences (two particles "
             "of an event, y_phi-y_theta, the histograms' normalisation), over its rank"}};
  for (const auto& [key, events, energies] : {std::tuple{"data", c.dataSelectedEvents, &c.dataBeamEnergiesMev},
                                              std::tuple{"mc", c.mcSelectedEvents, &c.mcBeamEnergiesMev}}) {
    if (events > 0) j[key]["selected_events"] = events;
    if (!energies->empty()) j[key]["beam_energies_mev"] = *energies;
  }
  if (!c.emptyThetaSlices.empty()) j["empty_theta_slices"] = c.emptyThetaSlices;
  if (!record.dataFiles.empty()) j["data"]["files"] = record.dataFiles;
  if (!record.mcFiles.empty()) j["mc"]["files"] = record.mcFiles;
  if (!record.software.empty()) j["software"] = record.software;
  if (record.depthOffsetCm) j["depth_offset_cm"] = *record.depthOffsetCm;
  return j;
}

Result<ComparisonRecord> parseComparison(const Json& j, std::string_view source) {
  return io::strict::guarded([&] {
    const StrictObject top(j, "", source);
    if (top.string("format") != kComparisonFormat)
      top.fail("format", fmt::format("expected \"{}\"", kComparisonFormat));
    ComparisonRecord r;
    Comparison& c = r.comparison;
    c.pValue = top.numberOrNull("p_value");
    c.chi2 = top.numberOrNull("chi2");
    c.ndf = static_cast<int>(top.integer("ndf"));
    int thetaBins = c.options.profileThetaBins;
    const Json& distributions = top.array("distributions");
    for (std::size_t k = 0; k < distributions.size(); ++k) {
      c.distributions.push_back(
          readDistribution(top.nested(distributions[k], fmt::format("distributions[{}]", k)), thetaBins));
    }
    const StrictObject data = top.object("data"), mc = top.object("mc");
    c.dataEvents = data.integer("events");
    c.dataParticles = data.integer("particles");
    c.mcEvents = mc.integer("events");
    c.mcParticles = mc.integer("particles");
    if (data.has("files")) r.dataFiles = data.strings("files");
    if (data.has("selected_events")) c.dataSelectedEvents = data.integer("selected_events");
    if (mc.has("selected_events")) c.mcSelectedEvents = mc.integer("selected_events");
    if (data.has("beam_energies_mev")) c.dataBeamEnergiesMev = data.numbers("beam_energies_mev");
    if (mc.has("beam_energies_mev")) c.mcBeamEnergiesMev = mc.numbers("beam_energies_mev");
    if (mc.has("files")) r.mcFiles = mc.strings("files");
    c.options = readOptions(top.object("options"));
    c.options.profileThetaBins = thetaBins;
    if (top.has("software")) r.software = top.string("software");
    if (top.has("depth_offset_cm")) r.depthOffsetCm = top.number("depth_offset_cm");
    return r;
  });
}

}  // namespace emcalign::apply
