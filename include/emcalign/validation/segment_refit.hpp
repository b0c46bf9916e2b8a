#pragma once
// `trend --refit`: one calibration per stable period of a tag (validation/trend.hpp) from all
// its events, in place of the run groups' calibrations it replaces. A period whose IOVs do not
// agree within their errors keeps them — a drift, a step or drift the IOVs cannot tell apart,
// a stretch its model does not fit, IOVs that scatter beyond their statistical errors, an IOV
// straddling a step: one value would average over what moves inside it.
//
// The precision gained, three ways (docs/campaign.md):
//  - quoted: the fit's errors, which carry σ_sys = 0.2° per profile bin (docs/contract.md §7). σ_sys does
//    not shrink with events, and it dominates a bin already at ~50 000 events, so the quoted
//    error of a period barely improves on a group's;
//  - statistical: the part the events make, which does shrink, as 1/√N (the fits' statistical
//    errors, calib::FitResult::statisticalErrors; for payloads that do not record them, the
//    same fits with σ_sys = 0);
//  - observed: the scatter (RMS) of the replaced IOVs about their mean, which is what they
//    really fluctuate by; with a period's truth, the refit's distance from it.

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "emcalign/validation/period.hpp"
#include "emcalign/validation/trend.hpp"

namespace emcalign::validation {

/// One parameter of a refitted period (file units). NaN where it does not apply.
struct RefitPrecision {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  Quantity parameter;          ///< its unit: parameter.unit()
  double value = kNaN;         ///< the refit
  double quotedBefore = kNaN;  ///< median quoted error of the replaced IOVs
  double quotedAfter = kNaN;   ///< the refit's quoted error
  double statBefore = kNaN;    ///< median statistical error (σ_sys = 0) of the replaced IOVs
  double statAfter = kNaN;     ///< the refit's statistical error
  double scatter = kNaN;       ///< RMS of the replaced IOVs about their mean
  /// The replaced IOVs' scatter about their weighted mean over the errors the trend weighed
  /// them by (statistical where recorded): √(χ²/ndf), and the χ² and ndf.
  double scatterOverError = kNaN, chi2 = kNaN;
  int ndf = 0;
  double truth = kNaN;           ///< mean truth over the period's runs (with a truth)
  double truthRmsBefore = kNaN;  ///< RMS over the replaced IOVs of (value − truth over the IOV)
};

struct RefittedSegment {
  std::int64_t firstRun = 0, lastRun = 0;
  std::size_t begin = 0, end = 0;  ///< the tag's IOVs [begin, end) it covers
  /// Its IOVs kept as they were, not refitted (TrendSegment::refittable): no fit, no precision.
  bool kept = false;
  /// Why it was kept (TrendSegment::refittable): parameters drifting inside it, changing by a
  /// step or a drift these IOVs cannot tell apart, inconsistent with one model, scattering
  /// beyond their errors; or an IOV straddling a step.
  std::vector<Quantity> drifting, undecided, inconsistent;
  std::vector<PeriodScatter> scattering;
  bool transition = false;
  std::int64_t selected = 0;  ///< selected events of the refit
  std::int64_t medianSelectedBefore = 0;
  std::optional<GroupFit> fit;
  std::vector<RefitPrecision> precision;  ///< the series of the trend, in their order
};

struct SegmentRefit {
  std::vector<conddb::Database::NewIov> iovs;  ///< the new tag, tiling the old one's runs
  std::vector<RefittedSegment> segments;
};

/// A refit comparable with a tag's calibrations uses what they were made with: `model` takes
/// the σ_sys every IOV's payload records (payloads made before the choice: the contract's), an error
/// when two differ; and every payload's corrections must be the model's (by SHA-256; by the
/// path for payloads that record none), an error naming the runs and the corrections used.
Status adoptTagSettings(conddb::TagSnapshot& tag, CampaignModel& model);

/// The corrections a tag's campaign fitted it with, when its payloads all name the same ones
/// and they are still where they were, with the SHA-256 recorded (what `trend --refit` takes
/// without --corrections); none when the payloads name none (the paper's model). An error says
/// which IOV names other corrections, or that the file is gone or has changed (give
/// --corrections, the campaign's own).
Result<std::optional<std::string>> recordedCorrections(conddb::TagSnapshot& tag);

/// The data of a refit must be what the tag was made from: every file whose SHA-256 its IOVs
/// record, and no other (compared by content: the files may have moved). The error names a
/// file missing, changed or foreign to the tag; warnings name IOVs that record no digests
/// (stored by hand: nothing to compare them with).
Result<std::vector<std::string>> checkRefitData(conddb::TagSnapshot& tag, const CampaignScan& scan);

/// Refits every stable period of `trend` (of `series`, the tag's) from the scanned events.
/// `model` must be the campaign's (the same corrections); `truth` may be null. A payload's
/// provenance says {"refit": {"tag", "period", "periods", "replaces_iovs", "runs"}}.
Result<SegmentRefit> refitSegments(const Trend& trend, const std::vector<TrendSeries>& series, conddb::TagSnapshot& tag,
                                   const CampaignScan& scan, const CampaignModel& model, const PeriodTruth* truth);

/// Why a period kept its IOVs, in words ("drifting: alpha; dx scatters 2.1 times its errors").
std::string keptBecause(const RefittedSegment& s);

/// trend.json's "refit": {"iovs", "iovs_before", "segments": [{"first_run", "last_run",
/// "replaces_iovs", "selected_events", "kept" | "parameters", "precision": {name: {...}}}]}.
io::Json refitJson(const SegmentRefit& r, std::size_t iovsBefore);
/// The section of trend.md: a table per refitted period and the gains over all of them.
std::string refitMarkdown(const SegmentRefit& r, std::size_t iovsBefore, const std::string& tagOut);

}  // namespace emcalign::validation
