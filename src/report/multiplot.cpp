// The panels of multiplot figures (multiplot.hpp): ranges, the grid, the legend strip.
#include "multiplot.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace emcalign::report::detail {

Range Range::padded(double minSpan) const {
  Range r = *this;
  if (!(r.hi >= r.lo)) r.lo = r.hi = 0.0;
  const double pad = 0.1 * (r.hi - r.lo);
  r.lo -= pad;
  r.hi += pad;
  if (r.hi - r.lo < minSpan) {
    const double c = 0.5 * (r.lo + r.hi);
    r.lo = c - 0.5 * minSpan;
    r.hi = c + 0.5 * minSpan;
  }
  return r;
}

Grid::Grid(int nPanels, int nCols, int widthPx, int panelHeightPx, Layout layout)
    : panels(nPanels),
      cols(std::max(1, std::min(nPanels, nCols))),
      width(widthPx),
      panelHeight(panelHeightPx),
      m(layout) {
  rows = (panels + cols - 1) / cols;
  height = m.top + m.bottom + rows * panelHeight + (rows - 1) * m.vGap;
}

int Grid::widthFor(int nPanels, int nCols, int panelWidthPx, const Layout& layout) {
  const int cols = std::max(1, std::min(nPanels, nCols));
  return layout.left + layout.right + cols * panelWidthPx + (cols - 1) * layout.hGap;
}

int Grid::panelWidth() const { return (width - m.left - m.right - (cols - 1) * m.hGap) / cols; }

std::string Grid::panel(int k, const std::string& xlabel, const std::string& ylabel) const {
  const int col = k % cols, row = k / cols;
  const int x0 = m.left + col * (panelWidth() + m.hGap);
  const int y0 = m.top + row * (panelHeight + m.vGap);
  const bool left = col == 0 || !m.sharedAxes;
  const bool bottom = row == rows - 1 || k + cols >= panels || !m.sharedAxes;
  return fmt::format(
      "set lmargin at screen {:.4f}; set rmargin at screen {:.4f}\n"
      "set tmargin at screen {:.4f}; set bmargin at screen {:.4f}\n"
      "set format y {}; set ylabel {}; set xlabel {}\n",
      double(x0) / width, double(x0 + panelWidth()) / width, 1.0 - double(y0) / height,
      1.0 - double(y0 + panelHeight) / height, left ? "'%g'" : "''", left ? "\"" + ylabel + "\"" : "''",
      bottom ? "\"" + xlabel + "\" offset 0,0.3" : "''");
}

std::string Grid::footnote(const std::string& text) const {
  if (text.empty()) return {};
  return fmt::format(
      "\n# ---- footnote: an axis-less full-width strip under the panels\n"
      "unset border; unset tics; unset grid; unset xlabel; unset ylabel; unset title; unset arrow; unset key\n"
      "set lmargin at screen 0.02; set rmargin at screen 0.98\n"
      "set tmargin at screen {:.4f}; set bmargin at screen 0\n"
      "set xrange [0:1]; set yrange [0:1]\n"
      "set label 99 \"{}\" at graph 0.5, graph 0.5 center font ',11'\n"
      "plot NaN notitle\n"
      "unset label 99\n",
      static_cast<double>(kFootnotePx) / height, text);
}

std::string Grid::legend(const std::vector<std::string>& entries) const {
  return fmt::format(
      "\n# ---- legend: an axis-less full-width plot holding only the key\n"
      "unset border; unset tics; unset grid; unset xlabel; unset ylabel; unset title; unset "
      "arrow\n"
      "set lmargin at screen 0.02; set rmargin at screen 0.98\n"
      "set tmargin at screen {:.4f}; set bmargin at screen {:.4f}\n"
      "set xrange [0:1]; set yrange [0:1]\n"
      "set key inside center center horizontal reverse Left samplen 2.5 width -1 font ',12'\n"
      "plot NaN notitle, \\\n     {}\n",
      1.0 - 50.0 / height, 1.0 - 80.0 / height, fmt::join(entries, ", \\\n     "));
}

std::string multiplotStart(const std::string& title, const std::string& subtitle) {
  return fmt::format(
      "set multiplot title \"{}\\n{{/=11 {}}}\" font ',14'\n"
      "unset key\n"
      "set grid xtics ytics lc rgb '#e0e0e0' lt 1\n"
      "set tics front\n"
      "set title offset 0,-0.5 font ',11'\n",
      title, subtitle);
}

std::string plotCommand(const std::vector<std::string>& items) {
  return fmt::format("plot {}\n", fmt::join(items, ", \\\n     "));
}

}  // namespace emcalign::report::detail
