#pragma once
// Two tools conditions-database users expect (CMS conddb's diff and list, Belle II
// b2conditionsdb's iov listing): a tag compared with another IOV by IOV, parameter by
// parameter in σ, and a tag as a table of one row per IOV.

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::conddb {

/// Payload::values of an IOV's payload; fails naming the IOV when one of the 12 parameters is
/// missing.
Result<StoredValues> storedValues(const Payload& payload, const Iov& iov, const std::string& tag);

/// Where the IOVs of two tags overlap: the runs both cover with one IOV each.
struct IovPair {
  std::int64_t firstRun = 0, lastRun = 0;  ///< the overlap
  Iov a, b;
  StoredValues valuesA, valuesB;
  /// (a − b)/√(σa² + σb²) of each entry (NaN without errors); ψ and τ modulo 360°.
  std::vector<double> z;
  calib::ModelIdentity modelA, modelB;  ///< Payload::modelIdentity of each
  [[nodiscard]] bool samePayload() const { return a.payload == b.payload; }
};

struct TagDiff {
  std::string tagA, tagB;
  std::vector<IovPair> pairs;
  /// Runs of one tag that the other does not cover: (first, last) of each stretch.
  std::vector<std::pair<std::int64_t, std::int64_t>> onlyA, onlyB;
  /// What each IOV of each tag says (its σ_sys, model, …), as `conditions list` shows it.
  std::vector<IovListing> listingA, listingB;
};

/// The models of the overlapping IOVs of two tags (`conditions diff`): each side's in words
/// ("not said" where a payload does not say; " | " between several), whether they are the same
/// models, and whether the paper's model is on one side only.
struct ModelComparison {
  std::string a, b;
  bool same = true;
  bool paperOnOneSide = false;
};
ModelComparison compareModels(const TagDiff& d);

/// Tag `a` against tag `b` of the same database (as they were at `at`, "" for now).
Result<TagDiff> diffTags(Database& db, const std::string& a, const std::string& b, const std::string& at = {});
/// {"tag_a", "tag_b", "pairs": [{"first_run", "last_run", "iov_a", "iov_b", "same_payload", "model_a", "model_b",
/// "parameters": {name: {"a", "error_a", "b", "error_b", "difference", "z", "unit"}}}],
/// "only_a", "only_b"}.
io::Json tagDiffJson(const TagDiff& d);
/// tagDiffJson(d).dump(2), byte for byte, written piece by piece (one pair at a time: the diff
/// of two tags of 10 000 IOVs is 80 MB of JSON, never held whole).
void writeTagDiffJson(const TagDiff& d, const std::function<void(std::string_view)>& out);

/// A tag as CSV, one row per IOV: first_run, last_run, payload, inserted, status, chi2, ndf,
/// chi2_statistical_errors, sigma_sys_method, selected_events, then each of the 17 entries
/// and its error (`alpha`, `alpha_error`, …; unit in the header's comment line).
/// `at`: as it was then ("" for now; said in the first line).
Result<std::string> tagCsv(Database& db, const std::string& tag, const std::string& at = {});

}  // namespace emcalign::conddb
