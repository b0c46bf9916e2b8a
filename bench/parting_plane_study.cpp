// The parting-plane response bin by bin: how much of each hemisphere's displacement the
// profile bins next to the plane see, measured on a uniform gap and on tilted gaps (μ ≠ 0),
// against the column weights W₊ of a corrections file (docs/validation.md).
//
//   emcalign_parting_plane_study CORRECTIONS.json [EVENTS_PER_SAMPLE] [SEED]
//
// Per sample S (gap dx_rel = 0.5 cm; tilts μ = 0.5° at τ = 0° and 90° on a 0.5 cm gap) and
// per bin of the four columns next to the plane, W₊ minimises
// Σ_{φ,θ components} (ȳ_S − ȳ_N − f₋ − W₊(f₊ − f₋))²/σ², N the nominal sample, at the file's
// depth. Then every sample is fitted with the file's corrections, with the truth beside it.

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/sigma_sys.hpp"
#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/residual_model.hpp"
#include "emcalign/sim/simulation.hpp"
#include "emcalign/validation/derive_corrections.hpp"

using namespace emcalign;

namespace {

struct Sample {
  std::string name;
  geometry::AlignmentParameters truth;
  std::vector<ParticleRow> rows;
};

Sample simulate(const geometry::Calorimeter& calo, std::string name, const geometry::AlignmentParameters& truth,
                std::int64_t events, std::uint64_t seed) {
  Sample s{std::move(name), truth, {}};
  sim::SimulationOptions so;
  so.generator.thetaMin = 40.0 * units::deg;
  so.generator.thetaMax = 140.0 * units::deg;
  so.seed = seed;
  auto simulation = sim::Simulation::create(calo, truth, so);
  if (!simulation) {
    fmt::print(stderr, "{}\n", simulation.error().message);
    std::exit(1);
  }
  calib::ProfileFiller filler(geometry::ShowerDepth::of(calo.description()), calib::SelectionOptions{}, {},
                              [&](const ParticleRow& row, const calib::ParticleResidual&) { s.rows.push_back(row); });
  const Status run = simulation->run(
      events, 0, [&](std::span<const ParticleRow> rows, std::span<const TruthRow>, std::span<const Hit>) {
        filler.addEvents(rows);
        return Status{};
      });
  if (!run) std::exit(1);
  return s;
}

calib::Profiles profileOf(const Sample& s, const geometry::ShowerDepth& depth, const calib::ProfileOptions& po) {
  calib::Profiles p(po);
  for (const auto& row : s.rows) {
    if (const auto y = calib::residualOf(row, depth)) p.fill(*y);
  }
  return p;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    fmt::print(stderr, "usage: {} CORRECTIONS.json [EVENTS_PER_SAMPLE] [SEED]\n", argv[0]);
    return 2;
  }
  auto corrections = calib::readCorrections(argv[1]);
  if (!corrections) {
    fmt::print(stderr, "{}\n", corrections.error().message);
    return 1;
  }
  const std::int64_t events = argc > 2 ? std::atoll(argv[2]) : 1000000;
  const std::uint64_t seed = argc > 3 ? std::strtoull(argv[3], nullptr, 10) : 11;
  const auto calo = geometry::Calorimeter::create(geometry::DetectorDescription::sndDefault());
  const double r1 = calo->description().r1();
  calib::FitGeometry g = calib::FitGeometry::of(calo->description());
  g.apply(*corrections);
  if (std::getenv("NO_RESPONSE") != nullptr) g.response = nullptr;

  auto tilt = [&](double tauDeg, double dxRel = 0.5, double muDeg = 0.5) {
    geometry::PhysicalParameters p;
    p[Physical::DxRel] = dxRel;
    p[Physical::Mu] = muDeg * units::deg;
    p[Physical::Tau] = tauDeg * units::deg;
    return geometry::fromPhysical(p, r1);
  };
  const Sample nominal = simulate(*calo, "nominal", {}, events, seed);
  std::vector<Sample> samples;
  const bool gaps = std::getenv("GAPS") != nullptr;
  for (double dxRel : {0.05, 0.1, 0.25, 0.5}) {
    if (!gaps) break;
    geometry::AlignmentParameters gap;
    gap[Param::Dp1] = gap[Param::Dp2] = gap[Param::Dp3] = 2.0 * dxRel;
    samples.push_back(simulate(*calo, fmt::format("gap dx_rel {}", dxRel), gap, events, seed + 1 + samples.size()));
  }
  samples.push_back(simulate(*calo, "tilt tau=0", tilt(0.0), events, seed + 10));
  samples.push_back(simulate(*calo, "tilt tau=90", tilt(90.0), events, seed + 11));
  samples.push_back(simulate(*calo, "tilt tau=0 mu=0.3 dx_rel=1", tilt(0.0, 1.0, 0.3), events, seed + 12));
  samples.push_back(simulate(*calo, "tilt tau=90 mu=0.3 dx_rel=1", tilt(90.0, 1.0, 0.3), events, seed + 13));
  samples.push_back(simulate(*calo, "tilt tau=0 mu=0.3 dx_rel=0.3", tilt(0.0, 0.3, 0.3), events, seed + 14));

