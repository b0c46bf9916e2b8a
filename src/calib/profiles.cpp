#include "emcalign/calib/profiles.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <numbers>
#include <optional>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

#include "emcalign/io/csv.hpp"
#include "emcalign/io/file_kind.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::calib {

Status ProfileOptions::validate() const {
  if (phiBins < 1 || thetaBins < 1 || phiBins > 1000 || thetaBins > 1000) {
    return Error{fmt::format("profiles: {} x {} bins; need 1 to 1000 each way", phiBins, thetaBins)};
  }
  if (!(thetaMin >= 0.0 && thetaMin < thetaMax && thetaMax <= std::numbers::pi)) {
    return Error{"profiles: the theta range must lie inside [0, 180] deg"};
  }
  if (!(std::isfinite(sigmaSys) && sigmaSys >= 0.0)) return Error{"profiles: sigma_sys must be finite and >= 0"};
  if (minEntries < 2) return Error{"profiles: a bin needs at least 2 entries for its sigma"};
  if (partingPlane && partingPlane->phiBins() != phiBins) {
    return Error{fmt::format("the parting-plane response has {} phi columns, the profiles {}", partingPlane->phiBins(),
                             phiBins)};
  }
  if (nominalProfile && (nominalProfile->phiBins != phiBins || nominalProfile->thetaBins != thetaBins)) {
    return Error{fmt::format("the nominal profile has {} x {} bins, the profiles {} x {}", nominalProfile->phiBins,
                             nominalProfile->thetaBins, phiBins, thetaBins)};
  }
  return {};
}

Profiles::Profiles(ProfileOptions options) : options_(std::move(options)) {
  if (Status s = options_.validate(); !s) throw std::invalid_argument(s.error().message);
  acc_.resize(static_cast<std::size_t>(options_.phiBins * options_.thetaBins));
}

int Profiles::binOf(const ParticleResidual& p) const {
  const auto& o = options_;
  if (!(p.phiEmc >= 0.0 && p.phiEmc < 2.0 * std::numbers::pi)) return -1;
  if (!(p.thetaEmc >= o.thetaMin && p.thetaEmc < o.thetaMax)) return -1;
  const int iPhi = std::min(o.phiBins - 1, static_cast<int>(p.phiEmc / (2.0 * std::numbers::pi) * o.phiBins));
  const int iTheta =
      std::min(o.thetaBins - 1, static_cast<int>((p.thetaEmc - o.thetaMin) / (o.thetaMax - o.thetaMin) * o.thetaBins));
  return iPhi * o.thetaBins + iTheta;
}

void Profiles::fillPair(const ParticleResidual& a, const ParticleResidual& b) {
  if (!options_.eventPairs) return;
  int ka = binOf(a), kb = binOf(b);
  if (ka < 0 || kb < 0) return;
  const ParticleResidual* pa = &a;
  const ParticleResidual* pb = &b;
  if (ka > kb) {
    std::swap(ka, kb);
    std::swap(pa, pb);
  }
  PairSums& s = pairs_[{ka, kb}];
  const double ya[2] = {pa->yPhi, pa->yTheta}, yb[2] = {pb->yPhi, pb->yTheta};
  s.n += 1;
  for (int c = 0; c < 2; ++c) {
    s.a[c] += ya[c];
    s.b[c] += yb[c];
    for (int d = 0; d < 2; ++d) s.ab[c][d] += ya[c] * yb[d];
  }
}

