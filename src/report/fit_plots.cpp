// The figures of a fit (emcalign/report/fit_plots.hpp): the profiles with the fitted model
// (the numbers behind them, their data files and scripts) and the residuals before and after.
#include "emcalign/report/fit_plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iterator>
#include <limits>
#include <utility>

#include <fmt/format.h>

#include "emcalign/core/types.hpp"
#include "emcalign/core/units.hpp"
#include "gnuplot.hpp"
#include "multiplot.hpp"

namespace emcalign::report {

namespace {

namespace fs = std::filesystem;
using namespace detail;
using units::deg;

constexpr const char* kBinsFile = "profile_bins.dat";
constexpr const char* kModelVsPhiFile = "profile_model_vs_phi.dat";
constexpr const char* kModelVsThetaFile = "profile_model_vs_theta.dat";

// Colours and styles shared by the scripts (gnuplot `set style line`).
constexpr const char* kStyles =
    "set style line 1 lc rgb '#000000' pt 7 ps 0.7 lw 1.2    # profile points (used in the chi2)\n"
    "set style line 2 lc rgb '#a0a0a0' pt 6 ps 0.7 lw 1.0    # bins left out of the chi2\n"
    "set style line 3 lc rgb '#d62728' lw 2.0                # fitted model\n"
    "set style line 4 lc rgb '#555555' lw 1.2 dt 2           # model at eta = 0\n"
    "set style line 5 lc rgb '#1f77b4' pt 7 ps 0.7 lw 1.2    # second residual (profile_theta)\n"
    "set style line 6 lc rgb '#1f77b4' lw 2.0                # its fitted model\n"
    "set style line 7 lc rgb '#d62728' pt 5 ps 0.6 lw 1.2    # first residual (profile_theta)\n";

bool hasEntries(const calib::ProfileBin& b) {
  return b.n > 0 && std::isfinite(b.phiMean) && std::isfinite(b.thetaMean) && std::isfinite(b.energyMean) &&
         std::isfinite(b.yPhi) && std::isfinite(b.yTheta);
}

double finiteOrZero(double x) { return std::isfinite(x) ? x : 0.0; }

std::string fitSummary(const calib::FitResult& fit) {
  std::string s = fmt::format("χ^2/ndf = {:.1f}/{}", fit.chi2, fit.ndf);
  s += fmt::format(" ({})", name(fit.status));
  return s;
}

// The footnote of a figure: the model the fit used ("" without one).
std::string modelNote(const std::string& model) {
  return model.empty() ? std::string() : "model: " + literalText(model);
}

// A grid with room for the model's footnote when there is one.
GridLayout withFootnote(const std::string& model) {
  GridLayout layout;
  if (!model.empty()) layout.bottom += Grid::kFootnotePx;
  return layout;
}

// Mean of a quantity over the bins of a slice, weighted by the entries.
struct Slice {
  std::int64_t n = 0;
  double sumPhi = 0.0, sumTheta = 0.0;
  [[nodiscard]] double meanPhi() const { return n > 0 ? sumPhi / static_cast<double>(n) : kNaN; }
  [[nodiscard]] double meanTheta() const { return n > 0 ? sumTheta / static_cast<double>(n) : kNaN; }
};

// Everything the three profile figures need, computed once.
struct ProfileData {
  int nPhi = 0, nTheta = 0;
  std::vector<Slice> phiSlices, thetaSlices;
  double energy = 0.0;  // MeV, entry-weighted mean over all bins
  // f at each bin's own means (what the χ² compares), in the order of `bins`.
  std::vector<geometry::AngularResidual> atBins;
  std::string model;  // fitModelText, said after the fit's χ²
};

Result<ProfileData> summarise(const std::vector<calib::ProfileBin>& bins, const calib::FitGeometry& geometry,
                              const calib::FitResult& fit) {
  ProfileData d;
  for (const auto& b : bins) {
    if (b.iPhi < 0 || b.iTheta < 0 || b.iPhi >= 1000 || b.iTheta >= 1000)
      return Error{fmt::format("profile bin ({}, {}): bin index out of range [0, 1000)", b.iPhi, b.iTheta)};
    d.nPhi = std::max(d.nPhi, b.iPhi + 1);
    d.nTheta = std::max(d.nTheta, b.iTheta + 1);
  }
  d.phiSlices.resize(static_cast<std::size_t>(d.nPhi));
  d.thetaSlices.resize(static_cast<std::size_t>(d.nTheta));
  std::int64_t n = 0;
  double sumE = 0.0;
  for (const auto& b : bins) {
    geometry::AngularResidual f{kNaN, kNaN};
    if (hasEntries(b)) {
      for (Slice* s :
           {&d.phiSlices[static_cast<std::size_t>(b.iPhi)], &d.thetaSlices[static_cast<std::size_t>(b.iTheta)]}) {
        s->n += b.n;
        s->sumPhi += static_cast<double>(b.n) * b.phiMean;
        s->sumTheta += static_cast<double>(b.n) * b.thetaMean;
      }
      n += b.n;
      sumE += static_cast<double>(b.n) * b.energyMean;
      f = calib::modelAt(geometry, fit.parameters.values, b.phiMean, b.thetaMean, b.energyMean);
    }
    d.atBins.push_back(f);
  }
  if (n == 0) return Error{"profile bins: no bin has entries, nothing to plot"};
  d.energy = sumE / static_cast<double>(n);
  return d;
}

// χ² contribution of the used bins selected by `inSlice` (φ part, θ part, or both).
struct SliceChi2 {
  double chi2 = 0.0;
  int terms = 0;
};

template <typename Pred>
SliceChi2 sliceChi2(const std::vector<calib::ProfileBin>& bins, const ProfileData& d, Pred inSlice, bool phiPart,
                    bool thetaPart) {
  SliceChi2 c;
  for (std::size_t k = 0; k < bins.size(); ++k) {
    const auto& b = bins[k];
    if (!b.used || !inSlice(b) || !hasEntries(b)) continue;
    if (phiPart) {
      c.chi2 += std::pow((b.yPhi - d.atBins[k].phi) / b.sigmaPhi, 2);
      ++c.terms;
    }
    if (thetaPart) {
      c.chi2 += std::pow((b.yTheta - d.atBins[k].theta) / b.sigmaTheta, 2);
      ++c.terms;
    }
  }
  return c;
}

// ---- data files

std::string binsFile(const std::vector<calib::ProfileBin>& bins) {
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out),
                 "# emcalign profile bins (bins without entries left out), angles in degrees.\n"
                 "# y_phi is sin(phi_TS,R - phi_EMC)*180/pi, y_theta is theta_TS,R - theta_EMC;\n"
                 "# sigma is the total (stat + sys) the chi2 uses; used = 1 if the bin is in the chi2.\n"
                 "# columns: 1 phi_emc  2 theta_emc  3 y_phi  4 sigma_phi  5 y_theta  6 sigma_theta"
                 "  7 used  8 n  9 i_phi  10 i_theta  11 e_mev\n");
  for (const auto& b : bins) {
    if (!hasEntries(b)) continue;
    fmt::format_to(std::back_inserter(out), "{:.6f} {:.6f} {:.6g} {:.6g} {:.6g} {:.6g} {} {} {} {} {:.6g}\n",
                   b.phiMean / deg, b.thetaMean / deg, b.yPhi / deg, finiteOrZero(b.sigmaPhi) / deg, b.yTheta / deg,
                   finiteOrZero(b.sigmaTheta) / deg, b.used ? 1 : 0, b.n, b.iPhi, b.iTheta, b.energyMean);
  }
  return fmt::to_string(out);
}

