#pragma once
// The conditions database as its users work with it (the command line, the Python module):
// a fit result stored for a run range with its provenance, the parameter file valid for a
// run, the tags as JSON, and the alignment of each run for correcting or simulating run by
// run (conddb/conditions.hpp is the database itself).

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "emcalign/apply/correct.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::conddb {

/// What putResultFile did.
struct PutReport {
  bool newTag = false;                ///< the tag was created
  std::string payload;                ///< the payload's hash
  std::vector<std::string> warnings;  ///< inputs of the result whose digest is not recorded
};

/// A result file to store, and where.
struct ResultFileToPut {
  std::string tag;
  std::int64_t firstRun = 0, lastRun = 0;  ///< inclusive
  std::string path;                        ///< the fit result or parameter file
  std::string description;                 ///< of the tag, when it is created
  double r1 = 0.0;                         ///< the detector's, for the physical set (native length)
};

/// Stores a fit result or a parameter file for runs [firstRun, lastRun] of its tag (created,
/// open, with its description when new). The payload's provenance records the file's SHA-256,
/// this software, and the SHA-256 of each input file the result names, found as named or
/// beside the result (one not found is a warning).
Result<PutReport> putResultFile(Database& db, const ResultFileToPut& file);

/// The parameter file of a payload (docs/contract.md §3), with where it came from under "input":
/// {"conditions": URI, "tag", "snapshot" (when read at one), "first_run", "last_run", "payload",
/// "inserted", "selected_events", "provenance"}.
io::Json parameterFileOf(const Iov& iov, const Payload& payload, const std::string& uri, const std::string& tag,
                         const std::string& at = {});

struct RunCalibration {
  Iov iov;
  io::Json parameterFile;  ///< parameterFileOf
};
/// What putWholeTag did.
enum class WholeTagPut { Stored, HeldAlready };
/// Writes a new tag whole: `iovs` and its state (open, or testing for a refit to be checked)
/// in one transaction, with `description`. A tag that holds exactly these IOVs (the same runs,
/// the same payloads) is left as it is: a job that writes a whole tag (a refit) and finds it
/// written, by its own earlier run or by a copy of it that stored it first, has nothing to do.
/// A tag that exists with anything else is an error (write to a new tag).
Result<WholeTagPut> putWholeTag(Database& db, const std::string& tag, const std::vector<Database::NewIov>& iovs,
                                const std::string& description, TagState state = TagState::Open);

/// The calibration valid for `run` (at the snapshot time `at`, "" for now); the error says
/// whether the tag or the IOV is missing.
Result<RunCalibration> calibrationAt(Database& db, const std::string& tag, std::int64_t run,
                                     const std::string& at = {});

/// A tag copied into another database (or the same one under another name) in one
/// transaction, in its state, as it is (or was at `at`); its history there starts with a
/// "copy" naming the original. Refused for an invalid tag, or a name taken in the target.
struct CopiedTag {
  std::size_t iovs = 0;
  TagState state = TagState::Open;
};
Result<CopiedTag> copyTag(Database& from, const std::string& tag, Database& to, const std::string& as,
                          const std::string& at = {});

/// An IOV as `conditions list` shows it: its runs and payload, and what the payload's fit
/// says (absent where the payload does not say it, or not as a fit result writes it: a
/// database can hold anything; a null χ² is NaN).
struct IovListing {
  Iov iov;
  std::optional<std::string> status = {};
  std::optional<double> chi2 = {};
  std::optional<std::int64_t> ndf = {};
  std::optional<std::string> sigmaSysMethod = {};
  /// With σ_sys auto χ²/ndf is 1 by construction: the χ² with the statistical errors alone is
  /// what tells one IOV from another.
  std::optional<double> chi2Statistical = {};
  std::optional<double> sigmaSysDeg = {};
  std::optional<std::int64_t> selectedEvents = {};
  calib::ModelIdentity model = {};  ///< Payload::modelIdentity
};

/// What an IOV's payload says (`conditions list`, `conditions export`).
IovListing iovListing(const Iov& iov, const Payload& payload);

/// The σ_sys of IOVs in a few words: "auto (0.012-0.015 deg)", "0.2 deg", "mixed (…): …", or
/// "-" when the payloads do not say.
std::string sigmaSysSummary(const std::vector<IovListing>& iovs);
/// The model of IOVs (Payload::modelIdentity): "paper's model", the corrections' file name,
/// "mixed" when they differ, "-" when the payloads do not say; not `brief`: in full (text()).
std::string modelSummary(const std::vector<IovListing>& iovs, bool brief = true);

