#include "emcalign/report/compare_plots.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>

#include <fmt/format.h>

#include "emcalign/calib/profiles.hpp"
#include "emcalign/core/units.hpp"
#include "gnuplot.hpp"

namespace emcalign::report {

namespace {

using namespace detail;
namespace fs = std::filesystem;

// A histogram bin drawn between finite edges (the open tails end at the range).
std::pair<double, double> edges(const apply::ComparedDistribution::Bin& b, double centre, double range) {
  return {std::isfinite(b.low) ? b.low : centre - range, std::isfinite(b.high) ? b.high : centre + range};
}

double centreOf(const apply::Comparison& c, std::size_t k) {
  return k == 0 ? c.options.phiCentreDeg : c.options.thetaCentreDeg;
}

// compare.dat: index 0/1 the Δφ/Δθ bins (centre, low, high, data and MC in particles per
// degree scaled to the data's particles, their errors, pull); index 2/3 the profile pulls
// (i_phi, i_theta, pull) of ȳ_φ and ȳ_θ, one gnuplot block per i_phi row.
std::string dataOf(const apply::Comparison& c) {
  fmt::memory_buffer out;
  auto put = std::back_inserter(out);
  fmt::format_to(put,
                 "# emcalign compare: index 0 dphi, 1 dtheta (columns: centre, low, high [deg], data, data error, MC, "
                 "MC error [particles/deg, MC scaled to the data's particles], pull); index 2 profile_phi, 3 "
                 "profile_theta (columns: the bin's phi_EMC and theta_EMC centres [deg], pull)\n");
  const double n = static_cast<double>(c.dataParticles);
  for (std::size_t k = 0; k < 2; ++k) {
    for (const auto& b : c.distributions[k].bins) {
      const auto [lo, hi] = edges(b, centreOf(c, k), c.options.rangeDeg);
      const double w = hi - lo;
      fmt::format_to(put, "{:.6g} {:.6g} {:.6g} {:.8g} {:.8g} {:.8g} {:.8g} {:.5g}\n", 0.5 * (lo + hi), lo, hi,
                     b.data * n / w, b.dataError * n / w, b.mc * n / w, b.mcError * n / w, b.pull);
    }
    fmt::format_to(put, "\n\n");
  }
  for (std::size_t k = 2; k < 4; ++k) {
    // Every cell of the map, NaN where the bin was not compared.
    std::vector<double> pulls(static_cast<std::size_t>(c.options.profilePhiBins * c.options.profileThetaBins),
                              std::nan(""));
    for (const auto& b : c.distributions[k].bins) pulls[static_cast<std::size_t>(b.low)] = b.pull;
    for (int i = 0; i < c.options.profilePhiBins; ++i) {
      for (int j = 0; j < c.options.profileThetaBins; ++j) {
        const double p = pulls[static_cast<std::size_t>(i * c.options.profileThetaBins + j)];
        // The bin's centre in degrees: φ_EMC over [0, 360), θ_EMC over the profiles' range.
        const calib::ProfileOptions profile;
        const double phi = (i + 0.5) * 360.0 / c.options.profilePhiBins;
        const double theta =
            (profile.thetaMin + (j + 0.5) * (profile.thetaMax - profile.thetaMin) / c.options.profileThetaBins) /
            units::deg;
        fmt::format_to(put, "{:.4g} {:.4g} {}\n", phi, theta,
                       std::isfinite(p) ? fmt::format("{:.4g}", p) : std::string("NaN"));
      }
      fmt::format_to(put, "\n");
    }
    fmt::format_to(put, "\n");
  }
  return fmt::to_string(out);
}

std::string scriptOf(const apply::Comparison& c, const std::string& dataLabel, const std::string& mcLabel) {
  std::string s = terminalHeader("compare", 1800, 1000);
  s += "data = 'compare.dat'\n";
  s += fmt::format(
      "set multiplot title \"MC against data: χ^2/ndf = {:.1f}/{}, p-value {:.3g} (all distributions together)\" "
      "font ',15'\n",
      c.chi2, c.ndf, c.pValue);
  s += "set grid lc rgb '#e0e0e0' lt 1\nset tics front\n";
  const char* xlabels[] = {"Δφ = φ_{TS} − φ_{EMC}  [deg]", "Δθ = θ_{TS} − θ_{EMC}  [deg]"};
  // Two columns of a distribution over its pulls (left two thirds), two pull maps (right).
  const double colW = 0.29, left = 0.06, gap = 0.07;
  for (std::size_t k = 0; k < 2; ++k) {
    const auto& d = c.distributions[k];
    const double x0 = left + static_cast<double>(k) * (colW + gap), x1 = x0 + colW;
    s += fmt::format(
        "\n# ---- {}\nset lmargin at screen {:.4f}; set rmargin at screen {:.4f}\n"
        "set tmargin at screen 0.90; set bmargin at screen 0.36\n"
        "set xrange [{}:{}]; set format x ''; unset xlabel\nset ylabel 'particles / deg'\nset yrange [0:*]\n"
        "set key top left reverse Left samplen 2 font ',11'\n"
        "set title \"{}: χ^2/ndf = {:.1f}/{}, p = {:.3g}\" font ',12'\n"
        "plot data index {} using 1:6:2:3:(0):6 with boxxyerror fs empty lw 1.5 lc rgb '#d62728' title \"{} (scaled to "
        "the data)\", \\\n"
        "     data index {} using 1:4:2:3:($4-$5):($4+$5) with xyerrorbars pt 7 ps 0.6 lc rgb '#1f77b4' title "
        "\"{}\"\n",
        d.name, x0, x1, centreOf(c, k) - c.options.rangeDeg, centreOf(c, k) + c.options.rangeDeg, d.name, d.chi2, d.ndf,
        d.pValue, k, literalText(mcLabel), k, literalText(dataLabel));
    s += fmt::format(
        "set tmargin at screen 0.33; set bmargin at screen 0.08\nunset title\nunset key\n"
        "set format x '%g'; set xlabel \"{}\"\nset ylabel 'pull'\nset yrange [-4.5:4.5]; set ytics 2\n"
        "set arrow 1 from {}, 0 to {}, 0 nohead lc rgb '#888888'\n"
        "plot data index {} using 1:8:($3-$2) with boxes fs solid 0.5 lc rgb '#555555'\n"
        "unset arrow 1; set ytics autofreq\n",
        xlabels[k], centreOf(c, k) - c.options.rangeDeg, centreOf(c, k) + c.options.rangeDeg, k);
  }
  // The profile pulls: φ_EMC across, θ_EMC up.
  const char* maps[] = {"ȳ_φ profile: pulls per bin", "ȳ_θ profile: pulls per bin"};
  for (std::size_t k = 0; k < 2; ++k) {
    const auto& d = c.distributions[2 + k];
    const double y1 = k == 0 ? 0.90 : 0.45, y0 = y1 - 0.33;
    s += fmt::format(
        "\n# ---- {}\nset lmargin at screen 0.755; set rmargin at screen 0.93\n"
        "set tmargin at screen {:.3f}; set bmargin at screen {:.3f}\n"
        "set title \"{} (χ^2/ndf = {:.1f}/{}, p = {:.3g})\" font ',11'\n"
        "set xrange [0:360]; set yrange [{:.4g}:{:.4g}]; set xtics 0,90,360; set ytics 45,18,135\n"
        "set xlabel 'φ_{{EMC}} [deg]'; set ylabel 'θ_{{EMC}} [deg]' offset 1.2,0\nunset grid\n"
        "set palette defined (-4 '#2166ac', -2 '#92c5de', 0 '#ffffff', 2 '#f4a582', 4 '#b2182b')\n"
        "set cbrange [-4:4]; set cbtics 2 font ',9'\n"
        "plot data index {} using 1:2:3 with image notitle\n",
        d.name, y1, y0, maps[k], d.chi2, d.ndf, d.pValue, calib::ProfileOptions{}.thetaMin / units::deg,
        calib::ProfileOptions{}.thetaMax / units::deg, 2 + k);
  }
  return s + "unset multiplot\n";
}

// compare_profiles.dat: one block per (profile, θ slice): the 16 φ bins' centre [deg], the
// data's mean and error, the MC's mean and error [deg]; index 0-9 ȳ_φ, 10-19 ȳ_θ.
std::string profileSlicesOf(const apply::Comparison& c) {
  fmt::memory_buffer out;
  auto put = std::back_inserter(out);
  fmt::format_to(put,
                 "# emcalign compare: the profiles per theta_EMC slice; index k < {0}: y_phi of slice k, index {0} + "
                 "k: y_theta of slice k (columns: phi_EMC centre [deg], data, data error, MC, MC error [deg])\n",
                 c.options.profileThetaBins);
  for (std::size_t k = 2; k < 4; ++k) {
    for (int j = 0; j < c.options.profileThetaBins; ++j) {
      bool any = false;
      for (const auto& b : c.distributions[k].bins) {
        const int bin = static_cast<int>(b.low);
        if (bin % c.options.profileThetaBins != j) continue;
        const int iPhi = bin / c.options.profileThetaBins;  // the bin index is i_phi-major
        const double phi = (iPhi + 0.5) * 360.0 / c.options.profilePhiBins;
        fmt::format_to(put, "{:.4g} {:.6g} {:.4g} {:.6g} {:.4g}\n", phi, b.data, b.dataError, b.mc, b.mcError);
        any = true;
      }
      if (!any) fmt::format_to(put, "NaN NaN NaN NaN NaN\n");
      fmt::format_to(put, "\n\n");
    }
  }
  return fmt::to_string(out);
}

std::string profileSlicesScript(const apply::Comparison& c, const std::string& dataLabel, const std::string& mcLabel) {
  const int slices = c.options.profileThetaBins;
  const calib::ProfileOptions profile;
  const double width = (profile.thetaMax - profile.thetaMin) / units::deg / slices;
  std::string s = terminalHeader("compare_profiles", 2000, 1500);
  s += "data = 'compare_profiles.dat'\n";
  s += fmt::format(
      "set multiplot layout 4,{} title \"MC against data per θ_{{EMC}} slice: the profiles ȳ_φ (rows 1-2) and ȳ_θ "
      "(rows 3-4) against φ_{{EMC}}; {} filled, {} open\" font ',15'\n",
      (slices + 1) / 2, literalText(dataLabel), literalText(mcLabel));
  s += "set grid lc rgb '#e0e0e0' lt 1\nset tics front font ',9'\nset xrange [0:360]; set xtics 0,90,360\n"
       "set key top right font ',8' samplen 1\n";
  for (int k = 0; k < 2 * slices; ++k) {
    const int j = k % slices;
    const double lo = profile.thetaMin / units::deg + j * width;
    if (std::find(c.emptyThetaSlices.begin(), c.emptyThetaSlices.end(), j) != c.emptyThetaSlices.end()) {
      // Nothing compared here: an empty frame that says so (gnuplot refuses to plot no point).
      s += fmt::format(
          "set title \"{} at θ_{{EMC}} {:g}-{:g}°\" font ',10'\nunset key\nset yrange [-1:1]\n"
          "set label 1 \"no bin with {} particles in both samples\" at graph 0.5, 0.5 center font ',9'\n"
          "plot 1/0 notitle\nunset label 1\nset yrange [*:*]\n",
          k < slices ? "ȳ_φ" : "ȳ_θ", lo, lo + width, c.options.minEntries);
      if (k == 0) s += "set key top right font ',8' samplen 1\n";
      continue;
    }
    s += fmt::format(
        "set title \"{} at θ_{{EMC}} {:g}-{:g}°\" font ',10'\nset ylabel '{} [deg]' font ',9'\n{}"
        "plot data index {} using 1:2:3 with yerrorbars pt 7 ps 0.5 lc rgb '#1f77b4' title '{}', \\\n"
        "     data index {} using 1:4:5 with yerrorbars pt 6 ps 0.7 lc rgb '#d62728' title '{}'\n",
        k < slices ? "ȳ_φ" : "ȳ_θ", lo, lo + width, k < slices ? "ȳ_φ" : "ȳ_θ", k == 0 ? "" : "unset key\n", k,
        k == 0 ? literalText(dataLabel) : "", k, k == 0 ? literalText(mcLabel) : "");
  }
  return s + "unset multiplot\n";
}

}  // namespace

Result<std::string> writeComparePlot(const std::string& dir, const apply::Comparison& comparison,
                                     const std::string& dataLabel, const std::string& mcLabel) {
  if (comparison.distributions.size() != 4) return Error{"compare: four distributions expected"};
  const fs::path out(dir);
  if (Status s = createPlotDirectory(out); !s) return s.error();
  if (Status s = writeFile(out, "compare.dat", dataOf(comparison)); !s) return s.error();
  if (Status s = writeFile(out, "compare_profiles.dat", profileSlicesOf(comparison)); !s) return s.error();
  auto pngs = drawFigures(out, {{"compare", scriptOf(comparison, dataLabel, mcLabel)},
                                {"compare_profiles", profileSlicesScript(comparison, dataLabel, mcLabel)}});
  if (!pngs) return pngs.error();
  return pngs->front();
}

}  // namespace emcalign::report