// One curve sample: fitted and nominal model at (φ, θ), degrees.
void writeCurvePoint(fmt::memory_buffer& out, double x, const geometry::AngularResidual& f,
                     const geometry::AngularResidual& f0, int slice) {
  if (!std::isfinite(f.phi) || !std::isfinite(f.theta)) {
    fmt::format_to(std::back_inserter(out), "\n");  // breaks the line
    return;
  }
  fmt::format_to(std::back_inserter(out), "{:.4f} {:.6g} {:.6g} {:.6g} {:.6g} {}\n", x, f.phi / deg, f.theta / deg,
                 f0.phi / deg, f0.theta / deg, slice);
}

constexpr const char* kCurveColumns =
    "  2 f_phi (sin dphi*180/pi)  3 f_theta  4 f_phi at eta=0  5 f_theta at eta=0  6 slice\n";

// f(φ) per θ slice at the slice's mean θ and the mean energy; one segment per hemisphere.
std::string modelVsPhiFile(const ProfileData& d, const calib::FitGeometry& geometry, const calib::FitResult& fit,
                           Range& phiRange, Range& thetaRange) {
  const geometry::ParamVector eta = fit.parameters.values;
  const geometry::ParamVector zero = geometry::ParamVector::Zero();
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out),
                 "# emcalign fitted model against phi_EMC, per theta slice (column 6 = i_theta), at the\n"
                 "# slice's mean theta_EMC and E = {:.1f} MeV; degrees; blank lines separate the\n"
                 "# hemispheres (the model jumps at 90 and 270 deg).\n"
                 "# columns: 1 phi_emc{}",
                 d.energy, kCurveColumns);
  // The model takes hemisphere s = sign(cos φ); sample each side up to its edge.
  const double edge = 1e-3;  // deg, printed exactly by {:.4f}
  const double segments[3][2] = {{0.0, 90.0 - edge}, {90.0 + edge, 270.0 - edge}, {270.0 + edge, 360.0}};
  for (int j = 0; j < d.nTheta; ++j) {
    const double theta = d.thetaSlices[static_cast<std::size_t>(j)].meanTheta();
    if (!std::isfinite(theta)) continue;
    for (const auto& seg : segments) {
      const int steps = static_cast<int>(std::ceil((seg[1] - seg[0]) / 0.5));
      for (int k = 0; k <= steps; ++k) {
        const double phiDeg = seg[0] + (seg[1] - seg[0]) * k / steps;
        const auto f = calib::modelAt(geometry, eta, phiDeg * deg, theta, d.energy);
        const auto f0 = calib::modelAt(geometry, zero, phiDeg * deg, theta, d.energy);
        writeCurvePoint(out, phiDeg, f, f0, j);
        phiRange.add(f.phi / deg);
        phiRange.add(f0.phi / deg);
        thetaRange.add(f.theta / deg);
        thetaRange.add(f0.theta / deg);
      }
      fmt::format_to(std::back_inserter(out), "\n");
    }
  }
  return fmt::to_string(out);
}

