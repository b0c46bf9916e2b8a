#pragma once
// `conditions list` and `conditions diff` in words (docs/outputs.md), and the two small
// decisions of the conditions commands: a run range as typed, and a copy between databases.
// Text read from a database is printed escaped (core/utf8.hpp): it can hold anything.

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/conddb/tag_tables.hpp"
#include "emcalign/core/result.hpp"

namespace emcalign::conddb {

/// Every tag, one line each: state, IOVs, runs, model, σ_sys, description; `uri` and `at`
/// (a snapshot time, "" for now) head it when `at` is given.
std::string tagsText(const std::vector<TagListing>& tags, const std::string& uri, const std::string& at);
/// One tag and its IOVs (events, χ²/ndf, the χ² of the statistical errors alone, status, payload).
std::string tagText(const TagListing& tag, const std::string& at);
/// Tag A against tag B: their models and σ_sys, a row per overlapping pair of IOVs with each
/// parameter's z (cut toward zero to two decimals, those of 3σ or more marked and counted),
/// the runs one tag alone covers.
std::string tagDiffText(const TagDiff& d, const std::string& uri, const std::string& at);

/// "FIRST-LAST" or "RUN" of `--runs` (runs are integers ≥ 0, the first not after the last).
Result<std::pair<std::int64_t, std::int64_t>> parseRunRange(const std::string& text);

/// A tag of the database `fromUri` copied into `toUri` (created if a new SQLite file, removed
/// again if the copy fails before storing) as `as`; the source read first. One SQLite file under
/// two names (a hard link) is opened by the source's name: SQLite would keep two write-ahead logs.
struct TagCopy {
  CopiedTag copied;
  std::string from, to;  ///< the databases as shown
};
Result<TagCopy> copyTagBetween(const std::string& fromUri, const std::string& tag, const std::string& toUri,
                               const std::string& as, const std::string& at);

}  // namespace emcalign::conddb
