// What a systematic study writes (validation/systematics.hpp): systematics.json, systematics.md
// and its heat map, and the systematic errors a corrections file carries from it.

#include <cmath>
#include <filesystem>
#include <limits>

#include <fmt/format.h>

#include "emcalign/core/paper.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/report/systematics_plot.hpp"
#include "emcalign/validation/systematics.hpp"
#include "systematics_internal.hpp"

namespace emcalign::validation {

namespace fs = std::filesystem;
using io::Json;

namespace {

// ψ and τ (isDirection), the directions of tilts drawn near zero: their error depends on the
// tilt, so they have no systematic error of their own to carry or draw.

// The heat map of the study (report/systematics_plot.hpp).
Status drawSystematics(const SystematicsTable& t, const std::string& dir) {
  report::SystematicsFigure f;
  f.title = "Systematic shifts: the simulation varied";
  f.subtitle = fmt::format("{} × {}; cells: shift / spread of the nominal fits", counted(t.samples, "paired sample"),
                           counted(t.events, "event"));
  std::vector<const SystematicsRow*> shown;
  for (const auto& r : t.rows) {
    if (r.name.isDirection()) continue;
    shown.push_back(&r);
    f.parameters.emplace_back(r.name.name());
  }
  const auto cellsOf = [&](const auto& value) {
    std::vector<double> cells;
    cells.reserve(shown.size());
    for (const SystematicsRow* r : shown) {
      cells.push_back(r->spread > 0.0 ? value(*r) / r->spread : std::numeric_limits<double>::quiet_NaN());
    }
    return cells;
  };
  for (std::size_t j = 0; j < t.variations.size(); ++j) {
    f.rows.push_back(t.variations[j]->name);
    f.cells.push_back(cellsOf([&](const SystematicsRow& r) { return r.shift[j]; }));
  }
  for (std::size_t q = 0; q < t.quantities.size(); ++q) {
    f.rows.push_back("effect of " + t.quantities[q]);
    f.cells.push_back(cellsOf([&](const SystematicsRow& r) { return r.envelope[q]; }));
  }
  f.rows.push_back("systematic");
  f.cells.push_back(cellsOf([](const SystematicsRow& r) { return r.systematic; }));
  if (!t.reverse.is_null()) {
    for (std::size_t j = 0; j < t.variations.size(); ++j) {
      f.reverseRows.push_back(t.variations[j]->name);
      f.reverseCells.push_back(cellsOf([&](const SystematicsRow& r) { return r.reverseShift[j]; }));
    }
  }
  auto written = report::writeSystematicsPlot((fs::path(dir) / "plots").string(), f);
  if (!written) return written.error();
  return {};
}

}  // namespace

// DIR/systematics.json, DIR/systematics.md and the figure.
Status writeSystematics(const SystematicsTable& t, const std::string& dir) {
  if (Status s = io::writeFileIn(dir, "systematics.json", systematicsJson(t).dump(2) + "\n"); !s) return s;
  if (Status s = io::writeFileIn(dir, "systematics.md", systematicsMarkdown(t)); !s) return s;
  if (Status s = drawSystematics(t, dir); !s) return s;
  if (t.reverse.is_null()) {  // a study run again without --reverse: no stale data beside its figure
    std::error_code ec;
    fs::remove(fs::path(dir) / "plots" / "systematics_reverse.dat", ec);
  }
  return {};
}

Json systematicsJson(const SystematicsTable& t) {
  Json variationsJson = Json::array();
  for (const Variation* v : t.variations) {
    variationsJson.push_back({{"name", v->name},
                              {"quantity", v->quantity},
                              {"change", v->change},
                              {"why", v->why},
                              {"pattern", v->pattern != nullptr}});
  }
  Json parameters = Json::object();
  for (const auto& r : t.rows) {
    Json shifts = Json::object(), effects = Json::object(), envelopes = Json::object();
    for (std::size_t j = 0; j < t.variations.size(); ++j) {
      shifts[t.variations[j]->name] = {r.shift[j], r.shiftError[j], r.shiftSpread[j]};
      effects[t.variations[j]->name] = r.effect[j];
    }
    for (std::size_t q = 0; q < t.quantities.size(); ++q) envelopes[t.quantities[q]] = r.envelope[q];
    Json p = {{"unit", r.name.unit()}, {"bias", r.bias},   {"bias_error", r.biasError},
              {"spread", r.spread},    {"shifts", shifts}, {"effects", effects}};
    if (!t.reverse.is_null()) {
      Json reverse = Json::object();
      for (std::size_t j = 0; j < t.variations.size(); ++j) {
        reverse[t.variations[j]->name] = {r.reverseShift[j], r.reverseShiftError[j]};
      }
      p["reverse_bias"] = {r.reverseBias, r.reverseBiasError};
      p["reverse_shifts"] = reverse;
    }
    p["envelopes"] = envelopes;
    p["systematic"] = r.systematic;
    parameters[std::string(r.name.name())] = p;
  }
  return {{"samples", t.samples},
          {"events", t.events},
          {"variations", variationsJson},
          {"reverse", t.reverse},
          {"parameters", parameters}};
}

std::string systematicsMarkdown(const SystematicsTable& t) {
  std::string md = fmt::format(
      "# Systematic shifts: {} × {} per variation\n\n"
      "Each quantity's column: the largest effect of its variations (file units): |mean of fit(variation) − "
      "fit(nominal)|, or for a pattern drawn per sample (gains, dead counters) the root mean square of the "
      "differences{}. systematic = their quadrature sum. Nominal bias ± its statistical error, and the spread of "
      "the fits, beside the paper's Table 1 bias.\n\n| parameter | unit | nominal bias | spread |",
      counted(t.samples, "paired sample"), counted(t.events, "event"),
      t.reverse.is_null() ? "" : "; the reverse shifts count too");
  for (const auto& q : t.quantities) md += fmt::format(" {} |", q);
  md += " **systematic** | paper bias |\n|---|---|---|---|";
  for (std::size_t q = 0; q < t.quantities.size(); ++q) md += "---|";
  md += "---|---|\n";
  for (const auto& r : t.rows) {
    md += fmt::format("| {} | {} | {:.4f} ± {:.4f} | {:.4f} |", r.name, r.name.unit(), r.bias, r.biasError, r.spread);
    for (double e : r.envelope) md += fmt::format(" {:.4f} |", e);
    const auto* p = paper::table1(r.name.name());
    md += fmt::format(" **{:.4f}** | {} |\n", r.systematic, p ? fmt::format("{:.3g}", p->bias) : std::string());
  }
  const auto shiftTable = [&](const std::string& heading, const auto& cell) {
    md += heading + "\n\n| parameter |";
    for (const Variation* v : t.variations) md += fmt::format(" {} |", v->name);
    md += "\n|---|";
    for (std::size_t j = 0; j < t.variations.size(); ++j) md += "---|";
    md += "\n";
    for (const auto& r : t.rows) {
      md += fmt::format("| {} |", r.name);
      for (std::size_t j = 0; j < t.variations.size(); ++j) md += fmt::format(" {} |", cell(r, j));
      md += "\n";
    }
  };
  shiftTable(
      "\nEvery shift with its statistical error (mean ± error of the paired differences; a pattern's root mean "
      "square after the slash):",
      [&](const SystematicsRow& r, std::size_t j) {
        return t.variations[j]->pattern != nullptr
                   ? fmt::format("{:+.4f} ± {:.4f} / {:.4f}", r.shift[j], r.shiftError[j], r.effect[j])
                   : fmt::format("{:+.4f} ± {:.4f}", r.shift[j], r.shiftError[j]);
      });
  if (!t.reverse.is_null()) {
    shiftTable(
        fmt::format("\nThe reverse study: corrections derived with each variation ({} events per derivation "
                    "sample, {} response samples × {} events, seed {}), fitted to the nominal samples; mean "
                    "± error of fit(its corrections) − fit(corrections derived without variation):",
                    t.reverse.value("events_per_sample", std::int64_t{0}), t.reverse.value("response_samples", 0),
                    t.reverse.value("response_events_per_sample", std::int64_t{0}),
                    t.reverse.value("seed", std::uint64_t{0})),
        [&](const SystematicsRow& r, std::size_t j) {
          return fmt::format("{:+.4f} ± {:.4f}", r.reverseShift[j], r.reverseShiftError[j]);
        });
    md += "\nThe nominal samples fitted with the corrections derived without variation: bias ± error\n\n";
    for (const auto& r : t.rows) {
      md += fmt::format("- {}: {:+.4f} ± {:.4f} {}\n", r.name, r.reverseBias, r.reverseBiasError, r.name.unit());
    }
  }
  return md;
}

Json systematicErrorsJson(const SystematicsTable& t, const calib::ModelCorrections& corrections, const Json& study) {
  // The derivation's own statistics are a systematic error of every fit with the file too
  // (validation/derive_corrections.hpp): added in quadrature, where the file records them.
  std::vector<std::pair<std::string, const Json*>> statistics;
  for (const char* key : {"response_parameter_errors", "nominal_profile_parameter_errors"}) {
    if (corrections.derivedFrom.is_object() && corrections.derivedFrom.contains(key) &&
        corrections.derivedFrom[key].is_object()) {
      statistics.emplace_back(key, &corrections.derivedFrom[key]);
    }
  }
  Json errors = Json::object(), variationsPart = Json::object();
  Json statisticsPart = Json::object();
  for (const auto& r : t.rows) {
    if (r.name.isDirection()) continue;
    const std::string name(r.name.name());
    variationsPart[name] = r.systematic;
    double sum2 = r.systematic * r.systematic;
    for (const auto& [key, values] : statistics) {
      if (!values->contains(name) || !(*values)[name].is_number()) continue;
      const double e = (*values)[name].get<double>();
      statisticsPart[key][name] = e;
      sum2 += e * e;
    }
    errors[name] = std::sqrt(sum2);
  }
  Json components = {{"simulation variations", variationsPart}};
  for (const auto& [key, values] : statisticsPart.items()) components["derivation statistics: " + key] = values;
  return {{"errors", errors}, {"components", components}, {"study", study}};
}

Status studyMatchesItsCorrections(const CampaignOptions& campaign, const std::string& name) {
  const Json& settings = campaign.settings;
  const auto flag = [&](const char* key) { return settings.contains(key) && settings[key] == true; };
  if (flag("ideal") || flag("point_showers") ||
      (settings.contains("off") && settings["off"].is_array() && !settings["off"].empty())) {
    return Error{
        "the errors a corrections file carries are measured with the realistic simulation (no --ideal, "
        "--point-showers or --off)"};
  }
  const calib::ModelCorrections& c = campaign.corrections;
  const double energy = campaign.simulation.generator.beamEnergy;
  if (!std::isnan(c.beamEnergy) && std::abs(c.beamEnergy - energy) > 1e-9 * energy) {
    return Error{fmt::format(
        "{} was derived at {} MeV, the study would run at {} MeV: its errors are measured at its own energy "
        "(--beam-energy {})",
        name, c.beamEnergy / units::MeV, energy / units::MeV, c.beamEnergy / units::MeV)};
  }
  const Json derived = c.derivedFrom.is_object() ? c.derivedFrom.value("settings", Json()) : Json();
  const Json study = {campaign.simulation.generator.thetaMin / units::deg,
                      campaign.simulation.generator.thetaMax / units::deg};
  const Json& given = settings.contains("theta_range_deg") ? settings["theta_range_deg"] : study;
  if (derived.is_object() && derived.contains("theta_range_deg") && derived["theta_range_deg"] != given) {
    return Error{fmt::format(
        "{} was derived for the polar range {} deg, the study's is [{}, {}]: give --theta-min and --theta-max as "
        "it was derived",
        name, derived["theta_range_deg"].dump(), given[0].get<double>(), given[1].get<double>())};
  }
  return {};
}

Result<calib::ModelCorrections> correctionsWithSystematics(const SystematicsTable& table,
                                                           const CampaignOptions& campaign,
                                                           const std::string& destination) {
  calib::ModelCorrections corrections = campaign.corrections;
  Json conditions = campaign.settings;  // the simulation, ranges, σ_sys and detector of the study
  conditions.erase("corrections");
  conditions["beam_energy_mev"] = campaign.simulation.generator.beamEnergy / units::MeV;
  std::vector<std::string> names;
  for (const auto* v : table.variations) names.push_back(v->name);
  const Json study = {{"command", "emcalign systematics"},
                      {"software", fmt::format("emcalign {}", kVersion)},
                      {"samples", table.samples},
                      {"events", table.events},
                      {"seed", campaign.seed},
                      {"conditions", conditions},
                      {"variations", names},
                      {"reverse", table.reverse},
                      {"combination", kSystematicsCombination},
                      {"corrections_fnv1a", calib::correctionsDigest(corrections)}};
  auto systematics = calib::parseSystematicErrors(systematicErrorsJson(table, corrections, study), destination);
  if (!systematics) return systematics.error();
  corrections.systematics = std::make_shared<const calib::SystematicErrors>(std::move(*systematics));
  return corrections;
}

}  // namespace emcalign::validation
