#include "emcalign/report/residual_plots.hpp"

#include <cmath>
#include <iterator>

#include <fmt/format.h>

#include "gnuplot.hpp"

namespace emcalign::report {

namespace {

using namespace detail;
namespace fs = std::filesystem;
using S = apply::ResidualSummary;

// Colours of the samples, in order (a nominal or "before" sample usually comes first).
constexpr const char* kColours[] = {"#000000", "#d62728", "#1f77b4", "#2ca02c", "#9467bd",
                                    "#ff7f0e", "#8c564b", "#e377c2", "#17becf", "#7f7f7f"};

const char* colour(std::size_t k) { return kColours[k % std::size(kColours)]; }

std::string histogramsData(const std::vector<LabelledSummary>& samples) {
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out),
                 "# emcalign residuals: per sample (gnuplot index) the distributions of dphi and dtheta, deg,\n"
                 "# normalised to unit area. columns: 1 bin centre  2 dphi density  3 dtheta density\n");
  const double width = 2.0 * S::kRangeDeg / S::kBins;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const S& s = samples[k].summary;
    double nPhi = 0.0, nTheta = 0.0;
    for (int i = 0; i < S::kBins; ++i) {
      nPhi += s.dPhiCounts[static_cast<std::size_t>(i)];
      nTheta += s.dThetaCounts[static_cast<std::size_t>(i)];
    }
    fmt::format_to(std::back_inserter(out), "{}# {}\n", k > 0 ? "\n\n" : "", commentText(samples[k].label));
    for (int i = 0; i < S::kBins; ++i) {
      const auto b = static_cast<std::size_t>(i);
      fmt::format_to(std::back_inserter(out), "{:.6g} {:.6g} {:.6g}\n", -S::kRangeDeg + (i + 0.5) * width,
                     nPhi > 0 ? s.dPhiCounts[b] / (nPhi * width) : 0.0,
                     nTheta > 0 ? s.dThetaCounts[b] / (nTheta * width) : 0.0);
    }
  }
  return fmt::to_string(out);
}

std::string columnsData(const std::vector<LabelledSummary>& samples) {
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out),
                 "# emcalign residuals: mean sin(dphi)*180/pi per phi column. columns: 1 phi centre (deg)");
  for (std::size_t k = 0; k < samples.size(); ++k) {
    fmt::format_to(std::back_inserter(out), "  {} {}", k + 2, commentText(samples[k].label));
  }
  fmt::format_to(std::back_inserter(out), "\n");
  for (int c = 0; c < S::kColumns; ++c) {
    fmt::format_to(std::back_inserter(out), "{:.6g}", (c + 0.5) * 360.0 / S::kColumns);
    for (const auto& sample : samples) {
      const double m = sample.summary.columnMeanDeg[static_cast<std::size_t>(c)];
      fmt::format_to(std::back_inserter(out), " {}", std::isfinite(m) ? fmt::format("{:.6g}", m) : "NaN");
    }
    fmt::format_to(std::back_inserter(out), "\n");
  }
  return fmt::to_string(out);
}

std::string residualsScript(const std::vector<LabelledSummary>& samples) {
  std::string s = terminalHeader("residuals", 1600, 650);
  s += "data = 'residuals.dat'\n"
       "set multiplot layout 1,2 title \"Residuals of the selected e+e- → e+e- particles (θ_{EMC} 45°–135°)\" "
       "font ',14' margins 0.06,0.98,0.13,0.88 spacing 0.07,0.1\n"
       "set grid lc rgb '#e0e0e0' lt 1\nset tics front\nset key top left Left reverse samplen 2 font ',10'\n"
       "set yrange [0:*]\nset offsets 0, 0, graph 0.45, 0  # room for the key above the peaks\n";
  const struct {
    const char *xlabel, *what;
    int column;
  } panels[] = {{"Δφ = φ_{TS} − φ_{EMC}  [deg]", "dphi", 2}, {"Δθ = θ_{TS} − θ_{EMC}  [deg]", "dtheta", 3}};
  for (const auto& p : panels) {
    s += fmt::format("\nset xlabel \"{}\"\nset ylabel \"particles / deg (unit area)\"\nset xrange [{}:{}]\n", p.xlabel,
                     -S::kRangeDeg, S::kRangeDeg);
    std::string items;
    for (std::size_t k = 0; k < samples.size(); ++k) {
      const S& x = samples[k].summary;
      const double mean = p.column == 2 ? x.meanSinDphiDeg : x.meanDthetaDeg;
      const double rms = p.column == 2 ? x.rmsDphiDeg : x.rmsDthetaDeg;
      items += fmt::format(
          "{}data index {} using 1:{} with histeps lw 2 lc rgb '{}' title \"{}: mean {:+.3f}°, rms "
          "{:.3f}°\"",
          k > 0 ? ", \\\n     " : "plot ", k, p.column, colour(k), literalText(samples[k].label), mean, rms);
    }
    s += items + "\n";
  }
  s += "unset multiplot\n";
  return s;
}

std::string columnsScript(const std::vector<LabelledSummary>& samples) {
  std::string s = terminalHeader("residual_columns", 1200, 650);
  s += "data = 'residual_columns.dat'\n"
       "set title \"Mean sin Δφ · 180/π in the 16 φ columns (the irregularity is max − min)\" font ',13'\n"
       "set grid lc rgb '#e0e0e0' lt 1\nset tics front\nset key outside right top Left reverse samplen 2 font ',10'\n"
       "set xlabel \"φ_{EMC}  [deg]\"\nset ylabel \"mean sin Δφ · 180/π  [deg]\"\nset xrange [0:360]\n"
       "set xtics 45\nset arrow from 90, graph 0 to 90, graph 1 nohead dt 2 lc rgb '#888888'\n"
       "set arrow from 270, graph 0 to 270, graph 1 nohead dt 2 lc rgb '#888888'\n";
  std::string items;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    items += fmt::format("{}data using 1:{} with linespoints pt 7 ps 0.8 lw 1.5 lc rgb '{}' title \"{} ({:.3f}°)\"",
                         k > 0 ? ", \\\n     " : "plot ", k + 2, colour(k), literalText(samples[k].label),
                         samples[k].summary.irregularityDeg);
  }
  return s + items + "\n";
}

}  // namespace

Result<std::vector<std::string>> writeResidualPlots(const std::string& dir,
                                                    const std::vector<LabelledSummary>& samples) {
  if (samples.empty()) return Error{"residual figures: no sample"};
  const fs::path out(dir);
  if (Status s = createPlotDirectory(out); !s) return s.error();
  if (Status s = writeFile(out, "residuals.dat", histogramsData(samples)); !s) return s.error();
  if (Status s = writeFile(out, "residual_columns.dat", columnsData(samples)); !s) return s.error();
  return drawFigures(out, {{"residuals", residualsScript(samples)}, {"residual_columns", columnsScript(samples)}});
}

}  // namespace emcalign::report