/// A tag and its IOVs as `conditions list` shows them.
struct TagListing {
  Tag tag;
  std::vector<IovListing> iovs = {};
};

/// The listing of a tag (at `at`, "" for now): each IOV's payload read (its hash checked: an
/// edited payload is an error, not shown).
Result<TagListing> tagListing(Database& db, const Tag& tag, const std::string& at = {});
/// Every tag's listing, or only `tag`'s when not empty (an error when it does not exist), as
/// it is or was at `at`.
Result<std::vector<TagListing>> listTags(Database& db, const std::string& tag = {}, const std::string& at = {});
/// A tag as `conditions list --json` shows it: {"tag", "state" (tag_states.hpp), "description",
/// "created", "state_changed" and "reason" when it has them, "iovs": [{"first_run", "last_run",
/// "payload", "inserted", "status", "chi2", "ndf", "sigma_sys_method", "chi2_statistical_errors",
/// "sigma_sys_deg", "selected_events", "model" (Payload::model)}]}.
io::Json tagJson(const TagListing& listing);

/// The alignment of each run from the IOVs of a tag.
class TagAlignments {
 public:
  /// The calorimeter must outlive this object.
  /// `at`: the snapshot to read ("" : the latest change of the tag, read then: at() says it).
  static Result<TagAlignments> open(const std::string& uri, const std::string& tag, const geometry::Calorimeter& calo,
                                    const std::string& at = {});
  /// The snapshot time it read: rerunning with it reads the same IOVs and payloads.
  [[nodiscard]] const std::string& at() const { return snapshot_->at(); }
  /// The alignment of `run` (the same object for every run of one IOV); the error names the
  /// run and the tag.
  Result<std::shared_ptr<const geometry::AlignmentTransform>> transformOf(std::int64_t run);
  Result<geometry::AlignmentParameters> parametersOf(std::int64_t run);
  /// The distinct (model, depth offset in cm) of the tag's IOVs whose payloads record their
  /// fit's model corrections (AlignmentSource::fittedDepths): of the IOVs used so far, or of
  /// all before any is.
  Result<std::vector<std::pair<std::string, double>>> fittedDepths();
  /// The IOVs used so far.
  [[nodiscard]] int used() const { return static_cast<int>(transforms_.size()); }
  [[nodiscard]] const std::string& uri() const { return db_->uri(); }
  [[nodiscard]] const std::string& tag() const { return snapshot_->tag().name; }

 private:
  std::unique_ptr<Database> db_;
  std::unique_ptr<TagSnapshot> snapshot_;
  const geometry::Calorimeter* calo_ = nullptr;
  std::map<std::int64_t, std::shared_ptr<const geometry::AlignmentTransform>> transforms_;  // by first run
};

/// The alignment events are corrected with: one file (a parameter file, a fit result or a
/// placements file) for every run, or each run's own IOV of a conditions tag.
// bugprone-exception-escape: clang-tidy 14 takes nlohmann::json's noexcept move (its
// assert_invariant) for one that throws; nothing here throws on a move.
struct AlignmentSource {  // NOLINT(bugprone-exception-escape)
  std::shared_ptr<const geometry::AlignmentTransform> one;
  std::shared_ptr<TagAlignments> byRun;
  /// For the outputs: {"file", "parameters"} or {"conditions", "tag", "conditions_snapshot"}.
  io::Json description;
  std::vector<std::string> warnings;  ///< of the alignment file
  /// The shower depths the alignment was fitted with, distinct: (the model in words, the
  /// depth offset added to R(E, θ) in cm) of the fit result, or of every IOV of the tag;
  /// empty when the file or the payloads do not say (a parameter file). The cluster method
  /// of `correct` moves each cluster at a depth: another than the fit's biases it.
  std::vector<std::pair<std::string, double>> fittedDepths;
  [[nodiscard]] apply::AlignmentOfRun alignmentOf() const;
  /// The file `alignment`, or when `conditions` is not empty the tag `tag` of that database
  /// (as it was at `snapshot`, a time parseSnapshot takes; "" : as it is).
  static Result<AlignmentSource> open(const std::string& alignment, const std::string& conditions,
                                      const std::string& tag, const geometry::Calorimeter& calo,
                                      const std::string& snapshot = {});
};

}  // namespace emcalign::conddb
