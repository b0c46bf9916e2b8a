// The figures of a validation campaign (emcalign/report/campaign_plots.hpp): per quantity
// fit − truth and the pulls, reduced from the samples, their data files and scripts.
#include "emcalign/report/campaign_plots.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <iterator>
#include <limits>
#include <numbers>
#include <string_view>
#include <utility>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/types.hpp"
#include "emcalign/report/histogram.hpp"
#include "gnuplot.hpp"
#include "multiplot.hpp"

namespace emcalign::report {

namespace {

namespace fs = std::filesystem;
using namespace detail;

constexpr const char* kSamplesFile = "campaign_samples.dat";
constexpr const char* kPullsFile = "pulls.dat";
constexpr double kPullLimit = 5.0;  // pull histograms over [−5, 5]

// Panels of the campaign figures: four to a row (the campaign's 12 fit parameters fill three
// rows, its 5 derived quantities two more), so that the figure, some 1600 px wide, keeps
// legible text when a page shows it at its width (emcalign report).
int campaignColumns(int panels) { return std::clamp(static_cast<int>(std::ceil(std::sqrt(1.5 * panels))), 1, 4); }

// A number in a data file; gnuplot reads "NaN" as not-a-number (fmt would write "nan").
std::string dataNumber(double x) { return std::isfinite(x) ? fmt::format("{:.9g}", x) : "NaN"; }

// A number in a title; "n/a" when not finite.
std::string titleNumber(double x, const char* spec) {
  return std::isfinite(x) ? fmt::format(fmt::runtime(spec), x) : "n/a";
}

// Mean and standard deviation (n − 1, as the campaign's table) of the finite values.
struct MeanWidth {
  double mean = kNaN, width = kNaN;
  int n = 0;
};

MeanWidth meanWidth(const std::vector<double>& v) {
  double sum = 0.0, sum2 = 0.0;
  MeanWidth r;
  for (double x : v) {
    if (!std::isfinite(x)) continue;
    sum += x;
    sum2 += x * x;
    ++r.n;
  }
  if (r.n == 0) return r;
  r.mean = sum / r.n;
  if (r.n > 1) r.width = std::sqrt(std::max(0.0, (sum2 - r.n * r.mean * r.mean) / (r.n - 1)));
  return r;
}

// A tic step of 1, 2 or 5 × 10^k giving at most `maxTics` intervals over `span`.
double ticStep(double span, int maxTics) {
  if (!(span > 0.0) || !std::isfinite(span)) return 1.0;
  const double raw = span / maxTics;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * decade >= raw) return m * decade;
  return 10.0 * decade;
}

// An axis range around the finite values added: padded by 8% of the span, and never of
// zero width (a constant truth gets ±1% of its size, at least ±1e-6).
Range axisRange(const Range& r) {
  if (!(r.hi >= r.lo)) return Range{-1.0, 1.0};
  const double span = r.hi - r.lo;
  const double minSpan = std::max(2e-6, 0.02 * std::max(std::abs(r.lo), std::abs(r.hi)));
  const double pad = 0.08 * span;
  Range out{r.lo - pad, r.hi + pad};
  if (out.hi - out.lo < minSpan) {
    const double c = 0.5 * (r.lo + r.hi);
    out = Range{c - 0.5 * minSpan, c + 0.5 * minSpan};
  }
  return out;
}

// One quantity, reduced: fit − truth and pulls per sample, their statistics, the pull
// histogram and the extent of the points.
struct Panel {
  const CampaignSeries* series = nullptr;
  std::string label;
  std::vector<double> diff, pull;  // per sample; NaN where not defined
  MeanWidth diffStats, pullStats;
  Histogram pulls{-kPullLimit, kPullLimit, 20};
  Range truth, residual;  // residual: fit − truth ± error (capped, see reduce)
};

// The median of the finite, positive values; NaN if none.
double medianOfPositive(const std::vector<double>& v) {
  std::vector<double> x;
  for (double e : v)
    if (std::isfinite(e) && e > 0.0) x.push_back(e);
  if (x.empty()) return kNaN;
  const auto mid = x.begin() + static_cast<std::ptrdiff_t>(x.size() / 2);
  std::nth_element(x.begin(), mid, x.end());
  return *mid;
}

Result<std::vector<Panel>> reduce(const std::vector<CampaignSeries>& series) {
  if (series.empty()) return Error{"campaign plots: no quantities to plot"};
  std::vector<Panel> out;
  for (std::size_t k = 0; k < series.size(); ++k) {
    const CampaignSeries& s = series[k];
    if (s.truth.size() != s.fit.size() || s.truth.size() != s.error.size())
      return Error{
          fmt::format("campaign plots: quantity '{}': truth, fit and error need one value per sample each "
                      "(got {}, {} and {})",
                      s.name, s.truth.size(), s.fit.size(), s.error.size())};
    if (s.truth.empty()) return Error{fmt::format("campaign plots: quantity '{}': no samples", s.name)};
    Panel q;
    q.series = &s;
    q.label = quantityLabel(std::string(s.name.name()));
    // The y range holds the error bars up to 3 median errors: one huge error (ψ or τ of a
    // sample with β or μ near zero) would otherwise squeeze all points onto the zero line.
    const double errorCap = 3.0 * medianOfPositive(s.error);
    for (std::size_t i = 0; i < s.truth.size(); ++i) {
      double d = s.fit[i] - s.truth[i];
      if (s.name.isDirection()) d = std::remainder(d, 360.0);  // shortest difference, [−180°, 180°]
      const double e = s.error[i];
      const double pull = std::isfinite(e) && e > 0.0 ? d / e : kNaN;
      q.diff.push_back(d);
      q.pull.push_back(pull);
      if (!std::isfinite(d)) continue;
      q.truth.add(s.truth[i]);
      q.residual.add(d);
      if (std::isfinite(e) && e > 0.0) {
        const double shown = std::isfinite(errorCap) ? std::min(e, errorCap) : e;
        q.residual.add(d - shown);
        q.residual.add(d + shown);
      }
    }
    q.diffStats = meanWidth(q.diff);
    q.pullStats = meanWidth(q.pull);
    // Bins of 0.5 (0.25 from 200 pulls on): a handful of entries per bin near 0.
    q.pulls = Histogram(-kPullLimit, kPullLimit, q.pullStats.n >= 200 ? 40 : 20);
    for (double p : q.pull)
      if (std::isfinite(p)) q.pulls.fill(p);
    q.residual.add(0.0);  // the zero line is always in view
    out.push_back(std::move(q));
  }
  return out;
}

std::string samplesFile(const std::vector<Panel>& qs) {
  fmt::memory_buffer out;
  const auto put = std::back_inserter(out);
  fmt::format_to(put,
                 "# emcalign validation campaign: one gnuplot index block per quantity, one row per sample,\n"
                 "# file units. fit - truth is the shortest angular difference for angles that wrap;\n"
                 "# pull = (fit - truth)/error, NaN without a finite positive error.\n");
  for (std::size_t k = 0; k < qs.size(); ++k)
    fmt::format_to(put, "#   index {}: {} [{}]{}\n", k, commentText(std::string(qs[k].series->name.name())),
                   qs[k].series->name.unit(), qs[k].series->name.isDirection() ? " (wraps at 360 deg)" : "");
  fmt::format_to(put, "# columns: 1 truth  2 fit  3 error  4 fit-truth  5 pull\n");
  for (std::size_t k = 0; k < qs.size(); ++k) {
    const Panel& q = qs[k];
    const CampaignSeries& s = *q.series;
    fmt::format_to(put, "{}# index {}: {}\n", k > 0 ? "\n\n" : "", k, commentText(std::string(s.name.name())));
    for (std::size_t i = 0; i < s.truth.size(); ++i)
      fmt::format_to(put, "{} {} {} {} {}\n", dataNumber(s.truth[i]), dataNumber(s.fit[i]), dataNumber(s.error[i]),
                     dataNumber(q.diff[i]), dataNumber(q.pull[i]));
  }
  return fmt::to_string(out);
}

std::string pullsFile(const std::vector<Panel>& qs) {
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out),
                 "# emcalign validation campaign: histograms of the pulls (fit - truth)/error over "
                 "[-5, 5],\n# one gnuplot index block per quantity (the order of {}).\n"
                 "# columns: 1 bin centre  2 samples\n",
                 kSamplesFile);
  for (std::size_t k = 0; k < qs.size(); ++k) {
    const Histogram& h = qs[k].pulls;
    fmt::format_to(std::back_inserter(out), "{}# index {}: {}\n", k > 0 ? "\n\n" : "", k,
                   commentText(std::string(qs[k].series->name.name())));
    for (int i = 0; i < static_cast<int>(h.counts.size()); ++i)
      fmt::format_to(std::back_inserter(out), "{:.6g} {:.6g}\n", h.binCenter(i), h.counts[static_cast<std::size_t>(i)]);
  }
  return fmt::to_string(out);
}