std::vector<BinCovariance> Profiles::binCovariances() const {
  std::vector<BinCovariance> out;
  if (!options_.eventPairs) return out;
  for (std::size_t k = 0; k < acc_.size(); ++k) {
    const Accumulator& a = acc_[k];
    if (a.n < 2) continue;
    const double n = static_cast<double>(a.n);
    const int bin = static_cast<int>(k);
    out.push_back({bin, 0, bin, 1, a.m2PhiTheta / (n - 1.0) / n});
  }
  // Σ over pairs of (y_a − ȳ_a)(y_b − ȳ_b), from the sums and the bins' own means, over N_a·N_b.
  for (const auto& [key, s] : pairs_) {
    const auto [ka, kb] = key;
    const Accumulator& a = acc_[static_cast<std::size_t>(ka)];
    const Accumulator& b = acc_[static_cast<std::size_t>(kb)];
    const double n = static_cast<double>(s.n);
    double sum[2][2];
    for (int c = 0; c < 2; ++c) {
      for (int d = 0; d < 2; ++d) {
        sum[c][d] = s.ab[c][d] - b.mean[d] * s.a[c] - a.mean[c] * s.b[d] + n * a.mean[c] * b.mean[d];
      }
    }
    const double scale = 1.0 / (static_cast<double>(a.n) * static_cast<double>(b.n));
    if (ka == kb) {
      // Both particles in one bin: the pair adds to the variance of its mean (both orders).
      out.push_back({ka, 0, ka, 0, 2.0 * sum[0][0] * scale});
      out.push_back({ka, 1, ka, 1, 2.0 * sum[1][1] * scale});
      out.push_back({ka, 0, ka, 1, (sum[0][1] + sum[1][0]) * scale});
      continue;
    }
    for (int c = 0; c < 2; ++c) {
      for (int d = 0; d < 2; ++d) out.push_back({ka, c, kb, d, sum[c][d] * scale});
    }
  }
  return out;
}

bool Profiles::fill(const ParticleResidual& p) {
  const int k = binOf(p);
  if (k < 0) return false;
  Accumulator& a = acc_[static_cast<std::size_t>(k)];
  a.n += 1;
  const double x[5] = {p.yPhi, p.yTheta, p.phiEmc, p.thetaEmc, p.energy};
  const double dPhi = x[0] - a.mean[0], dTheta = x[1] - a.mean[1];
  for (int i = 0; i < 5; ++i) a.mean[i] += (x[i] - a.mean[i]) / static_cast<double>(a.n);
  a.m2Phi += dPhi * (x[0] - a.mean[0]);
  a.m2Theta += dTheta * (x[1] - a.mean[1]);
  a.m2PhiTheta += dPhi * (x[1] - a.mean[1]);
  ++entries_;
  return true;
}

void Profiles::merge(const Profiles& other) {
  const auto& a = options_;
  const auto& b = other.options_;
  if (a.phiBins != b.phiBins || a.thetaBins != b.thetaBins || a.thetaMin != b.thetaMin || a.thetaMax != b.thetaMax) {
    throw std::invalid_argument("Profiles::merge: profiles with other bins");
  }
  // Chan, Golub & LeVeque's pairwise update of means and squared deviations.
  for (std::size_t k = 0; k < acc_.size(); ++k) {
    Accumulator& x = acc_[k];
    const Accumulator& y = other.acc_[k];
    if (y.n == 0) continue;
    if (x.n == 0) {
      x = y;
      continue;
    }
    const double nx = static_cast<double>(x.n), ny = static_cast<double>(y.n), n = nx + ny;
    const double dPhi = y.mean[0] - x.mean[0], dTheta = y.mean[1] - x.mean[1];
    for (int i = 0; i < 5; ++i) x.mean[i] += (y.mean[i] - x.mean[i]) * ny / n;
    x.m2Phi += y.m2Phi + dPhi * dPhi * nx * ny / n;
    x.m2Theta += y.m2Theta + dTheta * dTheta * nx * ny / n;
    x.m2PhiTheta += y.m2PhiTheta + dPhi * dTheta * nx * ny / n;
    x.n += y.n;
  }
  for (const auto& [key, s] : other.pairs_) {
    PairSums& t = pairs_[key];
    t.n += s.n;
    for (int c = 0; c < 2; ++c) {
      t.a[c] += s.a[c];
      t.b[c] += s.b[c];
      for (int d = 0; d < 2; ++d) t.ab[c][d] += s.ab[c][d];
    }
  }
  entries_ += other.entries_;
}

