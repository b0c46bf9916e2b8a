#include "emcalign/apply/mc_comparison.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <Eigen/Dense>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/core/special_functions.hpp"
#include "emcalign/core/units.hpp"

namespace emcalign::apply {

namespace {

using io::Json;

// A histogram's fine bin of a value (degrees) about `centre`: beyond the range, the last bin
// on its side.
int fineBin(double deg, double centre, const ComparisonOptions& o) {
  const double x = (deg - centre + o.rangeDeg) / (2.0 * o.rangeDeg) * o.histogramBins;
  return std::clamp(static_cast<int>(std::floor(x)), 0, o.histogramBins - 1);
}
int phiBin(const ComparedParticle& p, const ComparisonOptions& o) { return fineBin(p.dPhiDeg, o.phiCentreDeg, o); }
int thetaBin(const ComparedParticle& p, const ComparisonOptions& o) {
  return fineBin(p.dThetaDeg, o.thetaCentreDeg, o);
}

// Adjacent fine bins merged until each merged bin has minEntries in both samples: the first
// fine bin of each merged bin, and the map fine → merged.
struct Merged {
  std::vector<int> first;  // first fine bin of each merged bin
  std::vector<int> of;     // fine bin → merged bin
  [[nodiscard]] int size() const { return static_cast<int>(first.size()); }
};

Merged mergeBins(const std::vector<std::int64_t>& a, const std::vector<std::int64_t>& b, std::int64_t minEntries) {
  Merged m;
  m.of.assign(a.size(), 0);
  std::int64_t na = 0, nb = 0;
  int start = 0;
  for (int k = 0; k < static_cast<int>(a.size()); ++k) {
    na += a[static_cast<std::size_t>(k)];
    nb += b[static_cast<std::size_t>(k)];
    if (na >= minEntries && nb >= minEntries) {
      m.first.push_back(start);
      for (int j = start; j <= k; ++j) m.of[static_cast<std::size_t>(j)] = m.size() - 1;
      start = k + 1;
      na = nb = 0;
    }
  }
  // A short tail joins the last bin.
  for (int j = start; j < static_cast<int>(a.size()); ++j)
    m.of[static_cast<std::size_t>(j)] = std::max(0, m.size() - 1);
  return m;
}

// Where each compared quantity sits in the vector of all of them.
struct Layout {
  Merged phi, theta;
  std::vector<int> usedBins;   // profile bins compared
  std::vector<int> slotOfBin;  // profile bin → index into usedBins, −1 when not compared
  [[nodiscard]] int size() const { return phi.size() + theta.size() + 2 * static_cast<int>(usedBins.size()); }
  [[nodiscard]] int thetaOffset() const { return phi.size(); }
  [[nodiscard]] int profileOffset() const { return phi.size() + theta.size(); }
};

// One sample's quantities and their covariance (the events' influences, see the header).
struct SampleStatistics {
  Eigen::VectorXd value;
  Eigen::MatrixXd covariance;
  std::int64_t particles = 0, events = 0;
};

SampleStatistics statisticsOf(const std::vector<ComparedParticle>& sample, const Layout& l,
                              const ComparisonOptions& o) {
  const int k = l.size(), u = static_cast<int>(l.usedBins.size());
  const int tOff = l.thetaOffset(), pOff = l.profileOffset();
  SampleStatistics s;
  s.value = Eigen::VectorXd::Zero(k);
  s.particles = static_cast<std::int64_t>(sample.size());
  const double n = static_cast<double>(sample.size());
  std::vector<double> binCount(static_cast<std::size_t>(u), 0.0);
  for (const auto& p : sample) {
    s.value[l.phi.of[static_cast<std::size_t>(phiBin(p, o))]] += 1.0 / n;
    s.value[tOff + l.theta.of[static_cast<std::size_t>(thetaBin(p, o))]] += 1.0 / n;
    if (p.bin < 0) continue;
    const int slot = l.slotOfBin[static_cast<std::size_t>(p.bin)];
    if (slot < 0) continue;
    binCount[static_cast<std::size_t>(slot)] += 1.0;
    s.value[pOff + slot] += p.yPhi;
    s.value[pOff + u + slot] += p.yTheta;
  }
  for (int j = 0; j < u; ++j) {
    s.value[pOff + j] /= binCount[static_cast<std::size_t>(j)];
    s.value[pOff + u + j] /= binCount[static_cast<std::size_t>(j)];
  }
  // Σ a·aᵀ over events (a sparse), u = Σ k·a, Σ k²; the fractions' dense part through P.
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(k, k);
  Eigen::VectorXd ka = Eigen::VectorXd::Zero(k);
  double k2 = 0.0;
  std::vector<std::pair<int, double>> a;
  for (std::size_t begin = 0; begin < sample.size();) {
    std::size_t end = begin;
    while (end < sample.size() && sample[end].event == sample[begin].event) ++end;
    a.clear();
    for (std::size_t i = begin; i < end; ++i) {
      const auto& p = sample[i];
      a.emplace_back(l.phi.of[static_cast<std::size_t>(phiBin(p, o))], 1.0 / n);
      a.emplace_back(tOff + l.theta.of[static_cast<std::size_t>(thetaBin(p, o))], 1.0 / n);
      if (p.bin < 0) continue;
      const int slot = l.slotOfBin[static_cast<std::size_t>(p.bin)];
      if (slot < 0) continue;
      const double nb = binCount[static_cast<std::size_t>(slot)];
      a.emplace_back(pOff + slot, (p.yPhi - s.value[pOff + slot]) / nb);
      a.emplace_back(pOff + u + slot, (p.yTheta - s.value[pOff + u + slot]) / nb);
    }
    const double ke = static_cast<double>(end - begin);
    for (const auto& [i, x] : a) {
      ka[i] += ke * x;
      for (const auto& [j, y] : a) sum(i, j) += x * y;
    }
    k2 += ke * ke;
    ++s.events;
    begin = end;
  }
  Eigen::VectorXd p = Eigen::VectorXd::Zero(k);
  for (int i = 0; i < pOff; ++i) p[i] = s.value[i] / n;
  s.covariance = sum - ka * p.transpose() - p * ka.transpose() + k2 * p * p.transpose();
  return s;
}

// χ² of d with covariance c over c's rank (eigenvalues above 1e-10 of the largest).
std::pair<double, int> chi2Of(const Eigen::VectorXd& d, const Eigen::MatrixXd& c) {
  if (d.size() == 0) return {0.0, 0};
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(c);
  const Eigen::VectorXd& lambda = eig.eigenvalues();
  const double largest = lambda.maxCoeff();
  if (!(largest > 0.0)) return {0.0, 0};
  const Eigen::VectorXd projected = eig.eigenvectors().transpose() * d;
  double chi2 = 0.0;
  int rank = 0;
  for (Eigen::Index i = 0; i < lambda.size(); ++i) {
    if (!(lambda[i] > 1e-10 * largest)) continue;
    chi2 += projected[i] * projected[i] / lambda[i];
    ++rank;
  }
  return {chi2, rank};
}

// The options with the histograms' centres not given set to the data's means, to 0.25°.
ComparisonOptions centredOn(const std::vector<ComparedParticle>& data, ComparisonOptions o) {
  if (data.empty()) return o;
  double phi = 0.0, theta = 0.0;
  for (const auto& p : data) {
    phi += p.dPhiDeg;
    theta += p.dThetaDeg;
  }
  const auto quarter = [](double x) { return std::isfinite(x) ? std::round(4.0 * x) / 4.0 : 0.0; };
  if (std::isnan(o.phiCentreDeg)) o.phiCentreDeg = quarter(phi / static_cast<double>(data.size()));
  if (std::isnan(o.thetaCentreDeg)) o.thetaCentreDeg = quarter(theta / static_cast<double>(data.size()));
  return o;
}

// The θ slices of the profiles in which no bin is compared (`usedBins`: i_phi-major indices).
std::vector<int> emptyThetaSlices(const std::vector<int>& usedBins, int thetaBins) {
  std::vector<int> out;
  for (int j = 0; j < thetaBins; ++j) {
    if (std::none_of(usedBins.begin(), usedBins.end(), [&](int b) { return b % thetaBins == j; })) out.push_back(j);
  }
  return out;
}

Status checkOptions(const ComparisonOptions& o) {
  if (o.histogramBins < 2 || o.histogramBins > 10000) return Error{"histogram bins: 2 to 10000"};
  if (!(o.rangeDeg > 0.0) || !(o.rangeDeg <= 180.0)) return Error{"range: (0, 180] deg"};
  if (o.profilePhiBins < 1 || o.profileThetaBins < 1 || o.profilePhiBins * o.profileThetaBins > 100000) {
    return Error{"profile bins: at least one each way"};
  }
  if (o.minEntries < 2) return Error{"minimum entries per bin: at least 2"};
  if (!(o.sigmaSys >= 0.0) || !std::isfinite(o.sigmaSys)) return Error{"sigma_sys: finite and >= 0"};
  if (std::isinf(o.phiCentreDeg) || std::isinf(o.thetaCentreDeg)) return Error{"histogram centres: finite"};
  return {};
}

// What both samples must be before they are compared: apart, large enough, in the profile's bins
// and finite.
Status checkSamples(const std::vector<ComparedParticle>& data, const std::vector<ComparedParticle>& mc,
                    const ComparisonOptions& o) {
  // The same particles on both sides (a sample, a copy of it, the same events read twice): its
  // χ² would be 0 and its p-value 1, whatever the simulation.
  const auto same = [](const ComparedParticle& a, const ComparedParticle& b) {
    return a.event == b.event && a.bin == b.bin && a.yPhi == b.yPhi && a.yTheta == b.yTheta;
  };
  if (!data.empty() && data.size() == mc.size() && std::equal(data.begin(), data.end(), mc.begin(), same)) {
    return Error{"the data and the MC are the same particles: a comparison of a sample with itself"};
  }
  for (const auto& [what, sample] : {std::pair{"data", &data}, std::pair{"MC", &mc}}) {
    if (static_cast<std::int64_t>(sample->size()) < 2 * o.minEntries) {
      return Error{
          fmt::format("{}: {} selected particles in the profiles' theta range, fewer than the {} a comparison "
                      "needs",
                      what, sample->size(), 2 * o.minEntries)};
    }
  }
  const int profileBins = o.profilePhiBins * o.profileThetaBins;
  for (const auto* sample : {&data, &mc}) {
    for (const auto& p : *sample) {
      if (p.bin >= profileBins) return Error{fmt::format("profile bin {} beyond the {} bins", p.bin, profileBins)};
      if (!std::isfinite(p.dPhiDeg) || !std::isfinite(p.dThetaDeg) || !std::isfinite(p.yPhi) ||
          !std::isfinite(p.yTheta)) {
        return Error{fmt::format("event {}: a residual that is not a number", p.event)};
      }
    }
  }
  return {};
}

// The layout of the comparison: the histograms' fine bins merged until both samples have
// minEntries in each, and the profile bins both samples fill with minEntries.
Layout layoutOf(const std::vector<ComparedParticle>& data, const std::vector<ComparedParticle>& mc,
                const ComparisonOptions& o) {
  const int profileBins = o.profilePhiBins * o.profileThetaBins;
  Layout l;
  std::vector<std::int64_t> phiD(static_cast<std::size_t>(o.histogramBins)), phiM = phiD, thetaD = phiD, thetaM = phiD;
  std::vector<std::int64_t> binD(static_cast<std::size_t>(profileBins)), binM = binD;
  const auto count = [&](const std::vector<ComparedParticle>& s, std::vector<std::int64_t>& phi,
                         std::vector<std::int64_t>& theta, std::vector<std::int64_t>& bins) {
    for (const auto& p : s) {
      ++phi[static_cast<std::size_t>(phiBin(p, o))];
      ++theta[static_cast<std::size_t>(thetaBin(p, o))];
      if (p.bin >= 0) ++bins[static_cast<std::size_t>(p.bin)];
    }
  };
  count(data, phiD, thetaD, binD);
  count(mc, phiM, thetaM, binM);
  l.phi = mergeBins(phiD, phiM, o.minEntries);
  l.theta = mergeBins(thetaD, thetaM, o.minEntries);
  l.slotOfBin.assign(static_cast<std::size_t>(profileBins), -1);
  for (int b = 0; b < profileBins; ++b) {
    if (binD[static_cast<std::size_t>(b)] >= o.minEntries && binM[static_cast<std::size_t>(b)] >= o.minEntries) {
      l.slotOfBin[static_cast<std::size_t>(b)] = static_cast<int>(l.usedBins.size());
      l.usedBins.push_back(b);
    }
  }
  return l;
}

// Data − MC of every compared quantity, with the covariance of both samples (and σ_sys on the
// profile means).
struct Difference {
  const Layout& layout;
  const SampleStatistics &data, &mc;
  Eigen::VectorXd d;
  Eigen::MatrixXd c;
};

// One distribution of the comparison: quantities [begin, begin + count) of the vector, a
// histogram of Δφ or Δθ, or the profile means of y_φ or y_θ; its χ² and its bins.
ComparedDistribution distributionOf(const std::string& name, int begin, int count, bool histogram, bool theta,
                                    const Difference& diff, const ComparisonOptions& o) {
  const Layout& l = diff.layout;
  const Eigen::VectorXd& d = diff.d;
  const Eigen::MatrixXd& c = diff.c;
  ComparedDistribution dist;
  dist.name = name;
  const auto [chi2, ndf] = chi2Of(d.segment(begin, count), c.block(begin, begin, count, count));
  dist.chi2 = chi2;
  dist.ndf = ndf;
  dist.pValue = ndf > 0 ? chi2PValue(chi2, ndf) : 1.0;
  const double width = 2.0 * o.rangeDeg / o.histogramBins;
  const Merged& m = theta ? l.theta : l.phi;
  const double lowest = (theta ? o.thetaCentreDeg : o.phiCentreDeg) - o.rangeDeg;
  for (int i = 0; i < count; ++i) {
    const int j = begin + i;
    ComparedDistribution::Bin b;
    if (histogram) {
      b.low = lowest + width * m.first[static_cast<std::size_t>(i)];
      b.high = i + 1 < m.size() ? lowest + width * m.first[static_cast<std::size_t>(i + 1)] : lowest + 2.0 * o.rangeDeg;
      if (i == 0) b.low = -std::numeric_limits<double>::infinity();
      if (i + 1 == m.size()) b.high = std::numeric_limits<double>::infinity();
    } else {
      b.low = b.high = l.usedBins[static_cast<std::size_t>(i)];
    }
    const double scale = histogram ? 1.0 : 1.0 / units::deg;
    b.data = diff.data.value[j] * scale;
    b.mc = diff.mc.value[j] * scale;
    b.dataError = std::sqrt(std::max(0.0, diff.data.covariance(j, j))) * scale;
    b.mcError = std::sqrt(std::max(0.0, diff.mc.covariance(j, j))) * scale;
    b.pull = c(j, j) > 0.0 ? d[j] / std::sqrt(c(j, j)) : 0.0;
    dist.bins.push_back(b);
  }
  return dist;
}

}  // namespace

Result<Comparison> compareParticles(const std::vector<ComparedParticle>& data, const std::vector<ComparedParticle>& mc,
                                    const ComparisonOptions& given) {
  if (Status s = checkOptions(given); !s) return s.error();
  const ComparisonOptions o = centredOn(data, given);
  if (Status s = checkSamples(data, mc, o); !s) return s.error();
  const Layout l = layoutOf(data, mc, o);
  const SampleStatistics sd = statisticsOf(data, l, o), sm = statisticsOf(mc, l, o);
  Difference diff{l, sd, sm, sd.value - sm.value, sd.covariance + sm.covariance};
  const int u = static_cast<int>(l.usedBins.size()), pOff = l.profileOffset();
  for (int j = pOff; j < l.size(); ++j) diff.c(j, j) += o.sigmaSys * o.sigmaSys;

  Comparison out;
  out.options = o;
  out.dataParticles = sd.particles;
  out.mcParticles = sm.particles;
  out.dataEvents = sd.events;
  out.mcEvents = sm.events;
  out.distributions.push_back(distributionOf("dphi", 0, l.phi.size(), true, false, diff, o));
  out.distributions.push_back(distributionOf("dtheta", l.thetaOffset(), l.theta.size(), true, true, diff, o));
  out.distributions.push_back(distributionOf("profile_phi", pOff, u, false, false, diff, o));
  out.distributions.push_back(distributionOf("profile_theta", pOff + u, u, false, true, diff, o));
  if (u == 0) {
    return Error{fmt::format(
        "no profile bin has the {} particles a comparison needs in both samples (the data {} particles, the MC {})",
        o.minEntries, data.size(), mc.size())};
  }
  out.emptyThetaSlices = emptyThetaSlices(l.usedBins, o.profileThetaBins);
  const auto inEmptySlices = [&](std::span<const ComparedParticle> sample) {
    return std::count_if(sample.begin(), sample.end(), [&](const ComparedParticle& p) {
      return std::ranges::find(out.emptyThetaSlices, p.bin % o.profileThetaBins) != out.emptyThetaSlices.end();
    });
  };
  out.dataParticlesInEmptySlices = inEmptySlices(data);
  out.mcParticlesInEmptySlices = inEmptySlices(mc);

  const auto [chi2, ndf] = chi2Of(diff.d, diff.c);
  out.chi2 = chi2;
  out.ndf = ndf;
  out.pValue = ndf > 0 ? chi2PValue(chi2, ndf) : 1.0;
  return out;
}

namespace {

// The particles a fill visits (fillProfiles of files or of rows), binned as the profiles.
template <typename Fill>
Result<ComparedSample> comparedParticles(const ComparisonOptions& o, const Fill& fillWith) {
  const calib::ProfileOptions profile;
  ComparedSample sample;
  std::vector<ComparedParticle>& out = sample.particles;
  std::int64_t event = -1;
  std::int32_t lastRun = 0;
  std::int64_t lastEvent = 0;
  bool first = true;
  const double thetaSpan = profile.thetaMax - profile.thetaMin;
  const calib::ParticleVisitor visit = [&](const ParticleRow& row, const calib::ParticleResidual& y) {
    if (first || row.run != lastRun || row.event != lastEvent) ++event;
    first = false;
    lastRun = row.run;
    lastEvent = row.event;
    if (!(y.thetaEmc >= profile.thetaMin && y.thetaEmc < profile.thetaMax)) return;
    if (!(y.phiEmc >= 0.0 && y.phiEmc < 2.0 * std::numbers::pi)) return;
    ComparedParticle p;
    p.event = event;
    p.dPhiDeg = std::asin(std::clamp(y.yPhi, -1.0, 1.0)) / units::deg;
    p.dThetaDeg = y.yTheta / units::deg;
    p.yPhi = y.yPhi;
    p.yTheta = y.yTheta;
    const int iPhi =
        std::min(o.profilePhiBins - 1, static_cast<int>(y.phiEmc / (2.0 * std::numbers::pi) * o.profilePhiBins));
    const int iTheta = std::min(o.profileThetaBins - 1,
                                static_cast<int>((y.thetaEmc - profile.thetaMin) / thetaSpan * o.profileThetaBins));
    p.bin = iPhi * o.profileThetaBins + iTheta;
    out.push_back(p);
  };
  auto fill = fillWith(profile, visit);
  if (!fill) return fill.error();
  sample.selectedEvents = fill->cutFlow.events.back();
  for (double e : fill->beamEnergies) sample.beamEnergiesMev.push_back(e / units::MeV);
  return sample;
}

// The energies of `a` that none of `b` is within kSameBeamEnergy of.
std::vector<double> unmatched(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> out;
  for (double e : a) {
    const bool found = std::any_of(b.begin(), b.end(), [&](double f) {
      return std::abs(e - f) <= kSameBeamEnergy * std::max(std::abs(e), std::abs(f));
    });
    if (!found) out.push_back(e);
  }
  return out;
}

}  // namespace

Result<ComparedSample> comparedSampleOf(const std::vector<std::string>& files, const geometry::ShowerDepth& depth,
                                        const calib::SelectionOptions& selection, const ComparisonOptions& o) {
  return comparedParticles(o, [&](const calib::ProfileOptions& profile, const auto& visit) {
    return calib::fillProfiles(files, depth, selection, profile, visit);
  });
}

Result<ComparedSample> comparedSampleOfRows(std::span<const ParticleRow> rows, const std::string& source,
                                            const geometry::ShowerDepth& depth,
                                            const calib::SelectionOptions& selection, const ComparisonOptions& o) {
  return comparedParticles(o, [&](const calib::ProfileOptions& profile, const auto& visit) {
    return calib::fillProfilesOfRows(rows, source, depth, selection, profile, visit);
  });
}

Status checkCombinable(const ComparedSample& data, const ComparedSample& mc) {
  const auto mev = [](const std::vector<double>& e) {
    return e.empty() ? std::string("none") : fmt::format("{:g} MeV", fmt::join(e, ", "));
  };
  const std::vector<double> dataOnly = unmatched(data.beamEnergiesMev, mc.beamEnergiesMev);
  const std::vector<double> mcOnly = unmatched(mc.beamEnergiesMev, data.beamEnergiesMev);
  if (dataOnly.empty() && mcOnly.empty()) return {};
  return Error{fmt::format(
      "the data (beam energies {}) and the MC (beam energies {}) are not of the same beam energies{}{}: the "
      "residuals depend on the energy (the shower depth, the radiation), so they would differ whatever the "
      "simulation; compare samples of one energy (within {:g} of it)",
      mev(data.beamEnergiesMev), mev(mc.beamEnergiesMev),
      dataOnly.empty() ? std::string() : fmt::format("; the MC has none at {}", mev(dataOnly)),
      mcOnly.empty() ? std::string() : fmt::format("; the data have none at {}", mev(mcOnly)), kSameBeamEnergy)};
}

Result<Comparison> compareSamples(const ComparedSample& data, const ComparedSample& mc,
                                  const ComparisonOptions& options) {
  if (Status s = checkCombinable(data, mc); !s) return s.error();
  auto c = compareParticles(data.particles, mc.particles, options);
  if (!c) return c;
  c->dataSelectedEvents = data.selectedEvents;
  c->mcSelectedEvents = mc.selectedEvents;
  c->dataBeamEnergiesMev = data.beamEnergiesMev;
  c->mcBeamEnergiesMev = mc.beamEnergiesMev;
  return c;
}

std::string emptySlicesText(const Comparison& c) {
  if (c.emptyThetaSlices.empty()) return {};
  const std::int64_t d = c.dataParticlesInEmptySlices, m = c.mcParticlesInEmptySlices;
  const std::string which = d == 0 && m == 0 ? "neither sample has a particle there"
                            : d < m          ? "the data are thin there (a small sample, or another θ range?)"
                                             : "the MC is thin there (a small MC, or one simulated over a narrower θ "
                                               "range?)";
  return fmt::format(
      "{} of the {} theta_EMC slices have no profile bin with {} particles in both samples: not compared, drawn "
      "empty; the data have {} particles in them, the MC {}: {}",
      c.emptyThetaSlices.size(), c.options.profileThetaBins, c.options.minEntries, d, m, which);
}

std::string comparisonMarkdown(const Comparison& c, const std::vector<std::string>& dataFiles,
                               const std::vector<std::string>& mcFiles, const std::string& depth) {
  const auto energies = [](const std::vector<double>& e) {
    return e.empty() ? std::string() : fmt::format("beam energy {:g} MeV, ", fmt::join(e, ", "));
  };
  const auto selected = [](std::int64_t n) { return n > 0 ? fmt::format("{} selected events, ", n) : std::string(); };
  std::string md = fmt::format(
      "# MC against data\n\nData: {} ({}{}{} events and {} particles in 45-135 deg). MC: {} ({}{}{} events and {} "
      "particles).\n\n",
      fmt::join(dataFiles, ", "), energies(c.dataBeamEnergiesMev), selected(c.dataSelectedEvents), c.dataEvents,
      c.dataParticles, fmt::join(mcFiles, ", "), energies(c.mcBeamEnergiesMev), selected(c.mcSelectedEvents),
      c.mcEvents, c.mcParticles);
  if (!c.emptyThetaSlices.empty()) {
    std::vector<std::string> slices;
    for (int j : c.emptyThetaSlices) {
      const double width = 90.0 / c.options.profileThetaBins;
      slices.push_back(fmt::format("{:g}-{:g}°", 45.0 + j * width, 45.0 + (j + 1) * width));
    }
    md += fmt::format(
        "No profile bin of the θ_EMC slices {} has {} particles in both samples: they are not compared, and drawn "
        "empty.\n\n",
        fmt::join(slices, ", "), c.options.minEntries);
  }
  md += fmt::format("Errors: the statistical errors of both samples{}. Residuals at the shower depth {}.\n\n",
                    c.options.sigmaSys > 0.0 ? fmt::format(", and σ_sys = {:g} deg added to each profile mean",
                                                           c.options.sigmaSys * 180.0 / std::numbers::pi)
                                             : std::string(" alone (σ_sys 0)"),
                    depth.empty() ? std::string("R(E, θ) of the paper") : depth);
  const bool agree = c.pValue >= 0.01;
  md += fmt::format("**All together: χ²/ndf = {:.1f}/{}, p-value {:.3g}: {}.**\n\n", c.chi2, c.ndf, c.pValue,
                    agree ? "the simulation describes the data within the statistical errors of both"
                          : "the simulation does not describe the data");
  md += "| distribution | χ²/ndf | p-value | largest pulls |\n|---|---|---|---|\n";
  for (const auto& d : c.distributions) {
    std::vector<const ComparedDistribution::Bin*> bins;
    for (const auto& b : d.bins) bins.push_back(&b);
    std::sort(bins.begin(), bins.end(),
              [](const auto* a, const auto* b) { return std::abs(a->pull) > std::abs(b->pull); });
    std::vector<std::string> largest;
    for (std::size_t k = 0; k < std::min<std::size_t>(3, bins.size()); ++k) {
      const auto& b = *bins[k];
      const bool histogram = d.name == "dphi" || d.name == "dtheta";
      largest.push_back(histogram ? fmt::format("{:+.1f} at [{:.2f}, {:.2f}) deg", b.pull, b.low, b.high)
                                  : fmt::format("{:+.1f} in bin ({}, {})", b.pull,
                                                static_cast<int>(b.low) / c.options.profileThetaBins,
                                                static_cast<int>(b.low) % c.options.profileThetaBins));
    }
    md += fmt::format("| {} | {:.1f}/{} | {:.3g} | {} |\n", d.name, d.chi2, d.ndf, d.pValue, fmt::join(largest, "; "));
  }
  md += fmt::format(
      "\nThe χ² of each distribution uses the covariance of both samples (the two particles of an event, y_φ "
      "with y_θ, a histogram's normalisation; docs/apply.md), histogram bins merged until each sample has {} "
      "particles in each, profile bins with {} in both{}. A simulation that is the data's twin gives p-values "
      "uniform in [0, 1].\n",
      c.options.minEntries, c.options.minEntries,
      c.options.sigmaSys > 0.0
          ? fmt::format(", σ_sys = {:.3g} deg added to each profile mean", c.options.sigmaSys / units::deg)
          : std::string());
  return md;
}

}  // namespace emcalign::apply
