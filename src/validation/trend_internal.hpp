#pragma once
// The parts of the trend analysis (validation/trend.hpp) that live in files of their own.

#include <vector>

#include "emcalign/validation/trend.hpp"

namespace emcalign::validation {

/// The periods between the changes a trend found (its steps, known boundaries, edges and
/// drifts are set): steps at neighbouring IOVs (chained) are one change of the detector. A
/// change with a step inside an IOV makes that IOV a transition of its own (the strongest such
/// step's); otherwise the strongest step's IOV starts the next period. A known boundary always
/// starts a period (its straddling IOV a transition), and takes the place of a change found at
/// its IOV or the next. A drift's start and end cut a period too. Each period lists what
/// drifts or is inconsistent inside it.
std::vector<TrendSegment> stablePeriods(const Trend& t, const std::vector<TrendSeries>& series);

/// Marks the parameters whose IOVs scatter about their mean beyond their errors in each period
/// (not the transitions): the statistical errors as they are, quoted ones scaled by the
/// series' error scale; Bonferroni at `alpha` over every (period, series) tested. Returns the
/// number tested.
int judgeScatter(std::vector<TrendSegment>& periods, const std::vector<TrendSeries>& series,
                 const std::vector<SeriesAnalysis>& analyses, double alpha);

}  // namespace emcalign::validation