std::vector<ProfileBin> Profiles::bins(double sigmaSys) const {
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
        b.sigmaPhi = std::sqrt(statPhi2 + sigmaSys * sigmaSys);
        b.sigmaTheta = std::sqrt(statTheta2 + sigmaSys * sigmaSys);
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

std::string profileCsv(const std::vector<ProfileBin>& bins, const std::string& comment) {
  const bool weights =
      std::any_of(bins.begin(), bins.end(), [](const ProfileBin& b) { return !std::isnan(b.plusWeight); });
  std::string out = comment.empty() ? std::string() : comment + "\n";
  out += std::string(kHeader) + (weights ? ",plus_weight\n" : "\n");
  for (const auto& b : bins) {
    out +=
        fmt::format("{},{},{},{},{},{},{},{},{},{}", b.iPhi, b.iTheta, b.n, number(b.phiMean), number(b.thetaMean),
                    number(b.energyMean), number(b.yPhi), number(b.sigmaPhi), number(b.yTheta), number(b.sigmaTheta));
    out += weights ? fmt::format(",{}\n", number(b.plusWeight)) : "\n";
  }
  return out;
}

namespace {

// A profile-CSV integer: digits only (no sign, point or exponent), within [lo, hi].
std::optional<std::int64_t> profileInteger(std::string_view field, std::int64_t lo, std::int64_t hi) {
  std::int64_t x = 0;
  const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), x);
  if (field.empty() || ec != std::errc() || ptr != field.data() + field.size() || x < lo || x > hi) return std::nullopt;
  return x;
}

// The columns of a profile CSV, in their order (plus_weight optional).
constexpr const char* kColumns[] = {"i_phi", "i_theta",   "n",       "phi_mean_rad", "theta_mean_rad", "e_mean_mev",
                                    "y_phi", "sigma_phi", "y_theta", "sigma_theta",  "plus_weight"};
enum Column { kIPhi, kITheta, kN, kPhiMean, kThetaMean, kEMean, kYPhi, kSigmaPhi, kYTheta, kSigmaTheta, kPlusWeight };
constexpr std::size_t kRequiredColumns = kPlusWeight, kAllColumns = kPlusWeight + 1;

// One data line of a profile CSV, its fields split; `where(c)` names the file, line and column.
struct ProfileLine {
  const std::vector<std::string_view>& fields;
  std::function<std::string(int column)> where;
  [[nodiscard]] Error bad(int c, std::string_view what) const {
    return Error{fmt::format("{}: {} {}", where(c), io::quotedText(fields[static_cast<std::size_t>(c)]), what)};
  }
};

// The bin indices and the entries of a line.
Status parseBinIndex(const ProfileLine& line, const ProfileOptions& options, ProfileBin& b) {
  const auto& f = line.fields;
  const auto iPhi = profileInteger(f[kIPhi], 0, options.phiBins - 1);
  if (!iPhi) {
    return Error{fmt::format("{}: {} is not a bin index 0 to {}", line.where(kIPhi), io::quotedText(f[kIPhi]),
                             options.phiBins - 1)};
  }
  const auto iTheta = profileInteger(f[kITheta], 0, options.thetaBins - 1);
  if (!iTheta) {
    return Error{fmt::format("{}: {} is not a bin index 0 to {}", line.where(kITheta), io::quotedText(f[kITheta]),
                             options.thetaBins - 1)};
  }
  constexpr std::int64_t kMaxEntries = std::int64_t{1} << 53;
  const auto n = profileInteger(f[kN], 0, kMaxEntries);
  if (!n)
    return Error{fmt::format("{}: {} is not a count of entries (0 to 2^53)", line.where(kN), io::quotedText(f[kN]))};
  b.iPhi = static_cast<int>(*iPhi);
  b.iTheta = static_cast<int>(*iTheta);
  b.n = *n;
  return {};
}

