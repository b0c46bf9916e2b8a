// The heat map of a systematic study (emcalign/report/systematics_plot.hpp). The titles are
// the caller's text in enhanced mode (no _ ^ { } @ & ~ in them); the row names are set
// without enhancement, the parameters as quantity labels (α, β_{1}, dx_{rel}).
#include "emcalign/report/systematics_plot.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "gnuplot.hpp"

namespace emcalign::report {

namespace {

namespace fs = std::filesystem;
using namespace detail;

constexpr int kCellWidth = 62, kCellHeight = 26;  // px
// The first map's top leaves room for the figure's title and subtitle, its own title and its
// column labels; every map's for its title and column labels.
constexpr int kLeft = 250, kRight = 110, kTop = 140, kBottom = 20, kMapGap = 95, kMinColourBar = 200;

// x, y and the value of every cell (gnuplot's `with image` and `with labels` read it).
Result<std::string> cellData(const SystematicsFigure& f, const std::vector<std::string>& rows,
                             const std::vector<std::vector<double>>& cells) {
  if (cells.size() != rows.size()) return Error{"systematics plot: one row of cells per row name"};
  std::string out = "# column row value(shift/spread)\n";
  for (std::size_t r = 0; r < rows.size(); ++r) {
    if (cells[r].size() != f.parameters.size()) {
      return Error{fmt::format("systematics plot: row {} has {} cells for {} parameters", rows[r], cells[r].size(),
                               f.parameters.size())};
    }
    for (std::size_t c = 0; c < cells[r].size(); ++c) {
      const double v = cells[r][c];
      out += fmt::format("{} {} {}\n", c, r, std::isfinite(v) ? fmt::format("{:.6g}", v) : std::string("NaN"));
    }
  }
  return out;
}

// Text for a double-quoted gnuplot string: without quotes and backslashes.
std::string unquoted(const std::string& s) {
  std::string out;
  for (char c : s)
    if (c != '"' && c != '\\') out += c;
  return out;
}

// Tic labels at 0, 1, …: the names as they are (without quotes and backslashes: the tics
// are set noenhanced), or as enhanced-text labels of quantities (α, β_{1}, dx_{rel}).
std::string tics(const std::vector<std::string>& names, bool quantities) {
  std::string t;
  for (std::size_t k = 0; k < names.size(); ++k) {
    t += fmt::format("{}\"{}\" {}", k == 0 ? "" : ", ", quantities ? quantityLabel(names[k]) : unquoted(names[k]), k);
  }
  return t;
}

// One map: its margins (screen fractions) and the plot of cells with their printed values
// (white on the dark cells beyond ±0.7).
std::string mapScript(const SystematicsFigure& f, const std::vector<std::string>& rows, const std::string& data,
                      const std::string& title, int top, int width, int height) {
  const int mapHeight = static_cast<int>(rows.size()) * kCellHeight;
  return fmt::format(
      "set title \"{}\" font ',12' offset 0,1.2\n"
      "set lmargin at screen {:.4f}; set rmargin at screen {:.4f}\n"
      "set tmargin at screen {:.4f}; set bmargin at screen {:.4f}\n"
      "set xrange [-0.5:{}]; set x2range [-0.5:{}]; set yrange [{}:-0.5]\n"
      "unset xtics\n"
      "set x2tics ({}) scale 0 font ',11'\n"
      "set ytics ({}) scale 0 font ',10' noenhanced\n"
      "plot '{}' using 1:2:3 with image, \\\n"
      "     '' using 1:2:(($3 == $3) ? sprintf('%+.2f', $3) : ''):(abs($3) > 0.7 ? 0xffffff : 0x000000) \\\n"
      "        with labels textcolor rgb variable font ',9'\n",
      unquoted(title), double(kLeft) / width, double(width - kRight) / width, 1.0 - double(top) / height,
      1.0 - double(top + mapHeight) / height, static_cast<double>(f.parameters.size()) - 0.5,
      static_cast<double>(f.parameters.size()) - 0.5, static_cast<double>(rows.size()) - 0.5, tics(f.parameters, true),
      tics(rows, false), data);
}

}  // namespace

Result<std::string> writeSystematicsPlot(const std::string& dir, const SystematicsFigure& f) {
  if (f.parameters.empty() || f.rows.empty()) return Error{"systematics plot: nothing to draw"};
  auto forward = cellData(f, f.rows, f.cells);
  if (!forward) return forward.error();
  const bool reverse = !f.reverseRows.empty();
  auto backward = cellData(f, f.reverseRows, f.reverseCells);
  if (!backward) return backward.error();
  const fs::path out(dir);
  if (Status s = createPlotDirectory(out); !s) return s.error();
  if (Status s = writeFile(out, "systematics.dat", *forward); !s) return s.error();
  if (reverse) {
    if (Status s = writeFile(out, "systematics_reverse.dat", *backward); !s) return s.error();
  }
  const int width = kLeft + kRight + static_cast<int>(f.parameters.size()) * kCellWidth;
  const int forwardHeight = static_cast<int>(f.rows.size()) * kCellHeight;
  const int reverseHeight = reverse ? kMapGap + static_cast<int>(f.reverseRows.size()) * kCellHeight : 0;
  // The colour bar beside the first map, tall enough for its label however few its rows.
  const int colourBar = std::max(forwardHeight, kMinColourBar);
  const int height = kTop + std::max(forwardHeight + reverseHeight, colourBar) + kBottom;
  std::string script = terminalHeader("systematics", width, height);
  script += fmt::format(
      "set multiplot title \"{}\\n{{/=11 {}}}\" font ',14'\n"
      "unset key\n"
      "set palette defined (-1 '#2166ac', -0.5 '#92c5de', 0 '#ffffff', 0.5 '#f4a582', 1 '#b2182b')\n"
      "set cbrange [-1:1]\n"
      "set cbtics font ',10'\n"
      "set colorbox user origin screen {:.4f}, screen {:.4f} size screen {:.4f}, screen {:.4f}\n"
      "set cblabel 'shift / spread of the fits' font ',10'\n"
      "set border 0\n",
      unquoted(f.title), unquoted(f.subtitle), 1.0 - double(kRight - 25) / width,
      1.0 - double(kTop + colourBar) / height, 15.0 / width, double(colourBar) / height);
  script +=
      mapScript(f, f.rows, "systematics.dat",
                "mean of fit(variation) − fit(nominal); below it each quantity's effect, and the systematic error",
                kTop, width, height);
  if (reverse) {
    script += "unset colorbox\n";
    script += mapScript(f, f.reverseRows, "systematics_reverse.dat",
                        "reverse: corrections derived with the variation, fitted to the nominal samples − fitted "
                        "with those derived without",
                        kTop + forwardHeight + kMapGap, width, height);
  }
  script += "unset multiplot\n";
  auto written = drawFigures(out, {{"systematics", script}});
  if (!written) return written.error();
  return written->front();
}

}  // namespace emcalign::report
