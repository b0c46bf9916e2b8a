#pragma once
// The figure of a systematic study (`emcalign systematics`, docs/systematics.md): which
// variation of the simulation moves which parameter, and by how much against the
// statistical precision of one calibration.
//
// systematics.png is a heat map: a column per parameter, a row per variation; a cell is the
// variation's shift of that parameter divided by the spread of the nominal fits (so ±1 is
// one calibration's statistical error), coloured from blue (−1 or below) through white to
// red (+1 or above) and printed. Rows of the quantities' effects follow: a pattern variation
// (gains, dead counters) shows its root mean square there, unsigned. The last row is the
// systematic error over the spread. With the reverse study a second map below holds the
// reverse shifts (corrections derived with the variation, fitted to the nominal samples).
// Data: systematics.dat (forward), systematics_reverse.dat; script: systematics.gp.

#include <string>
#include <vector>

#include "emcalign/core/result.hpp"

namespace emcalign::report {

struct SystematicsFigure {
  std::string title, subtitle;
  std::vector<std::string> parameters;  ///< the columns, e.g. "alpha", "dx_rel"
  /// The rows of the first map and their cells (values in units of the fits' spread; NaN:
  /// empty): the variations, then the summary rows (e.g. "systematic").
  std::vector<std::string> rows;
  std::vector<std::vector<double>> cells;  ///< [row][parameter]
  /// The reverse study's rows and cells (empty: not run).
  std::vector<std::string> reverseRows;
  std::vector<std::vector<double>> reverseCells;
};

/// Writes dir/systematics.png with its data and script; the PNG's path.
Result<std::string> writeSystematicsPlot(const std::string& dir, const SystematicsFigure& figure);

}  // namespace emcalign::report