// f(θ) per φ slice at the slice's mean φ and the mean energy, over [thetaLo, thetaHi] (deg).
std::string modelVsThetaFile(const ProfileData& d, const calib::FitGeometry& geometry, const calib::FitResult& fit,
                             double thetaLoDeg, double thetaHiDeg, Range& range) {
  const geometry::ParamVector eta = fit.parameters.values;
  const geometry::ParamVector zero = geometry::ParamVector::Zero();
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out),
                 "# emcalign fitted model against theta_EMC, per phi slice (column 6 = i_phi), at the\n"
                 "# slice's mean phi_EMC and E = {:.1f} MeV; degrees.\n"
                 "# columns: 1 theta_emc{}",
                 d.energy, kCurveColumns);
  const int steps = std::max(1, static_cast<int>(std::ceil((thetaHiDeg - thetaLoDeg) / 0.5)));
  for (int i = 0; i < d.nPhi; ++i) {
    const double phi = d.phiSlices[static_cast<std::size_t>(i)].meanPhi();
    if (!std::isfinite(phi)) continue;
    for (int k = 0; k <= steps; ++k) {
      const double thetaDeg = thetaLoDeg + (thetaHiDeg - thetaLoDeg) * k / steps;
      const auto f = calib::modelAt(geometry, eta, phi, thetaDeg * deg, d.energy);
      const auto f0 = calib::modelAt(geometry, zero, phi, thetaDeg * deg, d.energy);
      writeCurvePoint(out, thetaDeg, f, f0, i);
      for (double y : {f.phi, f.theta, f0.phi, f0.theta}) range.add(y / deg);
    }
    fmt::format_to(std::back_inserter(out), "\n");
  }
  return fmt::to_string(out);
}

// ---- scripts

// The header of the fit figures: terminal, their line styles and the bins file.
std::string scriptHeader(const std::string& pngName, int width, int height) {
  return terminalHeader(pngName, width, height) + kStyles + fmt::format("bins = '{}'\n", kBinsFile);
}

