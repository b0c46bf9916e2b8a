#include "emcalign/calib/profiles.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <stdexcept>

#include <fmt/format.h>

#include "emcalign/io/csv.hpp"

namespace emcalign::calib {

Profiles::Profiles(ProfileOptions options)
    : options_(options), acc_(static_cast<std::size_t>(options.phiBins * options.thetaBins)) {
  if (options_.partingPlane && options_.partingPlane->phiBins() != options_.phiBins) {
    throw std::invalid_argument(fmt::format("profiles: the parting-plane response has {} phi columns, the profiles {}",
                                            options_.partingPlane->phiBins(), options_.phiBins));
  }
  if (options_.nominalProfile &&
      (options_.nominalProfile->phiBins != options_.phiBins || options_.nominalProfile->thetaBins != options_.thetaBins)) {
    throw std::invalid_argument("profiles: the nominal profile has other bins than the profiles");
  }
}

bool Profiles::fill(const ParticleResidual& p) {
  const auto& o = options_;
  if (!(p.phiEmc >= 0.0 && p.phiEmc < 2.0 * std::numbers::pi)) return false;
  if (!(p.thetaEmc >= o.thetaMin && p.thetaEmc < o.thetaMax)) return false;
  const int iPhi = std::min(o.phiBins - 1, static_cast<int>(p.phiEmc / (2.0 * std::numbers::pi) * o.phiBins));
  const int iTheta = std::min(o.thetaBins - 1,
                              static_cast<int>((p.thetaEmc - o.thetaMin) / (o.thetaMax - o.thetaMin) * o.thetaBins));
  Accumulator& a = acc_[static_cast<std::size_t>(iPhi * o.thetaBins + iTheta)];
  a.n += 1;
  const double x[5] = {p.yPhi, p.yTheta, p.phiEmc, p.thetaEmc, p.energy};
  const double dPhi = x[0] - a.mean[0], dTheta = x[1] - a.mean[1];
  for (int k = 0; k < 5; ++k) a.mean[k] += (x[k] - a.mean[k]) / static_cast<double>(a.n);
  a.m2Phi += dPhi * (x[0] - a.mean[0]);
  a.m2Theta += dTheta * (x[1] - a.mean[1]);
  ++entries_;
  return true;
}

std::vector<ProfileBin> Profiles::bins() const {
  const auto& o = options_;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<ProfileBin> out;
  out.reserve(acc_.size());
  for (int iPhi = 0; iPhi < o.phiBins; ++iPhi) {
    for (int iTheta = 0; iTheta < o.thetaBins; ++iTheta) {
      const Accumulator& a = acc_[static_cast<std::size_t>(iPhi * o.thetaBins + iTheta)];
      ProfileBin b;
      b.iPhi = iPhi;
      b.iTheta = iTheta;
      b.n = a.n;
      if (a.n > 0) {
        b.yPhi = a.mean[0];
        b.yTheta = a.mean[1];
        b.phiMean = a.mean[2];
        b.thetaMean = a.mean[3];
        b.energyMean = a.mean[4];
        if (o.partingPlane) b.plusWeight = o.partingPlane->plusWeight(iPhi);
      } else {
        b.yPhi = b.yTheta = b.phiMean = b.thetaMean = b.energyMean = nan;
      }
      if (a.n > 1) {
        const double n = static_cast<double>(a.n);
        const double statPhi2 = a.m2Phi / (n - 1.0) / n, statTheta2 = a.m2Theta / (n - 1.0) / n;
        b.sigmaPhi = std::sqrt(statPhi2 + o.sigmaSys * o.sigmaSys);
        b.sigmaTheta = std::sqrt(statTheta2 + o.sigmaSys * o.sigmaSys);
      } else {
        b.sigmaPhi = b.sigmaTheta = nan;
      }
      if (o.nominalProfile) {
        const NominalProfile& t = *o.nominalProfile;
        const auto k = static_cast<std::size_t>(iPhi * o.thetaBins + iTheta);
        b.yPhi -= t.yPhi[k];  // NaN where the nominal sample lacks the bin: left out
        b.yTheta -= t.yTheta[k];
        b.sigmaPhi = std::hypot(b.sigmaPhi, t.sigmaPhi[k]);
        b.sigmaTheta = std::hypot(b.sigmaTheta, t.sigmaTheta[k]);
      }
      out.push_back(b);
    }
  }
  markUsedBins(out, o.minEntries);
  return out;
}

int markUsedBins(std::vector<ProfileBin>& bins, int minEntries) {
  int used = 0;
  for (auto& b : bins) {
    b.used = b.n >= minEntries && std::isfinite(b.yPhi) && std::isfinite(b.yTheta) && b.sigmaPhi > 0.0 &&
             b.sigmaTheta > 0.0 && std::isfinite(b.sigmaPhi) && std::isfinite(b.sigmaTheta) &&
             std::isfinite(b.phiMean) && std::isfinite(b.thetaMean) && b.energyMean > 0.0;
    used += b.used;
  }
  return used;
}

namespace {
constexpr const char* kHeader =
    "i_phi,i_theta,n,phi_mean_rad,theta_mean_rad,e_mean_mev,y_phi,sigma_phi,y_theta,sigma_theta";

std::string number(double v) { return std::isfinite(v) ? fmt::format("{:.17g}", v) : std::string(); }
}  // namespace

std::string profileCsv(const std::vector<ProfileBin>& bins) {
  const bool weights = std::any_of(bins.begin(), bins.end(), [](const ProfileBin& b) { return !std::isnan(b.plusWeight); });
  std::string out = std::string(kHeader) + (weights ? ",plus_weight\n" : "\n");
  for (const auto& b : bins) {
    out += fmt::format("{},{},{},{},{},{},{},{},{},{}", b.iPhi, b.iTheta, b.n, number(b.phiMean), number(b.thetaMean),
                       number(b.energyMean), number(b.yPhi), number(b.sigmaPhi), number(b.yTheta), number(b.sigmaTheta));
    out += weights ? fmt::format(",{}\n", number(b.plusWeight)) : "\n";
  }
  return out;
}

Result<std::vector<ProfileBin>> readProfileCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Error{fmt::format("{}: cannot open", path)};
  std::vector<ProfileBin> bins;
  std::string line;
  long lineNo = 0;
  bool header = false;
  static const char* kColumns[] = {"i_phi", "i_theta", "n", "phi_mean_rad", "theta_mean_rad", "e_mean_mev",
                                   "y_phi", "sigma_phi", "y_theta", "sigma_theta", "plus_weight"};
  std::size_t columns = 10;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  while (std::getline(in, line)) {
    ++lineNo;
    if (io::isBlankOrComment(line)) continue;
    const auto f = io::splitCsvLine(line);
    if (!header) {
      bool names = f.size() == 10 || f.size() == 11;
      for (std::size_t k = 0; names && k < f.size(); ++k) names = f[k] == kColumns[k];
      if (names) {
        columns = f.size();
      } else {
        return Error{fmt::format("{}: line {}: header: expected '{}' (optionally followed by ',plus_weight')", path,
                                 lineNo, kHeader)};
      }
      header = true;
      continue;
    }
    if (f.size() != columns) {
      return Error{fmt::format("{}: line {}: expected {} columns, got {}", path, lineNo, columns, f.size())};
    }
    double v[11];
    v[10] = nan;
    for (int k = 0; k < static_cast<int>(columns); ++k) {
      if (f[static_cast<std::size_t>(k)].empty() && k >= 3) {
        v[k] = nan;
        continue;
      }
      const auto x = io::parseFiniteDouble(f[static_cast<std::size_t>(k)]);
      if (!x) {
        return Error{fmt::format("{}: line {}: column '{}': not a finite number: '{}'", path, lineNo, kColumns[k],
                                 f[static_cast<std::size_t>(k)])};
      }
      v[k] = *x;
    }
    for (int k : {0, 1, 2}) {
      if (v[k] != std::floor(v[k]) || v[k] < 0) {
        return Error{fmt::format("{}: line {}: column '{}': expected a non-negative integer", path, lineNo, kColumns[k])};
      }
    }
    for (int k : {7, 9}) {
      if (!std::isnan(v[k]) && !(v[k] > 0.0)) {
        return Error{fmt::format("{}: line {}: column '{}': a sigma must be positive", path, lineNo, kColumns[k])};
      }
    }
    ProfileBin b;
    b.iPhi = static_cast<int>(v[0]);
    b.iTheta = static_cast<int>(v[1]);
    b.n = static_cast<std::int64_t>(v[2]);
    b.phiMean = v[3];
    b.thetaMean = v[4];
    b.energyMean = v[5];
    b.yPhi = v[6];
    b.sigmaPhi = v[7];
    b.yTheta = v[8];
    b.sigmaTheta = v[9];
    if (columns == 11) {
      if (!std::isnan(v[10]) && !(v[10] >= 0.0 && v[10] <= 1.0)) {
        return Error{fmt::format("{}: line {}: column 'plus_weight': expected a weight in [0, 1]", path, lineNo)};
      }
      b.plusWeight = v[10];
    }
    bins.push_back(b);
  }
  if (!header) return Error{fmt::format("{}: no header line", path)};
  if (bins.empty()) return Error{fmt::format("{}: no bins", path)};
  return bins;
}

}  // namespace emcalign::calib
