#include "emcalign/report/trend_plots.hpp"
#include "emcalign/core/text.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>

#include <fmt/format.h>

#include "gnuplot.hpp"

namespace emcalign::report {

namespace {

using namespace detail;
namespace fs = std::filesystem;

// How a parameter is named on an axis ("beta_rel" → β_{rel}).
std::string axisName(Quantity p) { return quantityLabel(std::string(p.name())); }

std::string dataOf(const TrendFigure& f) {
  fmt::memory_buffer out;
  fmt::format_to(
      std::back_inserter(out),
      "# emcalign trend of {} ({}): index 0 the IOVs (columns: middle run, value, error, first run, last "
      "run), index 1 the segments' lines (third column: 0 consistent, 1 a drift, 2 inconsistent with its model), "
      "index 2 the truth\n",
      commentText(std::string(f.parameter.name())), f.parameter.unit());
  for (const auto& p : f.points) {
    fmt::format_to(std::back_inserter(out), "{:.1f} {:.8g} {:.6g} {:.0f} {:.0f}\n", p.x, p.y, p.error, p.firstRun,
                   p.lastRun);
  }
  fmt::format_to(std::back_inserter(out), "\n\n");
  for (const auto& l : f.segments) {
    const int kind = l.inconsistent ? 2 : l.drift ? 1 : 0;
    fmt::format_to(std::back_inserter(out), "{:.1f} {:.8g} {}\n{:.1f} {:.8g} {}\n\n", l.x0, l.y0, kind, l.x1, l.y1,
                   kind);
  }
  fmt::format_to(std::back_inserter(out), "\n");
  if (f.truth.empty()) fmt::format_to(std::back_inserter(out), "NaN NaN\n");
  for (const auto& [x, y] : f.truth) fmt::format_to(std::back_inserter(out), "{:.1f} {:.8g}\n", x, y);
  return fmt::to_string(out);
}

// The plot commands of one panel (its data file is trend_<parameter>.dat).
std::string panel(const TrendFigure& f, bool key, int fontSize) {
  std::string s;
  s += fmt::format("set ylabel \"{} [{}]\" font ',{}'\n", axisName(f.parameter), f.parameter.unit(), fontSize);
  s += "unset arrow\n";
  for (double x : f.steps) {
    s += fmt::format("set arrow from {:.1f}, graph 0 to {:.1f}, graph 1 nohead lw 1.5 dt 2 lc rgb '#d62728'\n", x - 0.5,
                     x - 0.5);
  }
  for (double x : f.boundaries) {
    s += fmt::format("set arrow from {:.1f}, graph 0 to {:.1f}, graph 1 nohead lw 1 dt 3 lc rgb '#7f7f7f'\n", x - 0.5,
                     x - 0.5);
  }
  if (key) {
    s += "set key tmargin right horizontal Left reverse samplen 2 font ',10'\n";
  } else {
    s += "unset key\n";
  }
  // The range holds every error bar whole (gnuplot's autoscale clips them).
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  auto take = [&](double y) {
    if (std::isfinite(y)) {
      lo = std::min(lo, y);
      hi = std::max(hi, y);
    }
  };
  for (const auto& p : f.points) {
    take(p.y - p.error);
    take(p.y + p.error);
  }
  for (const auto& l : f.segments) {
    take(l.y0);
    take(l.y1);
  }
  for (const auto& [x, y] : f.truth) take(y);
  if (lo <= hi) {
    const double pad = hi > lo ? 0.06 * (hi - lo) : std::max(1e-6, 0.1 * std::abs(hi));
    s += fmt::format("set yrange [{:.8g}:{:.8g}]\n", lo - pad, hi + pad);
  } else {
    s += "set autoscale y\n";
  }
  const bool drift = std::any_of(f.segments.begin(), f.segments.end(), [](const auto& l) { return l.drift; });
  const bool orStep = std::any_of(f.segments.begin(), f.segments.end(), [](const auto& l) { return l.orStep; });
  const bool consistent =
      std::any_of(f.segments.begin(), f.segments.end(), [](const auto& l) { return !l.drift && !l.inconsistent; });
  const bool inconsistent =
      std::any_of(f.segments.begin(), f.segments.end(), [](const auto& l) { return l.inconsistent; });
  const std::string data = fmt::format("'trend_{}.dat'", f.parameter);
  s += fmt::format(
      "plot {0} index 2 using 1:2 with steps lw 1.2 lc rgb '#555555' title '{1}', \\\n"
      "     {0} index 0 using 1:2:4:5:($2-$3):($2+$3) with xyerrorbars pt 7 ps 0.35 lc rgb '#1f77b4' title 'IOVs', \\\n"
      "     {0} index 1 using 1:($3 == 0 ? $2 : NaN) with lines lw 2 lc rgb '#2ca02c' title '{2}', \\\n"
      "     {0} index 1 using 1:($3 == 1 ? $2 : NaN) with lines lw 2.5 dt 2 lc rgb '#ff7f0e' title '{3}', \\\n"
      "     {0} index 1 using 1:($3 == 2 ? $2 : NaN) with lines lw 2.5 dt 3 lc rgb '#d62728' title '{4}'",
      data, f.truth.empty() ? "" : "truth", consistent ? "segments" : "",
      drift ? (orStep ? "drift or step" : "drift") : "", inconsistent ? "inconsistent (χ²)" : "");
  // The vertical lines in the key too.
  if (!f.steps.empty()) s += ", \\\n     NaN with lines lw 1.5 dt 2 lc rgb '#d62728' title 'step'";
  if (!f.boundaries.empty()) s += ", \\\n     NaN with lines lw 1 dt 3 lc rgb '#7f7f7f' title 'known boundary'";
  s += "\n";
  return s;
}

std::string common() {
  return "set grid lc rgb '#e0e0e0' lt 1\nset tics front\nset format x '%.0f'\nset xlabel 'run'\n"
         "set mxtics 2\n";
}

}  // namespace

Result<std::vector<std::string>> writeTrendPlots(const std::string& dir, const std::vector<TrendFigure>& figures,
                                                 const std::string& title) {
  if (figures.empty()) return Error{"trend figures: no parameter"};
  const fs::path out(dir);
  if (Status s = createPlotDirectory(out); !s) return s.error();
  std::vector<Figure> scripts;
  for (const auto& f : figures) {
    if (Status s = writeFile(out, fmt::format("trend_{}.dat", f.parameter), dataOf(f)); !s) return s.error();
    std::string s = terminalHeader(fmt::format("trend_{}", f.parameter), 1400, 560) + common();
    s += fmt::format("set title \"{}: {} against run ({}, {})\" font ',13'\n", literalText(title),
                     axisName(f.parameter), counted(f.points.size(), "IOV"), counted(f.steps.size(), "step"));
    s += panel(f, true, 12);
    scripts.push_back({fmt::format("trend_{}", f.parameter), s});
  }
  // The paper's Fig. 7: α, dx, μ, ψ.
  std::vector<const TrendFigure*> four;
  for (Quantity p : {Quantity(Param::Alpha), Quantity(Param::Dx), Quantity(Physical::Mu), Quantity(Physical::Psi)}) {
    auto it = std::find_if(figures.begin(), figures.end(), [&](const TrendFigure& f) { return f.parameter == p; });
    if (it != figures.end()) four.push_back(&*it);
  }
  if (!four.empty()) {
    std::string s = terminalHeader("fig7", 1600, 1000) + common();
    std::vector<std::string> shown;
    shown.reserve(four.size());
    for (const TrendFigure* f : four) shown.push_back(axisName(f->parameter));
    // ψ is absent where β is within 3σ of 0 in every IOV (its direction undefined): said.
    const bool noPsi = four.back()->parameter != Physical::Psi;
    s += fmt::format(
        "set multiplot layout 2,2 title \"{}: the time evolution of {} (the paper's Fig. 7){}\" font ',14'\n",
        literalText(title), fmt::join(shown, ", "), noPsi ? "; ψ undefined: β within 3σ of 0 in every IOV" : "");
    for (std::size_t k = 0; k < four.size(); ++k) s += panel(*four[k], true, 11);
    s += "unset multiplot\n";
    scripts.push_back({"fig7", s});
  }
  {
    // Two to a row, 1400 px wide: legible where a page shows it at its width (emcalign report).
    const int columns = 2;
    const int rows = static_cast<int>((figures.size() + columns - 1) / columns);
    std::string s = terminalHeader("trend_all", 1400, 330 * rows) + common();
    s += "set xlabel ''\nset format x '%.0f'\nset tics font ',10'\n";
    s += fmt::format(
        "set multiplot layout {},{} title \"{}: every parameter against run\\n{{/*0.65 points: the IOVs with their "
        "errors; grey: the truth; green: segments; orange dashed: a drift (or a step's two constants)}}\\n"
        "{{/*0.65 red dotted: inconsistent with its model (χ²); red dashed verticals: steps; grey dotted: known "
        "boundaries}}\" font ',15'\n",
        rows, columns, literalText(title));
    for (std::size_t k = 0; k < figures.size(); ++k) s += panel(figures[k], false, 10);
    s += "unset multiplot\n";
    scripts.push_back({"trend_all", s});
  }
  return drawFigures(out, scripts);
}

}  // namespace emcalign::report