// The profile against φ of one residual (Δφ or Δθ), one panel per θ slice.
std::string profileVsPhiScript(const std::string& name, bool phiResidual, const std::vector<calib::ProfileBin>& bins,
                               const ProfileData& d, const calib::FitResult& fit, Range yRange) {
  const Grid g(d.nTheta, 5, 1900, 300, withFootnote(d.model));
  std::string s = scriptHeader(name, g.width, g.height);
  s += fmt::format("model = '{}'\n", kModelVsPhiFile);
  s += multiplotStart(fmt::format("{} profiles against φ_{{EMC}}, per θ_{{EMC}} slice — fit {}",
                                  phiResidual ? "sin Δφ" : "Δθ", fitSummary(fit)),
                      fmt::format("error bars: the σ of the χ^2 (stat ⊕ sys); curves at the slice's mean θ_{{EMC}} and "
                                  "E = {:.0f} MeV, broken where the hemispheres meet (90°, 270°)",
                                  d.energy));
  s += fmt::format(
      "set xrange [0:360]; set xtics 0,90,360; set mxtics 3\n"
      "set yrange [{:.6g}:{:.6g}]\n"
      "set arrow 1 from 90, graph 0 to 90, graph 1 nohead lc rgb '#b0b0b0' dt 3 back\n"
      "set arrow 2 from 270, graph 0 to 270, graph 1 nohead lc rgb '#b0b0b0' dt 3 back\n",
      yRange.lo, yRange.hi);
  const std::string ylabel = phiResidual ? "sin(φ_{TS} − φ_{EMC}) · 180/π  [deg]" : "θ_{TS} − θ_{EMC}  [deg]";
  const int yCol = phiResidual ? 3 : 5, fCol = phiResidual ? 2 : 3, f0Col = phiResidual ? 4 : 5;
  bool anyLeftOut = false;
  for (int j = 0; j < d.nTheta; ++j) {
    const Slice& slice = d.thetaSlices[static_cast<std::size_t>(j)];
    s += fmt::format("\n# ---- theta slice {} (column 10 of the bins, column 6 of the model)\n", j);
    s += g.panel(j, "φ_{EMC}  [deg]", ylabel);
    int used = 0, leftOut = 0;
    for (const auto& b : bins) {
      if (b.iTheta == j && hasEntries(b)) (b.used ? used : leftOut) += 1;
    }
    anyLeftOut = anyLeftOut || leftOut > 0;
    const auto c = sliceChi2(
        bins, d, [j](const calib::ProfileBin& b) { return b.iTheta == j; }, phiResidual, !phiResidual);
    if (slice.n == 0)
      s += "set title 'no entries'\n";
    else
      s += fmt::format("set title \"θ_{{EMC}} ≈ {:.1f}°     χ^2_{{{}}} = {:.1f} / {} bins\"\n", slice.meanTheta() / deg,
                       phiResidual ? "φ" : "θ", c.chi2, c.terms);
    std::vector<std::string> items = {"NaN notitle"};
    if (slice.n > 0) {
      items.push_back(fmt::format("model using 1:($6=={} ? ${} : NaN) with lines ls 4", j, f0Col));
      items.push_back(fmt::format("model using 1:($6=={} ? ${} : NaN) with lines ls 3", j, fCol));
    }
    if (leftOut > 0)
      items.push_back(
          fmt::format("bins using 1:(($10=={} && $7==0) ? ${} : NaN):{} with yerrorbars ls 2", j, yCol, yCol + 1));
    if (used > 0)
      items.push_back(
          fmt::format("bins using 1:(($10=={} && $7==1) ? ${} : NaN):{} with yerrorbars ls 1", j, yCol, yCol + 1));
    s += plotCommand(items);
  }
  std::vector<std::string> legend = {"keyentry with yerrorbars ls 1 title 'profile mean ± σ'"};
  if (anyLeftOut) legend.push_back("keyentry with yerrorbars ls 2 title 'left out of the χ^2'");
  legend.push_back("keyentry with lines ls 3 title 'fit'");
  legend.push_back("keyentry with lines ls 4 title 'η = 0'");
  s += g.legend(legend);
  s += g.footnote(modelNote(d.model));
  s += "unset multiplot\n";
  return s;
}

