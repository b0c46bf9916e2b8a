#pragma once
// `emcalign prompt` and `prompt-thresholds` as their command lines give them (docs/prompt.md):
// where the loop's state and database may not be, the spreads a thresholds file is proposed
// from, and what the two commands say when they end.

#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/validation/campaign.hpp"
#include "emcalign/validation/prompt.hpp"
#include "emcalign/validation/prompt_decision.hpp"

namespace emcalign::validation {

/// The state directory and the watched directory are apart (neither inside the other: the
/// loop would take its own files), and an SQLite database is not inside the watched one.
Status checkPromptPlaces(const PromptOptions& options);

/// What a prompt loop did, in one line: the files taken and quarantined, the groups decided,
/// the alerts sent.
std::string promptSummaryText(const PromptSummary& summary);

/// The spread of each parameter of a validation table (`source`) and the error a fit quotes
/// (the spread over the pulls' width), for `parameters` (by name; none: all 12): a parameter
/// not in the table, or a width that is no positive number, is an error naming it.
Result<std::vector<MeasuredSpread>> measuredSpreads(const Table& table, const std::vector<std::string>& parameters,
                                                    const std::string& source);
/// A table of few samples gives rough spreads: said (empty for 20 samples or more).
std::string fewSamplesWarning(const Table& table, const std::string& source);
/// What `prompt-thresholds` wrote, and how the thresholds were made.
std::string thresholdsWrittenText(const Table& table, std::size_t parameters, double falseRate,
                                  const std::string& source, const std::string& output);

}  // namespace emcalign::validation
