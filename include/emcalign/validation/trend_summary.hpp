#pragma once
// What `emcalign trend` says on its report stream (docs/outputs.md): the trend in a few lines
// (IOVs, steps, drifts, stable periods, each step, edge, known boundary and drift), the refit
// by stable period, and the trend's directory written whole (trend.json, trend.md, figures).

#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/validation/segment_refit.hpp"
#include "emcalign/validation/trend.hpp"

namespace emcalign::validation {

/// The report of a trend of tag `tag`: a line of counts, the models (modelsText), the verdict
/// when it found no step or something else to say, then one line per step, edge, known
/// boundary where nothing changed, and drift.
std::string trendSummaryText(const Trend& t, const std::string& tag, const std::vector<calib::ModelIdentity>& models);
/// What the trend warns of: a known boundary with no IOV on one side.
std::vector<std::string> trendWarnings(const Trend& t);
/// The refit's report: its IOVs against the tag's, the periods kept and why, dx's errors before
/// and after in each refitted period.
std::string refitSummaryText(const SegmentRefit& r, std::size_t iovsBefore, const std::string& database,
                             const std::string& tagOut);

/// The trend's directory `dir` (created if missing): trend.json, trend.md and the figures
/// (titled `title`); returns the figures written.
Result<std::vector<std::string>> writeTrendDirectory(const std::string& dir, const Trend& t,
                                                     const std::vector<TrendSeries>& series, const TrendOrigin& origin,
                                                     const std::string& markdown, const PeriodTruth* truth,
                                                     const std::string& title);

}  // namespace emcalign::validation