// The real-valued columns of a line (empty: NaN), each a finite number in the range its
// definition allows.
Status parseBinValues(const ProfileLine& line, const ProfileOptions& options, ProfileBin& b) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double pi = std::numbers::pi;
  std::array<double, kAllColumns> v;
  v[kPlusWeight] = nan;
  for (std::size_t c = kPhiMean; c < line.fields.size(); ++c) {
    const auto field = line.fields[c];
    if (field.empty()) {
      v[c] = nan;
      continue;
    }
    const auto x = io::parseFiniteDouble(field);
    if (!x)
      return Error{fmt::format("{}: not a finite number: {}", line.where(static_cast<int>(c)), io::quotedText(field))};
    v[c] = *x;
  }
  const double phiLo = 2.0 * pi * b.iPhi / options.phiBins, phiHi = 2.0 * pi * (b.iPhi + 1) / options.phiBins;
  const double dTheta = (options.thetaMax - options.thetaMin) / options.thetaBins;
  const double thetaLo = options.thetaMin + dTheta * b.iTheta, thetaHi = thetaLo + dTheta;
  const double slack = 1e-9;
  if (b.n == 0) {
    for (int c = kPhiMean; c <= kSigmaTheta; ++c) {
      if (!std::isnan(v[c])) return line.bad(c, "is given for a bin without entries (n = 0)");
    }
  } else {
    for (int c : {kPhiMean, kThetaMean, kEMean}) {
      if (std::isnan(v[c])) return Error{fmt::format("{}: empty, but the bin has {} entries", line.where(c), b.n)};
    }
  }
  if (!std::isnan(v[kPhiMean]) && !(v[kPhiMean] >= phiLo - slack && v[kPhiMean] <= phiHi + slack)) {
    return line.bad(kPhiMean,
                    fmt::format("lies outside its bin i_phi = {} ({:.6g} to {:.6g} rad)", b.iPhi, phiLo, phiHi));
  }
  if (!std::isnan(v[kThetaMean]) && !(v[kThetaMean] >= thetaLo - slack && v[kThetaMean] <= thetaHi + slack)) {
    return line.bad(kThetaMean, fmt::format("lies outside its bin i_theta = {} ({:.6g} to {:.6g} rad)", b.iTheta,
                                            thetaLo, thetaHi));
  }
  if (!std::isnan(v[kEMean]) && !(v[kEMean] > 1.0 && v[kEMean] < 1e5)) {
    return line.bad(kEMean, "is not a plausible cluster energy (1 to 100000 MeV; energies are in MeV)");
  }
  if (!std::isnan(v[kYPhi]) && !(std::abs(v[kYPhi]) <= 1.0)) return line.bad(kYPhi, "is not a sine (|y_phi| <= 1)");
  if (!std::isnan(v[kYTheta]) && !(std::abs(v[kYTheta]) <= pi)) {
    return line.bad(kYTheta, "is not an angle (|y_theta| <= pi)");
  }
  for (int c : {kSigmaPhi, kSigmaTheta}) {
    if (!std::isnan(v[c]) && !(v[c] > 0.0 && v[c] <= pi)) {
      return line.bad(c, "is not a plausible sigma (0 < sigma <= pi)");
    }
  }
  if (!std::isnan(v[kPlusWeight]) && !(v[kPlusWeight] >= 0.0 && v[kPlusWeight] <= 1.0)) {
    return line.bad(kPlusWeight, "is not a weight in [0, 1]");
  }
  b.phiMean = v[kPhiMean];
  b.thetaMean = v[kThetaMean];
  b.energyMean = v[kEMean];
  b.yPhi = v[kYPhi];
  b.sigmaPhi = v[kSigmaPhi];
  b.yTheta = v[kYTheta];
  b.sigmaTheta = v[kSigmaTheta];
  b.plusWeight = v[kPlusWeight];
  return {};
}

// A file of another kind given as a profile (an event file, a fit result, …), named by what it is.
Error notAProfile(const std::string& path, const std::string& kind) {
  return Error{fmt::format("{}: this is {}, not a profile CSV (fit --profile-out)", path, kind)};
}

}  // namespace

