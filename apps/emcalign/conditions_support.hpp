#pragma once
// The conditions database as the commands use it: a tag's calibrations looked up run by run
// (correct, simulate, trend), and a payload written out as a parameter file (get).

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "emcalign/apply/correct.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/detector.hpp"

namespace emcalign::app {

/// The parameter file of a payload (SPEC §3), with where it came from under "input":
/// {"conditions": URI, "tag", "first_run", "last_run", "payload", "provenance"}.
io::Json parameterFileOf(const conddb::Iov& iov, const conddb::Payload& payload, const std::string& uri,
                         const std::string& tag);

/// A tag as `conditions list --json` shows it: {"tag", "state", "description", "created",
/// "iovs": [{"first_run", "last_run", "payload", "inserted", "status", "chi2", "ndf",
/// "selected_events"}]}.
io::Json tagJson(conddb::Database& db, const conddb::Tag& tag);

/// `--conditions URI --tag T`: each run's alignment, from the IOV that contains it.
class ConditionsAlignments {
 public:
  static Result<ConditionsAlignments> open(const std::string& uri, const std::string& tag,
                                           const geometry::Calorimeter& calo);
  /// The alignment of `run` (the same object for every run of one IOV); the error names the
  /// run and the tag.
  Result<std::shared_ptr<const geometry::AlignmentTransform>> transformOf(std::int64_t run);
  Result<geometry::AlignmentParameters> parametersOf(std::int64_t run);
  /// The IOVs used so far.
  int used() const { return static_cast<int>(transforms_.size()); }
  const std::string& uri() const { return db_->uri(); }
  const std::string& tag() const { return snapshot_->tag().name; }

 private:
  std::unique_ptr<conddb::Database> db_;
  std::unique_ptr<conddb::TagSnapshot> snapshot_;
  const geometry::Calorimeter* calo_ = nullptr;
  std::map<std::int64_t, std::shared_ptr<const geometry::AlignmentTransform>> transforms_;  // by first run
};

/// The alignment a command corrects with: one file (`--alignment`) for every run, or each
/// run's own IOV (`--conditions URI --tag T`). `description` says which, for the outputs.
struct AlignmentSource {
  std::shared_ptr<const geometry::AlignmentTransform> one;
  std::shared_ptr<ConditionsAlignments> byRun;
  io::Json description;
  std::vector<std::string> warnings;  ///< of the alignment file
  apply::AlignmentOfRun alignmentOf() const;
  static Result<AlignmentSource> open(const std::string& alignment, const std::string& conditions,
                                      const std::string& tag, const geometry::Calorimeter& calo);
};

/// The options of a correction from the command line: the method by name (auto, hits,
/// clusters), the cluster method's R(E, θ) with its depth offset (cm), or the offset of a
/// corrections file when one is given (of a grid directory: at each event's beam energy).
Result<apply::CorrectOptions> correctOptions(const std::string& method, double depthOffsetCm,
                                             const std::string& corrections, const geometry::Calorimeter& calo);

}  // namespace emcalign::app