int sampleCount(const std::vector<Panel>& qs) {
  std::size_t n = 0;
  for (const auto& q : qs) n = std::max(n, q.series->truth.size());
  return static_cast<int>(n);
}

constexpr const char* kCampaignStyles =
    "set style line 1 lc rgb '#000000' pt 7 ps 0.6 lw 1.0    # samples\n"
    "set style line 2 lc rgb '#808080' lw 1.2 dt 2           # zero\n"
    "set style line 3 lc rgb '#d62728' lw 2.0                # mean (bias), unit Gaussian\n"
    "set style line 4 lc rgb '#4a7ebb'                       # pull histogram\n";

// "; ψ, τ: shortest angular difference" for the quantities that wrap, or "".
std::string wrapNote(const std::vector<Panel>& qs) {
  std::vector<std::string> labels;
  for (const auto& q : qs)
    if (q.series->name.isDirection()) labels.push_back(q.label);
  if (labels.empty()) return "";
  return fmt::format("; {}: shortest angular difference", fmt::join(labels, ", "));
}

// Panel titles of the campaign figures: the quantity in bold, the numbers after it.
constexpr const char* kCampaignTitleFont = "set title offset 0,-0.3 font ',12'\n";

std::string pullsScript(const std::string& name, const std::vector<Panel>& qs) {
  const int n = static_cast<int>(qs.size());
  const int cols = campaignColumns(n);
  const Grid::Layout layout{105, 20, 112, 62, 34, 78, true};
  const Grid g(n, cols, Grid::widthFor(n, cols, 330, layout), 250, layout);
  double yMax = 0.0;
  for (const auto& q : qs) {
    for (double c : q.pulls.counts) yMax = std::max(yMax, c);
    yMax = std::max(yMax, q.pullStats.n * q.pulls.binWidth() / std::sqrt(2.0 * std::numbers::pi));
  }
  std::string s = terminalHeader(name, g.width, g.height) + kCampaignStyles;
  s += fmt::format("pulls = '{}'\ngauss(x, n, w) = n * w / sqrt(2 * pi) * exp(-0.5 * x * x)\n", kPullsFile);
  s += multiplotStart(
      fmt::format("Pulls (fit − truth)/σ_{{fit}} of the validation campaign — {} samples", sampleCount(qs)),
      "curve: the unit Gaussian, scaled to the number of pulls × bin width (what unbiased fits "
      "with right errors give); panel title: mean and width (standard deviation) of the pulls" +
          wrapNote(qs));
  s += kCampaignTitleFont;
  s += fmt::format(
      "set xrange [{0}:{1}]; set xtics -4,2,4; set mxtics 2\nset yrange [0:{2:.6g}]\n"
      "set samples 400\nset style fill solid 0.5 border lc rgb '#2a5e9b'\n",
      -kPullLimit, kPullLimit, std::max(1.0, std::ceil(1.2 * yMax)));
  for (int k = 0; k < n; ++k) {
    const Panel& q = qs[static_cast<std::size_t>(k)];
    s += fmt::format("\n# ---- {} (index {} of the pulls)\n", commentText(std::string(q.series->name.name())), k);
    s += g.panel(k, "(fit − truth)/σ_{fit}", fmt::format("samples / {:.2g}", q.pulls.binWidth()));
    std::string title;
    if (q.pullStats.n == 0) {
      title = fmt::format("{{/:Bold {}}}   no pulls (no finite error)", q.label);
    } else {
      title = fmt::format("{{/:Bold {}}}   mean {},  width {}", q.label, titleNumber(q.pullStats.mean, "{:.2f}"),
                          titleNumber(q.pullStats.width, "{:.2f}"));
      const double outside = q.pulls.underflow + q.pulls.overflow;
      if (outside > 0.0) title += fmt::format("  ({:.0f} beyond ±5)", outside);
    }
    s += fmt::format("set title \"{}\"\n", title);
    s += plotCommand({fmt::format("pulls index {} using 1:2 with boxes ls 4", k),
                      fmt::format("gauss(x, {}, {:.6g}) with lines ls 3", q.pullStats.n, q.pulls.binWidth())});
  }
  s += g.legend({"keyentry with boxes ls 4 title 'pulls of the samples'",
                 "keyentry with lines ls 3 title 'unit Gaussian N(0, 1)'"});
  s += "unset multiplot\n";
  return s;
}

