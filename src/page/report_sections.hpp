#pragma once
// The parts of the HTML report (page/calibration_report.hpp) in files of their own: how it
// writes parameters and numbers (report_text.cpp), and its sections: the fit (fit_section.cpp),
// the time evolution (trend_section.cpp), the checks against simulation and physics
// (check_sections.cpp).

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/page/calibration_report.hpp"

namespace emcalign::report {

/// The symbol a physicist reads for a parameter's file name.
std::string symbol(const std::string& name);

/// A parameter as a physicist reads it, with its file name where that differs.
std::string label(const std::string& name);

/// A value to the precision of its error (two significant digits of the error).
std::pair<std::string, std::string> withError(double value, double error);

/// A number, or "—" for none.
std::string number(double v, const char* format = "{:.4g}");

/// A fit's χ² in words: with σ_sys auto, χ²/ndf is 1 by construction and tests nothing; the
/// test is the χ² with the statistical errors alone (plain text: the caller escapes nothing).
std::string fitChi2Text(const calib::FitRecord& r);

/// The sections of the page, each the body of its html::Section.
Result<std::string> fitSection(const ReportFit& f);
Result<std::string> compareSection(const ReportCompare& report);
Result<std::string> validationSection(const ReportValidation& v);
Result<std::string> trendSection(const std::optional<ReportTrend>& tr, const std::optional<ReportConditions>& cond);
Result<std::string> checksSection(const std::vector<ReportCheck>& checks);

}  // namespace emcalign::report