// Both residuals against θ, one panel per φ slice.
std::string profileVsThetaScript(const std::string& name, const std::vector<calib::ProfileBin>& bins,
                                 const ProfileData& d, const calib::FitResult& fit, double thetaLoDeg,
                                 double thetaHiDeg, Range yRange) {
  const Grid g(d.nPhi, static_cast<int>(std::ceil(std::sqrt(static_cast<double>(d.nPhi)))), 1700, 250,
               withFootnote(d.model));
  std::string s = scriptHeader(name, g.width, g.height);
  s += fmt::format("model = '{}'\n", kModelVsThetaFile);
  s += multiplotStart(
      fmt::format("sin Δφ and Δθ profiles against θ_{{EMC}}, per φ_{{EMC}} slice — fit {}", fitSummary(fit)),
      fmt::format("error bars: the σ of the χ^2 (stat ⊕ sys); curves at the slice's mean φ_{{EMC}} and "
                  "E = {:.0f} MeV; (+), (−): hemisphere, cos φ_{{EMC}} ≥ 0 or < 0; panel χ^2 / number of "
                  "terms (both residuals)",
                  d.energy));
  s += fmt::format("set xrange [{:.6g}:{:.6g}]; set xtics 60,30,120; set mxtics 2\nset yrange [{:.6g}:{:.6g}]\n",
                   thetaLoDeg, thetaHiDeg, yRange.lo, yRange.hi);
  bool anyLeftOut = false;
  for (int i = 0; i < d.nPhi; ++i) {
    const Slice& slice = d.phiSlices[static_cast<std::size_t>(i)];
    s += fmt::format("\n# ---- phi slice {} (column 9 of the bins, column 6 of the model)\n", i);
    s += g.panel(i, "θ_{EMC}  [deg]", "residual  [deg]");
    int used = 0, leftOut = 0;
    for (const auto& b : bins) {
      if (b.iPhi == i && hasEntries(b)) (b.used ? used : leftOut) += 1;
    }
    anyLeftOut = anyLeftOut || leftOut > 0;
    const auto c = sliceChi2(
        bins, d, [i](const calib::ProfileBin& b) { return b.iPhi == i; }, true, true);
    if (slice.n == 0) {
      s += "set title 'no entries'\n";
    } else {
      const double phi = slice.meanPhi();
      s += fmt::format("set title \"φ_{{EMC}} ≈ {:.1f}° ({})     χ^2 = {:.1f} / {}\"\n", phi / deg,
                       std::cos(phi) >= 0.0 ? "+" : "−", c.chi2, c.terms);
    }
    std::vector<std::string> items = {"NaN notitle"};
    if (slice.n > 0) {
      for (int col : {4, 5}) items.push_back(fmt::format("model using 1:($6=={} ? ${} : NaN) with lines ls 4", i, col));
      items.push_back(fmt::format("model using 1:($6=={} ? $2 : NaN) with lines ls 3", i));
      items.push_back(fmt::format("model using 1:($6=={} ? $3 : NaN) with lines ls 6", i));
    }
    if (leftOut > 0) {
      for (int col : {3, 5})
        items.push_back(
            fmt::format("bins using 2:(($9=={} && $7==0) ? ${} : NaN):{} with yerrorbars ls 2", i, col, col + 1));
    }
    if (used > 0) {
      items.push_back(fmt::format("bins using 2:(($9=={} && $7==1) ? $3 : NaN):4 with yerrorbars ls 7", i));
      items.push_back(fmt::format("bins using 2:(($9=={} && $7==1) ? $5 : NaN):6 with yerrorbars ls 5", i));
    }
    s += plotCommand(items);
  }
  std::vector<std::string> legend = {
      "keyentry with yerrorbars ls 7 title 'sin Δφ · 180/π'", "keyentry with lines ls 3 title 'fit, sin Δφ'",
      "keyentry with yerrorbars ls 5 title 'Δθ'", "keyentry with lines ls 6 title 'fit, Δθ'"};
  if (anyLeftOut) legend.push_back("keyentry with yerrorbars ls 2 title 'left out of the χ^2'");
  legend.push_back("keyentry with lines ls 4 title 'η = 0'");
  s += g.legend(legend);
  s += g.footnote(modelNote(d.model));
  s += "unset multiplot\n";
  return s;
}

// ---- residuals before and after the correction

// Histogram blocks (gnuplot index 0..3) and the x range that holds the bulk of them.
std::string histogramsFile(const ResidualHistograms& r) {
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out),
                 "# emcalign residual distributions of the selected particles, degrees.\n"
                 "# blocks (gnuplot index): 0 dphi before, 1 dphi after, 2 dtheta before, 3 dtheta after\n"
                 "# columns: 1 bin centre  2 count  3 low edge  4 high edge\n");
  const Histogram* hs[4] = {&r.dPhiBefore, &r.dPhiAfter, &r.dThetaBefore, &r.dThetaAfter};
  for (int k = 0; k < 4; ++k) {
    const Histogram& h = *hs[k];
    if (k > 0) fmt::format_to(std::back_inserter(out), "\n\n");
    for (int i = 0; i < static_cast<int>(h.counts.size()); ++i) {
      fmt::format_to(std::back_inserter(out), "{:.6g} {:.6g} {:.6g} {:.6g}\n", h.binCenter(i),
                     h.counts[static_cast<std::size_t>(i)], h.low + i * h.binWidth(), h.low + (i + 1) * h.binWidth());
    }
  }
  return fmt::to_string(out);
}

