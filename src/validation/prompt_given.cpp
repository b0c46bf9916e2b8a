// `prompt` and `prompt-thresholds` as given (validation/prompt_given.hpp).

#include "emcalign/validation/prompt_given.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/io/paths.hpp"

namespace emcalign::validation {

Status checkPromptPlaces(const PromptOptions& o) {
  if (io::isWithin(o.stateDir, o.watchDir) || io::isWithin(o.watchDir, o.stateDir)) {
    return Error{fmt::format(
        "-o {}: the state directory and the watched directory {} are one inside the other: the loop would take its "
        "own files; give them apart",
        o.stateDir, o.watchDir)};
  }
  const std::string dbFile = conddb::sqliteFileOf(o.conditions);
  if (!dbFile.empty() && io::isWithin(dbFile, o.watchDir)) {
    return Error{fmt::format("--conditions: the database {} is inside the watched directory {}: put it elsewhere",
                             dbFile, o.watchDir)};
  }
  return {};
}

std::string promptSummaryText(const PromptSummary& s) {
  return fmt::format("prompt: {} taken, {} quarantined, {} decided, {} sent", counted(s.filesTaken, "file"),
                     counted(s.quarantined, "file"), counted(s.decided, "group"), counted(s.alertsSent, "alert"));
}

Result<std::vector<MeasuredSpread>> measuredSpreads(const Table& table, const std::vector<std::string>& parameters,
                                                    const std::string& source) {
  std::vector<MeasuredSpread> spreads;
  for (const auto& row : table.rows) {
    const auto p = row.name.param();
    if (!p) continue;
    if (!parameters.empty() && std::find(parameters.begin(), parameters.end(), name(*p)) == parameters.end()) continue;
    // The error a fit quotes: the spread over the pulls' width (a pull is (fit − truth)/error).
    if (!(row.pullWidth > 0.0 && std::isfinite(row.pullWidth))) {
      return Error{fmt::format("{}: {}: the pulls' width {} is not a positive number: not a table of emcalign validate",
                               source, name(*p), row.pullWidth)};
    }
    spreads.push_back({*p, row.spread, row.spread / row.pullWidth});
  }
  for (const auto& wanted : parameters) {
    if (std::none_of(spreads.begin(), spreads.end(), [&](const auto& s) { return name(s.parameter) == wanted; })) {
      return Error{fmt::format("--parameters {}: not a parameter of the table {}", wanted, source)};
    }
  }
  return spreads;
}

std::string fewSamplesWarning(const Table& table, const std::string& source) {
  if (table.samples >= 20) return {};
  return fmt::format(
      "{}: {} samples: their spread is known to ±{:.0f} % only; a validation of 40 or more samples gives thresholds "
      "to trust",
      source, table.samples, 100.0 / std::sqrt(2.0 * std::max(table.samples - 1, 1)));
}

std::string thresholdsWrittenText(const Table& table, std::size_t parameters, double falseRate,
                                  const std::string& source, const std::string& output) {
  return fmt::format(
      "prompt-thresholds: {} from the spreads of {} ({} samples of {} events): min_change = {:.3g}·√2·spread (a "
      "false update rate of {:g} over them on a stable stretch, for groups of that size), significance 3, max_change "
      "10·min_change (set it from the detector's history), max_error 2·the error a fit quotes (spread/pull width) -> "
      "{}\n",
      counted(parameters, "parameter"), source, table.samples, table.events, falseUpdateQuantile(falseRate, parameters),
      falseRate, output);
}

}  // namespace emcalign::validation
