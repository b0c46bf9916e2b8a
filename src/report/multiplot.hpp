#pragma once
// Internal to the report module (src/report/): figures of many panels drawn with gnuplot's
// multiplot (the fit's profiles, the validation campaign's pulls and residuals) — the value
// range an axis must show, the grid that places the panels and the legend strip, the start
// of a multiplot and one panel's plot command.

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace emcalign::report::detail {

/// The extent of the finite values added; empty (lo > hi) until one is.
struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  void add(double x) {
    if (!std::isfinite(x)) return;
    lo = std::min(lo, x);
    hi = std::max(hi, x);
  }
  /// Padded by 10% of the span on each side, at least `minSpan` wide.
  [[nodiscard]] Range padded(double minSpan) const;
};

// Small multiples: panels placed by explicit screen margins (the numbers are in the script,
// for whoever restyles it), y tic labels and y label on the left column only, x label on the
// bottom row only. Above the panels a header strip holds the title and a one-line legend,
// drawn last as an axis-less full-width plot so that the key never covers data.
// With `sharedAxes == false` (panels of different quantities and ranges) every panel gets
// its own tic labels and axis labels; the gaps must then leave room for them.
struct GridLayout {
  int left = 105, right = 20, top = 112, bottom = 62, hGap = 34, vGap = 72;  // px
  bool sharedAxes = true;
};

struct Grid {
  using Layout = GridLayout;
  int panels = 0, cols = 1, rows = 1;
  int width = 0, height = 0, panelHeight = 0;  // px
  Layout m;

  Grid(int nPanels, int nCols, int widthPx, int panelHeightPx, Layout layout = {});

  /// The width that gives panels of `panelWidthPx`.
  static int widthFor(int nPanels, int nCols, int panelWidthPx, const Layout& layout);

  [[nodiscard]] int panelWidth() const;
  /// Margins and axis labels of panel k (row by row, from the top left).
  [[nodiscard]] std::string panel(int k, const std::string& xlabel, const std::string& ylabel) const;
  /// The header strip's key: `entries` are gnuplot `keyentry` plot items.
  [[nodiscard]] std::string legend(const std::vector<std::string>& entries) const;
  /// A line of text in a strip under the panels (reserve kFootnotePx more in the bottom
  /// margin); "" for none. `text` is enhanced text, safe in a double-quoted string.
  [[nodiscard]] std::string footnote(const std::string& text) const;
  static constexpr int kFootnotePx = 24;
};

/// `set multiplot` with a title and a smaller subtitle line, and the settings every panel shares.
std::string multiplotStart(const std::string& title, const std::string& subtitle);
/// `plot` of the items, one to a line.
std::string plotCommand(const std::vector<std::string>& items);

}  // namespace emcalign::report::detail
