#pragma once
// Figures of a tag's time evolution (validation/trend.hpp; the paper's Fig. 7):
//  - trend_<parameter>.png: the parameter of every IOV against run (the error bar, and the
//    IOV's run range as a horizontal bar), the fitted segments (dashed where a drift is
//    flagged), the steps as vertical lines, the truth when known (a simulated period);
//  - fig7.png: α, dx, μ and ψ, the paper's four panels;
//  - trend_all.png: every parameter on one page.
// Data: trend_<parameter>.dat (gnuplot index 0: points, 1: segment lines, 2: truth).

#include <string>
#include <utility>
#include <vector>

#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"

namespace emcalign::report {

struct TrendFigure {
  Quantity parameter;  ///< its unit: parameter.unit()
  struct Point {
    double x, y, error, firstRun, lastRun;
  };
  std::vector<Point> points;
  struct Line {
    double x0, y0, x1, y1;
    bool drift;
    bool inconsistent = false;  ///< its χ² rejects it: drawn as what it is, not as stable
    bool orStep = false;        ///< a drift that a step explains as well (validation::TrendDrift::orStep)
  };
  std::vector<Line> segments;
  std::vector<double> steps;                     ///< run of each step (the first run after)
  std::vector<double> boundaries;                ///< known boundaries (first run after), dotted
  std::vector<std::pair<double, double>> truth;  ///< (run, value), when known
};

/// Writes the figures into `dir` (created if missing); the PNG paths.
Result<std::vector<std::string>> writeTrendPlots(const std::string& dir, const std::vector<TrendFigure>& figures,
                                                 const std::string& title);

}  // namespace emcalign::report