Result<std::vector<ProfileBin>> readProfileCsv(const std::string& path, const ProfileOptions& options) {
  if (Status s = options.validate(); !s) return s.error();
  auto content = io::readTextFile(path);
  if (!content) {
    if (const std::string kind = io::describeFileAt(path); !kind.empty() && kind != io::kProfileCsvKind) {
      return notAProfile(path, kind);
    }
    return content.error();
  }
  std::istringstream in(*content);
  const int bins = options.phiBins * options.thetaBins;
  std::vector<int> lineOfBin(static_cast<std::size_t>(bins), 0);
  std::vector<ProfileBin> out;
  std::string text;
  long lineNo = 0;
  bool header = false;
  std::size_t columns = kRequiredColumns;
  while (std::getline(in, text)) {
    ++lineNo;
    if (in.eof() && !text.empty()) {
      return Error{
          fmt::format("{}: line {}: the file ends inside this line (no newline at its end): truncated?", path, lineNo)};
    }
    if (io::isBlankOrComment(text)) continue;
    const auto f = io::splitCsvLine(text);
    if (!header) {
      bool names = f.size() == kRequiredColumns || f.size() == kAllColumns;
      for (std::size_t k = 0; names && k < f.size(); ++k) names = f[k] == kColumns[k];
      if (!names) {
        if (const std::string kind = io::describeContent(*content); !kind.empty() && kind != io::kProfileCsvKind) {
          return notAProfile(path, kind);
        }
        return Error{fmt::format("{}: line {}: header: expected '{}' (optionally followed by ',plus_weight'), got {}",
                                 path, lineNo, kHeader, io::quotedText(text))};
      }
      columns = f.size();
      header = true;
      continue;
    }
    if (f.size() != columns) {
      return Error{fmt::format("{}: line {}: expected {} columns, got {}", path, lineNo, columns, f.size())};
    }
    const ProfileLine line{f,
                           [&](int k) { return fmt::format("{}: line {}: column '{}'", path, lineNo, kColumns[k]); }};
    ProfileBin b;
    if (Status s = parseBinIndex(line, options, b); !s) return s.error();
    const auto k = static_cast<std::size_t>(b.iPhi * options.thetaBins + b.iTheta);
    if (lineOfBin[k] != 0) {
      return Error{fmt::format("{}: line {}: bin ({}, {}) is given again (first on line {})", path, lineNo, b.iPhi,
                               b.iTheta, lineOfBin[k])};
    }
    lineOfBin[k] = static_cast<int>(lineNo);
    if (Status s = parseBinValues(line, options, b); !s) return s.error();
    out.push_back(b);
  }
  if (in.bad()) return Error{fmt::format("{}: read error: {}", path, std::strerror(errno))};
  if (!header) return Error{fmt::format("{}: no header line '{}'", path, kHeader)};
  if (out.size() != static_cast<std::size_t>(bins)) {
    for (int i = 0; i < bins; ++i) {
      if (lineOfBin[static_cast<std::size_t>(i)] == 0) {
        return Error{
            fmt::format("{}: {} of the {} bins are given; bin ({}, {}) is missing (a profile lists every bin, "
                        "also the empty ones)",
                        path, out.size(), bins, i / options.thetaBins, i % options.thetaBins)};
      }
    }
  }
  return out;
}

}  // namespace emcalign::calib