// The range [0.1%, 99.9%] quantiles of both histograms, widened by 30%, inside the histogram.
Range bulkRange(const Histogram& a, const Histogram& b) {
  Range r;
  for (const Histogram* h : {&a, &b}) {
    const double total = h->entries();
    if (total <= 0.0) continue;
    double cum = 0.0;
    for (int i = 0; i < static_cast<int>(h->counts.size()); ++i) {
      const double before = cum;
      cum += h->counts[static_cast<std::size_t>(i)];
      if (before < 0.001 * total && cum >= 0.001 * total) r.add(h->low + i * h->binWidth());
      if (before < 0.999 * total && cum >= 0.999 * total) r.add(h->low + (i + 1) * h->binWidth());
    }
  }
  if (!(r.hi > r.lo)) return Range{a.low, a.high};
  const double pad = 0.3 * (r.hi - r.lo);
  return Range{std::max(std::min(a.low, b.low), r.lo - pad), std::min(std::max(a.high, b.high), r.hi + pad)};
}

std::string histogramKey(const char* when, const Histogram& h) {
  std::string s = fmt::format("{}: N = {:.0f}, mean = {:.3f}°, rms = {:.3f}°", when, h.entries(), h.mean(), h.rms());
  const double outside = h.underflow + h.overflow;
  if (outside > 0.0) s += fmt::format(" ({:.0f} outside)", outside);
  return s;
}

std::string residualsScript(const std::string& name, const ResidualHistograms& r, const calib::FitResult& fit,
                            const std::string& model) {
  std::string s = scriptHeader(name, 1600, 650);
  s += "hist = 'residuals_before_after.dat'\n";
  s += fmt::format(
      "set multiplot layout 1,2 title \"Residuals of the selected particles before (filled) and "
      "after (open) "
      "the correction — fit {}{}\" font ',14' margins 0.07,0.98,0.13,0.84 spacing 0.08,0.1\n",
      fitSummary(fit), model.empty() ? std::string() : "\\n{/=11 model: " + literalText(model) + "}");
  s += "set grid lc rgb '#e0e0e0' lt 1\nset tics front\nset style fill solid 0.45 noborder\n"
       "set key top left reverse Left samplen 2 font ',11'\n";
  struct Panel {
    const Histogram *before, *after;
    const char *xlabel, *title;
    int index;
  };
  const Panel panels[2] = {{&r.dPhiBefore, &r.dPhiAfter, "Δφ = φ_{TS} − φ_{EMC}  [deg]", "Δφ", 0},
                           {&r.dThetaBefore, &r.dThetaAfter, "Δθ = θ_{TS} − θ_{EMC}  [deg]", "Δθ", 2}};
  for (const Panel& p : panels) {
    const Range x = bulkRange(*p.before, *p.after);
    double yMax = 0.0;
    for (const Histogram* h : {p.before, p.after})
      for (double c : h->counts) yMax = std::max(yMax, c);
    s += fmt::format("\n# ---- {}\n", p.title);
    s += fmt::format("set xrange [{:.6g}:{:.6g}]\nset yrange [0:{:.6g}]\n", x.lo, x.hi, yMax > 0.0 ? 1.35 * yMax : 1.0);
    s += fmt::format("set xlabel \"{}\"\nset ylabel \"particles / {:.2g}°\"\n", p.xlabel, p.before->binWidth());
    s += fmt::format(
        "plot hist index {} using 1:2 with boxes lc rgb '#4a7ebb' title \"{}\", \\\n"
        "     hist index {} using 1:2 with histeps lw 2 lc rgb '#000000' title \"{}\"\n",
        p.index, histogramKey("before", *p.before), p.index + 1, histogramKey("after", *p.after));
  }
  s += "unset multiplot\n";
  return s;
}

}  // namespace

