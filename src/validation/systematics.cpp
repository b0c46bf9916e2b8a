#include "emcalign/validation/systematics.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/core/paper.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::validation {

namespace {

namespace fs = std::filesystem;
using io::Json;

// Sample i of a varied campaign against sample i of the nominal one: as a "truth" the
// nominal fit, so that tabulate's bias is the mean of fit(variation) − fit(nominal), its
// error their spread/√n, with ψ and τ by the shortest angle and the derived parameters
// against the nominal fit's (the same conversion).
std::vector<SampleResult> pairedWithNominal(const std::vector<SampleResult>& varied,
                                            const std::vector<SampleResult>& nominal) {
  std::vector<SampleResult> out;
  for (std::size_t i = 0; i < varied.size() && i < nominal.size(); ++i) {
    SampleResult s = varied[i];
    s.truth = nominal[i].fit.parameters;
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace

CampaignOptions withVariation(CampaignOptions options, const Variation& variation) {
  variation.apply(options.simulation);
  options.settings["variation"] = variation.name;
  return options;
}

Result<SystematicsTable> runSystematics(const geometry::Calorimeter& calo, const SystematicsOptions& options,
                                        const std::string& dir, const SystematicsProgress& progress) {
  SystematicsTable t;
  t.variations = options.variations;
  if (t.variations.empty()) {
    for (const auto& v : variations()) t.variations.push_back(&v);
  }
  const CampaignOptions& nominalOptions = options.campaign;
  t.samples = nominalOptions.samples;
  t.events = nominalOptions.events;
  const int total = nominalOptions.samples * static_cast<int>(t.variations.size() + 1);
  int campaignsDone = 0;
  const auto progressOf = [&](int done, int) {
    if (progress) progress(campaignsDone * nominalOptions.samples + done, total);
  };
  std::vector<SampleResult> nominal;
  auto nominalTable = runCampaign(calo, nominalOptions, (fs::path(dir) / "nominal").string(), progressOf, &nominal);
  if (!nominalTable) return Error{fmt::format("the nominal campaign: {}", nominalTable.error().message)};
  ++campaignsDone;
  const double r1 = calo.description().r1();
  std::vector<Table> shifts;
  for (const Variation* v : t.variations) {
    const CampaignOptions o = withVariation(nominalOptions, *v);
    std::vector<SampleResult> varied;
    auto table = runCampaign(calo, o, (fs::path(dir) / v->name).string(), progressOf, &varied);
    if (!table) return Error{fmt::format("variation {}: {}", v->name, table.error().message)};
    ++campaignsDone;
    shifts.push_back(tabulate(pairedWithNominal(varied, nominal), o.events, r1));
    if (std::find(t.quantities.begin(), t.quantities.end(), v->quantity) == t.quantities.end()) {
      t.quantities.push_back(v->quantity);
    }
  }
  for (std::size_t k = 0; k < nominalTable->rows.size(); ++k) {
    const TableRow& n = nominalTable->rows[k];
    SystematicsRow row{n.name, n.unit, n.bias, n.biasError, n.spread, {}, {}, {}, 0.0};
    row.envelope.assign(t.quantities.size(), 0.0);
    for (std::size_t j = 0; j < t.variations.size(); ++j) {
      const TableRow& s = shifts[j].rows[k];
      row.shift.push_back(s.bias);
      row.shiftError.push_back(s.biasError);
      const auto q = static_cast<std::size_t>(
          std::find(t.quantities.begin(), t.quantities.end(), t.variations[j]->quantity) - t.quantities.begin());
      row.envelope[q] = std::max(row.envelope[q], std::abs(s.bias));
    }
    double sum2 = 0.0;
    for (double e : row.envelope) sum2 += e * e;
    row.systematic = std::sqrt(sum2);
    t.rows.push_back(std::move(row));
  }
  if (Status s = io::writeOutputFile((fs::path(dir) / "systematics.json").string(), systematicsJson(t).dump(2) + "\n");
      !s) {
    return s.error();
  }
  if (Status s = io::writeOutputFile((fs::path(dir) / "systematics.md").string(), systematicsMarkdown(t)); !s) {
    return s.error();
  }
  return t;
}

Json systematicsJson(const SystematicsTable& t) {
  Json variationsJson = Json::array();
  for (const Variation* v : t.variations) {
    variationsJson.push_back({{"name", v->name}, {"quantity", v->quantity}, {"change", v->change}, {"why", v->why}});
  }
  Json parameters = Json::object();
  for (const auto& r : t.rows) {
    Json shifts = Json::object(), envelopes = Json::object();
    for (std::size_t j = 0; j < t.variations.size(); ++j) {
      shifts[t.variations[j]->name] = {r.shift[j], r.shiftError[j]};
    }
    for (std::size_t q = 0; q < t.quantities.size(); ++q) envelopes[t.quantities[q]] = r.envelope[q];
    parameters[r.name] = {
        {"unit", r.unit},   {"bias", r.bias},         {"bias_error", r.biasError}, {"spread", r.spread},
        {"shifts", shifts}, {"envelopes", envelopes}, {"systematic", r.systematic}};
  }
  return {{"samples", t.samples}, {"events", t.events}, {"variations", variationsJson}, {"parameters", parameters}};
}

std::string systematicsMarkdown(const SystematicsTable& t) {
  std::string md = fmt::format(
      "# Systematic shifts: {} paired samples × {} events per variation\n\n"
      "Each column: the larger |mean of fit(variation) − fit(nominal)| of the quantity's variations (file units). "
      "systematic = their quadrature sum. Nominal bias ± its statistical error, and the spread of the fits, "
      "beside the paper's Table 1 bias (SPEC §10).\n\n| parameter | unit | nominal bias | spread |",
      t.samples, t.events);
  for (const auto& q : t.quantities) md += fmt::format(" {} |", q);
  md += " **systematic** | paper bias |\n|---|---|---|---|";
  for (std::size_t q = 0; q < t.quantities.size(); ++q) md += "---|";
  md += "---|---|\n";
  for (const auto& r : t.rows) {
    md += fmt::format("| {} | {} | {:.4f} ± {:.4f} | {:.4f} |", r.name, r.unit, r.bias, r.biasError, r.spread);
    for (double e : r.envelope) md += fmt::format(" {:.4f} |", e);
    const auto* p = paper::table1(r.name);
    md += fmt::format(" **{:.4f}** | {} |\n", r.systematic, p ? fmt::format("{:.3g}", p->bias) : std::string());
  }
  md += "\nEvery shift with its statistical error (mean ± error of the paired differences):\n\n| parameter |";
  for (const Variation* v : t.variations) md += fmt::format(" {} |", v->name);
  md += "\n|---|";
  for (std::size_t j = 0; j < t.variations.size(); ++j) md += "---|";
  md += "\n";
  for (const auto& r : t.rows) {
    md += fmt::format("| {} |", r.name);
    for (std::size_t j = 0; j < t.variations.size(); ++j) {
      md += fmt::format(" {:+.4f} ± {:.4f} |", r.shift[j], r.shiftError[j]);
    }
    md += "\n";
  }
  return md;
}

}  // namespace emcalign::validation