namespace emcalign::calib {

// The state: {"bins": [phi, theta], "entries": N, "acc": [[k, n, 5 means, m2φ, m2θ, m2φθ]...]
// (filled bins only), "pairs": [[a, b, n, a0, a1, b0, b1, ab00, ab01, ab10, ab11]...]}.
io::Json Profiles::state() const {
  io::Json acc = io::Json::array(), pairs = io::Json::array();
  for (std::size_t k = 0; k < acc_.size(); ++k) {
    const Accumulator& x = acc_[k];
    if (x.n == 0) continue;
    acc.push_back({k, x.n, x.mean[0], x.mean[1], x.mean[2], x.mean[3], x.mean[4], x.m2Phi, x.m2Theta, x.m2PhiTheta});
  }
  for (const auto& [key, s] : pairs_) {
    pairs.push_back(
        {key.first, key.second, s.n, s.a[0], s.a[1], s.b[0], s.b[1], s.ab[0][0], s.ab[0][1], s.ab[1][0], s.ab[1][1]});
  }
  return {{"bins", {options_.phiBins, options_.thetaBins}}, {"entries", entries_}, {"acc", acc}, {"pairs", pairs}};
}

namespace {

// Row `row` of a state's list: `size` finite numbers, the first `integers` of them integers ≥ 0.
Result<std::vector<double>> stateRow(const io::Json& row, std::size_t size, std::size_t integers,
                                     const std::string& where) {
  if (!row.is_array() || row.size() != size) return Error{fmt::format("{}: not a list of {} numbers", where, size)};
  std::vector<double> out;
  for (std::size_t i = 0; i < size; ++i) {
    const io::Json& v = row[i];
    if (i < integers ? !(v.is_number_unsigned() || (v.is_number_integer() && v.get<std::int64_t>() >= 0))
                     : !v.is_number()) {
      return Error{fmt::format("{}: entry {} is not {}", where, i, i < integers ? "a count" : "a number")};
    }
    out.push_back(i < integers ? static_cast<double>(v.get<std::int64_t>()) : v.get<double>());
    if (!std::isfinite(out.back())) return Error{fmt::format("{}: entry {} is not finite", where, i)};
  }
  return out;
}

}  // namespace

Result<Profiles> Profiles::restore(const io::Json& state, ProfileOptions options, const std::string& source) {
  if (Status s = options.validate(); !s) return s.error();
  Profiles p(std::move(options));
  const auto& o = p.options_;
  if (!state.is_object() || !state.contains("bins") || state["bins"] != io::Json{o.phiBins, o.thetaBins}) {
    return Error{fmt::format("{}: profiles of other bins than {} x {}", source, o.phiBins, o.thetaBins)};
  }
  const io::Json& entries = state.contains("entries") ? state["entries"] : io::Json();
  if (!entries.is_number_integer() || entries.get<std::int64_t>() < 0) {
    return Error{fmt::format("{}: \"entries\" is not a count", source)};
  }
  p.entries_ = entries.get<std::int64_t>();
  const auto bins = static_cast<std::int64_t>(p.acc_.size());
  if (!state.contains("acc") || !state["acc"].is_array() || !state.contains("pairs") || !state["pairs"].is_array()) {
    return Error{fmt::format("{}: no \"acc\" and \"pairs\" lists", source)};
  }
  for (const io::Json& row : state["acc"]) {
    auto v = stateRow(row, 10, 2, fmt::format("{}: a bin", source));
    if (!v) return v.error();
    const auto k = static_cast<std::int64_t>((*v)[0]);
    if (k >= bins || p.acc_[static_cast<std::size_t>(k)].n != 0 || (*v)[1] < 1) {
      return Error{fmt::format("{}: bin {} out of range, repeated or empty", source, k)};
    }
    Accumulator& x = p.acc_[static_cast<std::size_t>(k)];
    x.n = row[1].get<std::int64_t>();
    for (int i = 0; i < 5; ++i) x.mean[i] = (*v)[static_cast<std::size_t>(2 + i)];
    x.m2Phi = (*v)[7];
    x.m2Theta = (*v)[8];
    x.m2PhiTheta = (*v)[9];
  }
  for (const io::Json& row : state["pairs"]) {
    auto v = stateRow(row, 11, 3, fmt::format("{}: a pair of bins", source));
    if (!v) return v.error();
    const auto a = static_cast<int>((*v)[0]), b = static_cast<int>((*v)[1]);
    if (a >= bins || b >= bins || a > b || p.pairs_.count({a, b}) != 0) {
      return Error{fmt::format("{}: the pair of bins {}, {} out of range or repeated", source, a, b)};
    }
    PairSums& s = p.pairs_[{a, b}];
    s.n = row[2].get<std::int64_t>();
    s.a[0] = (*v)[3];
    s.a[1] = (*v)[4];
    s.b[0] = (*v)[5];
    s.b[1] = (*v)[6];
    s.ab[0][0] = (*v)[7];
    s.ab[0][1] = (*v)[8];
    s.ab[1][0] = (*v)[9];
    s.ab[1][1] = (*v)[10];
  }
  return p;
}

}  // namespace emcalign::calib