  calib::ProfileOptions raw;
  raw.sigmaSys = 0.0;
  // The two particles of an event: how their residuals correlate (the profiles treat them as
  // independent).
  {
    double s[4][5] = {};  // per pair kind (φφ, θθ, φθ, θφ): n, Σa, Σb, Σab, Σa², Σb² (reused)
    double sa2[4] = {}, sb2[4] = {};
    for (std::size_t i = 0; i + 1 < nominal.rows.size(); i += 2) {
      const auto a = calib::residualOf(nominal.rows[i], g.depth), c = calib::residualOf(nominal.rows[i + 1], g.depth);
      if (!a || !c || nominal.rows[i].event != nominal.rows[i + 1].event) continue;
      const double x[4] = {a->yPhi, a->yTheta, a->yPhi, a->yTheta}, y[4] = {c->yPhi, c->yTheta, c->yTheta, c->yPhi};
      for (int k = 0; k < 4; ++k) {
        s[k][0] += 1;
        s[k][1] += x[k];
        s[k][2] += y[k];
        s[k][3] += x[k] * y[k];
        sa2[k] += x[k] * x[k];
        sb2[k] += y[k] * y[k];
      }
    }
    const char* names[] = {"phi-phi", "theta-theta", "phi-theta", "theta-phi"};
    for (int k = 0; k < 4; ++k) {
      const double n = s[k][0], ma = s[k][1] / n, mb = s[k][2] / n;
      const double cov = s[k][3] / n - ma * mb, va = sa2[k] / n - ma * ma, vb = sb2[k] / n - mb * mb;
      fmt::print("residual correlation of the two particles of an event, {}: {:+.4f} ({} events)\n", names[k],
                 cov / std::sqrt(va * vb), n);
    }
  }
  // The depth row by row: χ²_j(δ) of the shift sample against the model, the nominal sample
  // subtracted, per θ row j, for y_φ and y_θ apart and together, on a grid of δ.
  if (std::getenv("DEPTH_STUDY") != nullptr) {
    geometry::AlignmentParameters shift;
    shift[Param::Dx] = shift[Param::Dy] = shift[Param::Dz] = 0.6;
    const Sample shifted = simulate(*calo, "shift", shift, events, seed + 4);
    constexpr int kRows = 26;  // 10 θ rows, then 16 φ columns
    std::vector<double> grid;
    for (double d = 1.0; d <= 8.001; d += 0.25) grid.push_back(d);
    std::vector<std::array<std::array<double, 3>, kRows>> chi2(grid.size());
    for (std::size_t k = 0; k < grid.size(); ++k) {
      calib::FitGeometry gk = g;
      gk.depth.offset = grid[k];
      const auto sb = profileOf(shifted, gk.depth, raw).bins(0.0);
      const auto nb0 = profileOf(nominal, gk.depth, raw).bins(0.0);
      for (auto& row : chi2[k]) row = {0.0, 0.0, 0.0};
      for (std::size_t b = 0; b < sb.size(); ++b) {
        if (!sb[b].used || !nb0[b].used) continue;
        const auto f = calib::modelAt(gk, shift.values, sb[b].phiMean, sb[b].thetaMean, sb[b].energyMean);
        const double rp = sb[b].yPhi - nb0[b].yPhi - f.phi, rt = sb[b].yTheta - nb0[b].yTheta - f.theta;
        const double cp = rp * rp / (sb[b].sigmaPhi * sb[b].sigmaPhi + nb0[b].sigmaPhi * nb0[b].sigmaPhi);
        const double ct = rt * rt / (sb[b].sigmaTheta * sb[b].sigmaTheta + nb0[b].sigmaTheta * nb0[b].sigmaTheta);
        for (int r : {sb[b].iTheta, 10 + sb[b].iPhi}) {
          auto& row = chi2[k][static_cast<std::size_t>(r)];
          row[0] += cp;
          row[1] += ct;
          row[2] += cp + ct;
        }
      }
    }
    auto minimum = [&](int row, int which) {
      std::size_t best = 0;
      for (std::size_t k = 1; k < grid.size(); ++k) {
        if (chi2[k][row][which] < chi2[best][row][which]) best = k;
      }
      if (best == 0 || best + 1 == grid.size()) return std::pair{grid[best], std::nan("")};
      const double a = chi2[best - 1][row][which], c = chi2[best][row][which], e = chi2[best + 1][row][which];
      const double h = grid[1] - grid[0], curv = (a - 2 * c + e) / (h * h);
      return std::pair{grid[best] + h * (a - e) / (2.0 * (a - 2 * c + e)), std::sqrt(2.0 / curv)};
    };
    fmt::print("depth offset per theta row (shift sample dx = dy = dz = 0.6 cm): y_phi | y_theta | both, cm\n");
    for (int j = 0; j < kRows; ++j) {
      const auto [p, pe] = minimum(j, 0);
      const auto [t, te] = minimum(j, 1);
      const auto [b, be] = minimum(j, 2);
      fmt::print("  {} {:2d} ({:5.1f} deg): {:6.2f} ± {:.2f} | {:6.2f} ± {:.2f} | {:6.2f} ± {:.2f}\n",
                 j < 10 ? "theta" : "phi  ", j < 10 ? j : j - 10, j < 10 ? 49.5 + 9.0 * j : 11.25 + 22.5 * (j - 10), p,
                 pe, t, te, b, be);
    }
  }
  const auto nb = profileOf(nominal, g.depth, raw).bins(0.0);
  for (const Sample& s : samples) {
    const auto sb = profileOf(s, g.depth, raw).bins(0.0);
    fmt::print(
        "\n{}: W+ per bin (rows: theta bins 0-9; columns: phi bins 3, 4, 11, 12), file's column W+: {:.3f} "
        "{:.3f} {:.3f} {:.3f}\n",
        s.name, corrections->partingPlane->plusWeight(3), corrections->partingPlane->plusWeight(4),
        corrections->partingPlane->plusWeight(11), corrections->partingPlane->plusWeight(12));
    auto terms = [&](int ip, int it) {
      const auto k = static_cast<std::size_t>(ip * 10 + it);
      return validation::plusWeightTerms(sb[k], nb[k], s.truth, g.depth, g.radii);
    };
    for (int it = 0; it < 10; ++it) {
      fmt::print("  theta {:2d}:", it);
      for (int ip : {3, 4, 11, 12}) {
        const auto t = terms(ip, it);
        fmt::print("  {:6.3f}±{:.3f}", t.num / t.den, 1.0 / std::sqrt(t.den));
      }
      fmt::print("\n");
    }
    fmt::print("  column W+ (all rows):");
    for (int ip : {3, 4, 11, 12}) {
      double num = 0.0, den = 0.0;
      for (int it = 0; it < 10; ++it) {
        const auto t = terms(ip, it);
        num += t.num;
        den += t.den;
      }
      fmt::print("  {:6.3f}±{:.3f}", num / den, 1.0 / std::sqrt(den));
    }
    fmt::print("\n");
    calib::ProfileOptions po;
    po.partingPlane = corrections->partingPlane;
    po.nominalProfile = corrections->nominalProfile;
    auto fit = calib::fitProfiles(profileOf(s, g.depth, po), g, calib::SigmaSysChoice::automatic());
    if (!fit) continue;
    auto truthPhys = geometry::toPhysical(s.truth, r1);
    auto fitPhys = geometry::toPhysical(fit->parameters, r1);
    fmt::print(
        "  fit with the file: mu {:.4f} deg (truth {:.4f}), tau {:.2f} deg (truth {:.2f}), dx_rel {:.4f} cm "
        "(truth {:.4f}); dp {:.4f} {:.4f} {:.4f} (truth {:.4f} {:.4f} {:.4f}); beta_rel {:.4f} deg\n",
        (*fitPhys)[Physical::Mu] / units::deg, (*truthPhys)[Physical::Mu] / units::deg,
        (*fitPhys)[Physical::Tau] / units::deg, (*truthPhys)[Physical::Tau] / units::deg, (*fitPhys)[Physical::DxRel],
        (*truthPhys)[Physical::DxRel], fit->parameters[Param::Dp1], fit->parameters[Param::Dp2],
        fit->parameters[Param::Dp3], s.truth[Param::Dp1], s.truth[Param::Dp2], s.truth[Param::Dp3],
        fit->parameters[Param::BetaRel] / units::deg);
  }
  return 0;
}
