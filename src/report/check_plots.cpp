#include "emcalign/report/check_plots.hpp"

#include <array>
#include <cmath>
#include <iterator>

#include <fmt/format.h>

#include "emcalign/report/histogram.hpp"
#include "gnuplot.hpp"

namespace emcalign::report {

namespace {

using namespace detail;
namespace fs = std::filesystem;

// Text of ours in a double-quoted gnuplot string (enhanced mode: the labels may use ^ and _).
std::string gnuplotQuoted(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out;
}

std::string dataOf(const std::vector<BeforeAfterPanel>& panels) {
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out),
                 "# emcalign physics check: per panel an index block (columns: bin centre, events before, events "
                 "after the correction)\n");
  for (const auto& p : panels) {
    Histogram before(p.low, p.high, p.bins), after(p.low, p.high, p.bins);
    for (double x : p.before) before.fill(x);
    for (double x : p.after) after.fill(x);
    for (int i = 0; i < p.bins; ++i) {
      fmt::format_to(std::back_inserter(out), "{:.6g} {:.0f} {:.0f}\n", before.binCenter(i),
                     before.counts[static_cast<std::size_t>(i)], after.counts[static_cast<std::size_t>(i)]);
    }
    fmt::format_to(std::back_inserter(out), "\n\n");
  }
  return fmt::to_string(out);
}

std::string scriptOf(const std::string& name, const std::string& title, const std::vector<BeforeAfterPanel>& panels) {
  std::string s = terminalHeader(name, 800 * static_cast<int>(panels.size()), 650);
  s += fmt::format("data = '{}.dat'\n", name);
  // 140 pixels on the left of the first panel for five-digit tick labels and the axis title.
  const double left = 140.0 / (800.0 * static_cast<double>(panels.size()));
  s += fmt::format("set multiplot layout 1,{} title \"{}\" font ',14' margins {:.3f},0.98,0.13,0.88 spacing 0.08,0.1\n",
                   panels.size(), gnuplotQuoted(title), left);
  s += "set grid lc rgb '#e0e0e0' lt 1\nset tics front\nset key top right Left reverse samplen 2 font ',10'\n"
       "set yrange [0:*]\nset offsets 0, 0, graph 0.25, 0\nset style fill solid 0.35 noborder\n";
  for (std::size_t k = 0; k < panels.size(); ++k) {
    const auto& p = panels[k];
    const double width = (p.high - p.low) / p.bins;
    s += fmt::format("\nset xlabel \"{}\"\nset ylabel \"events / {:.3g}{}\"\nset xrange [{}:{}]\n", p.xlabel, width,
                     p.unit.empty() ? std::string() : " " + p.unit, p.low, p.high);
    s += fmt::format(
        "plot data index {} using 1:2 with boxes lc rgb '#1f77b4' title \"{}\", \\\n"
        "     data index {} using 1:3 with histeps lw 2 lc rgb '#d62728' title \"{}\"",
        k, gnuplotQuoted(p.beforeLabel), k, gnuplotQuoted(p.afterLabel));
    if (p.chi2Ndf > 0) {
      // The χ² density of ndf, scaled to the events after the correction (ndf = 2: exp(−x/2)/2).
      const double n = static_cast<double>(p.after.size()) * width;
      if (p.chi2Ndf == 2) {
        s += fmt::format(
            ", \\\n     {:.8g} * exp(-x / 2) / 2 with lines dt 2 lw 1.5 lc rgb '#444444' title "
            "\"χ^2 density, ndf 2\"",
            n);
      } else {
        const double k2 = p.chi2Ndf / 2.0;
        s += fmt::format(
            ", \\\n     {:.8g} * x**({:.6g}) * exp(-x / 2) / (2**{:.6g} * gamma({:.6g})) with lines dt 2 "
            "lw 1.5 lc rgb '#444444' title \"χ^2 density, ndf {}\"",
            n, k2 - 1.0, k2, k2, p.chi2Ndf);
      }
    }
    s += "\n";
  }
  return s + "unset multiplot\n";
}

}  // namespace

Result<std::string> writeBeforeAfterPlot(const std::string& dir, const std::string& name, const std::string& title,
                                         const std::vector<BeforeAfterPanel>& panels) {
  if (panels.empty()) return Error{fmt::format("{}: no panel to draw", name)};
  const fs::path out(dir);
  if (Status s = createPlotDirectory(out); !s) return s.error();
  if (Status s = writeFile(out, name + ".dat", dataOf(panels)); !s) return s.error();
  auto pngs = drawFigures(out, {{name, scriptOf(name, title, panels)}});
  if (!pngs) return pngs.error();
  return pngs->front();
}

namespace {

std::string fixedOrDash(double v, int digits) { return std::isfinite(v) ? fmt::format("{:.{}f}", v, digits) : "—"; }

}  // namespace

CheckFigure checkFigure(const apply::GammaGammaCheck& check, const apply::CheckRecord& record) {
  auto label = [](const char* when, const apply::CheckWidth& w) {
    return fmt::format("{}: σ_{{core}} {}°, rms {}°", when, fixedOrDash(w.width, 3), fixedOrDash(w.rms, 3));
  };
  const apply::CheckSide &b = record.before, &a = record.after;
  CheckFigure f;
  f.name = "acollinearity";
  f.title = "e+e- → γγ: acollinearity before and after the correction";
  f.panels.push_back({"Δφ = |φ_1 − φ_2| − 180°  [deg]", -6.0, 6.0, 60, check.dphi[0], check.dphi[1],
                      label("before", b.dphi), label("after", a.dphi), 0, "deg"});
  f.panels.push_back({"Δθ = θ_1 + θ_2 − 180°  [deg]", -15.0, 15.0, 60, check.dtheta[0], check.dtheta[1],
                      label("before", b.dtheta), label("after", a.dtheta), 0, "deg"});
  f.summary = fmt::format("check gg: {} of {} events selected; Δφ core width {}° -> {}° ({}% better), Δθ {}° -> {}°",
                          record.selected, check.cutFlow.events.front(), fixedOrDash(b.dphi.width, 3),
                          fixedOrDash(a.dphi.width, 3), fixedOrDash(record.improvement.dphiWidth, 1),
                          fixedOrDash(b.dtheta.width, 3), fixedOrDash(a.dtheta.width, 3));
  return f;
}

CheckFigure checkFigure(const apply::ThreePionCheck& check, const apply::CheckRecord& record) {
  std::array<std::vector<double>, 2> chi2;
  for (std::size_t k = 0; k < 2; ++k) {
    for (const auto& fit : check.fits[k]) {
      if (fit.converged) chi2[k].push_back(fit.chi2);
    }
  }
  const apply::CheckSide &b = record.before, &a = record.after;
  CheckFigure f;
  f.name = "chi2";
  f.title = "e+e- → π+π−π0: kinematic fit before and after the correction";
  f.panels.push_back({"χ^2 of the kinematic fit (ndf 2)", 0.0, 30.0, 60, chi2[0], chi2[1],
                      fmt::format("before: mean {}", fixedOrDash(b.chi2Mean, 2)),
                      fmt::format("after: mean {}", fixedOrDash(a.chi2Mean, 2)), 2, ""});
  f.summary =
      fmt::format("check 3pi: {} of {} events selected; mean χ² {} -> {} ({}% lower); not converged {} / {}",
                  record.selected, check.cutFlow.events.front(), fixedOrDash(b.chi2Mean, 3), fixedOrDash(a.chi2Mean, 3),
                  fixedOrDash(record.improvement.chi2Mean, 1), b.notConverged, a.notConverged);
  return f;
}

}  // namespace emcalign::report