std::string residualsVsTruthScript(const std::string& name, const std::vector<Panel>& qs) {
  const int n = static_cast<int>(qs.size());
  const int cols = campaignColumns(n);
  const Grid::Layout layout{95, 25, 140, 62, 100, 112, false};
  const Grid g(n, cols, Grid::widthFor(n, cols, 300, layout), 250, layout);
  std::string s = terminalHeader(name, g.width, g.height) + kCampaignStyles;
  s += fmt::format("samples = '{}'\n", kSamplesFile);
  s += multiplotStart(fmt::format("Fit − truth against truth, validation campaign — {} samples", sampleCount(qs)),
                      "error bars: the fit's σ; dashed: zero; red: the mean of fit − truth (the bias); panel "
                      "title: bias ± spread/√n and spread (standard deviation)" +
                          wrapNote(qs));
  s += kCampaignTitleFont;
  s += "set format x '%g'; set mxtics 2\n";
  for (int k = 0; k < n; ++k) {
    const Panel& q = qs[static_cast<std::size_t>(k)];
    const std::string unit(q.series->name.unit());
    const Range x = axisRange(q.truth), y = axisRange(q.residual);
    s += fmt::format("\n# ---- {} (index {} of the samples)\n", commentText(std::string(q.series->name.name())), k);
    s += g.panel(k, fmt::format("truth  [{}]", unit), fmt::format("fit − truth  [{}]", unit));
    // Angles that wrap span up to 360°: tics at multiples of 45° or 90°.
    const double span = x.hi - x.lo;
    const double xStep = !q.series->name.isDirection() ? ticStep(span, 4)
                         : span > 200.0                ? 90.0
                         : span > 100.0                ? 45.0
                                                       : ticStep(span, 4);
    s += fmt::format("set xrange [{:.9g}:{:.9g}]; set xtics {:.9g}\nset yrange [{:.9g}:{:.9g}]\n", x.lo, x.hi, xStep,
                     y.lo, y.hi);
    const MeanWidth& d = q.diffStats;
    const double biasError = d.n > 1 ? d.width / std::sqrt(static_cast<double>(d.n)) : kNaN;
    const int samples = static_cast<int>(q.series->truth.size());
    s += fmt::format("set title \"{{/:Bold {}}}\\n{{/=10 bias {} ± {} {},  spread {}{}}}\"\n", q.label,
                     titleNumber(d.mean, "{:.2g}"), titleNumber(biasError, "{:.1g}"), unit,
                     titleNumber(d.width, "{:.2g}"),
                     d.n < samples ? fmt::format("  ({} of {} samples)", d.n, samples) : "");
    std::vector<std::string> items = {"0 with lines ls 2"};
    if (std::isfinite(d.mean)) items.push_back(fmt::format("{:.9g} with lines ls 3", d.mean));
    items.push_back(fmt::format("samples index {} using 1:4:($3 == $3 ? $3 : 0) with yerrorbars ls 1", k));
    s += plotCommand(items);
  }
  s += g.legend({"keyentry with yerrorbars ls 1 title 'fit − truth ± σ_{fit}'",
                 "keyentry with lines ls 3 title 'mean (bias)'", "keyentry with lines ls 2 title 'zero'"});
  s += "unset multiplot\n";
  return s;
}

}  // namespace

Result<std::vector<std::string>> writeCampaignPlots(const std::string& dir, const std::vector<CampaignSeries>& series) {
  auto quantities = reduce(series);
  if (!quantities) return quantities.error();
  const fs::path out(dir);
  if (auto st = createPlotDirectory(out); !st) return st.error();
  if (auto st = writeFile(out, kSamplesFile, samplesFile(*quantities)); !st) return st.error();
  if (auto st = writeFile(out, kPullsFile, pullsFile(*quantities)); !st) return st.error();
  return drawFigures(out, {{"pulls", pullsScript("pulls", *quantities)},
                           {"residuals_vs_truth", residualsVsTruthScript("residuals_vs_truth", *quantities)}});
}

}  // namespace emcalign::report