std::string fitModelText(const calib::FitGeometry& geometry, const calib::ProfileOptions& profile,
                         const std::string& corrections) {
  std::vector<std::string> on;
  if (geometry.depth.offset != 0.0)
    on.push_back(fmt::format("depth offset {:+.2f} cm", geometry.depth.offset / units::cm));
  if (profile.partingPlane) on.push_back("parting plane");
  if (profile.nominalProfile) on.push_back("nominal pattern");
  if (geometry.response) on.push_back("fit response");
  if (on.empty()) return "the paper's model, no corrections";
  if (corrections.empty()) return fmt::format("the paper's model with {}", fmt::join(on, ", "));
  return fmt::format("corrections {}: {}", fs::path(corrections).filename().string(), fmt::join(on, ", "));
}

Result<std::vector<std::string>> writeFitPlots(const std::string& dir, const std::vector<calib::ProfileBin>& bins,
                                               const calib::FitGeometry& geometry, const calib::FitResult& fit,
                                               const ResidualHistograms* residuals, const std::string& model) {
  auto summary = summarise(bins, geometry, fit);
  if (!summary) return summary.error();
  ProfileData& d = *summary;
  d.model = model;

  const fs::path out(dir);
  if (auto st = createPlotDirectory(out); !st) return st.error();

  // Data files, and the y ranges: used points ± σ and the curves.
  Range phiRange, thetaRange;
  double thetaLo = std::numeric_limits<double>::infinity(), thetaHi = -thetaLo;
  for (const auto& b : bins) {
    if (!hasEntries(b)) continue;
    thetaLo = std::min(thetaLo, b.thetaMean / deg);
    thetaHi = std::max(thetaHi, b.thetaMean / deg);
    if (!b.used) continue;
    for (double sign : {-1.0, 1.0}) {
      phiRange.add((b.yPhi + sign * b.sigmaPhi) / deg);
      thetaRange.add((b.yTheta + sign * b.sigmaTheta) / deg);
    }
  }
  // θ axis: the slice means plus half a slice width on each side (45°–135° for docs/contract.md §7).
  const double halfSlice = d.nTheta > 1 ? 0.5 * (thetaHi - thetaLo) / (d.nTheta - 1) : 5.0;
  thetaLo -= halfSlice;
  thetaHi += halfSlice;
  Range bothRange = phiRange;
  bothRange.add(thetaRange.lo);
  bothRange.add(thetaRange.hi);

  const std::string modelVsPhi = modelVsPhiFile(d, geometry, fit, phiRange, thetaRange);
  const std::string modelVsTheta = modelVsThetaFile(d, geometry, fit, thetaLo, thetaHi, bothRange);
  const double minSpan = 0.05;  // deg
  const struct {
    const char* name;
    std::string data;
  } files[] = {{kBinsFile, binsFile(bins)}, {kModelVsPhiFile, modelVsPhi}, {kModelVsThetaFile, modelVsTheta}};
  for (const auto& f : files)
    if (auto st = writeFile(out, f.name, f.data); !st) return st.error();

  std::vector<Figure> figures = {
      {"profile_phi", profileVsPhiScript("profile_phi", true, bins, d, fit, phiRange.padded(minSpan))},
      {"profile_theta_vs_phi",
       profileVsPhiScript("profile_theta_vs_phi", false, bins, d, fit, thetaRange.padded(minSpan))},
      {"profile_theta",
       profileVsThetaScript("profile_theta", bins, d, fit, thetaLo, thetaHi, bothRange.padded(minSpan))}};
  if (residuals != nullptr) {
    const std::pair<const char*, const Histogram*> hs[] = {{"dPhiBefore", &residuals->dPhiBefore},
                                                           {"dPhiAfter", &residuals->dPhiAfter},
                                                           {"dThetaBefore", &residuals->dThetaBefore},
                                                           {"dThetaAfter", &residuals->dThetaAfter}};
    for (const auto& [what, h] : hs) {
      if (h->counts.empty() || !(h->high > h->low))
        return Error{
            fmt::format("residual histogram {}: needs at least one bin and low < high (got {} bins "
                        "over [{}, {}])",
                        what, h->counts.size(), h->low, h->high)};
    }
    if (auto st = writeFile(out, "residuals_before_after.dat", histogramsFile(*residuals)); !st) return st.error();
    figures.push_back({"residuals_before_after", residualsScript("residuals_before_after", *residuals, fit, model)});
  }

  return drawFigures(out, figures);
}

}  // namespace emcalign::report
