#include "emcalign/apply/physics_checks.hpp"
#include "emcalign/apply/check_record.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>

#include <fmt/format.h>
#include <Eigen/Dense>

#include "emcalign/core/statistics.hpp"
#include "emcalign/geometry/track.hpp"
#include "emcalign/io/event_file.hpp"

namespace emcalign::apply {

using io::Json;

namespace {

constexpr double kDeg = units::deg;
constexpr double kChi2Tail = 20.0;  // χ²(2) > 20: p < 5e-5, the tail of non-Gaussian responses

// One event's rows: [begin, end) of a block.
using EventVisitor = std::function<Status(std::span<const ParticleRow> before, std::span<const ParticleRow> after)>;

// Reads `before` and `after` in step and hands over each event of both.
// Events one by one from a reader, whatever its blocks (a reader's block never spans two
// files, so several input files and the one corrected file cut their blocks differently).
class EventCursor {
 public:
  explicit EventCursor(std::unique_ptr<io::EventReader> reader) : reader_(std::move(reader)) {}
  // The next event's rows (a view into the current block), empty at the end.
  Result<std::span<const ParticleRow>> next() {
    if (pos_ == rows_.size()) {
      auto more = reader_->next(rows_);
      if (!more) return more.error();
      pos_ = 0;
      if (!*more) {
        rows_.clear();
        return std::span<const ParticleRow>();
      }
    }
    std::size_t end = pos_ + 1;
    while (end < rows_.size() && sameEvent(rows_[end], rows_[pos_])) ++end;
    const auto event = std::span<const ParticleRow>(rows_).subspan(pos_, end - pos_);
    pos_ = end;
    return event;
  }

 private:
  std::unique_ptr<io::EventReader> reader_;
  std::vector<ParticleRow> rows_;
  std::size_t pos_ = 0;
};

Status forEachEventPair(const std::vector<std::string>& before, const std::vector<std::string>& after,
                        const EventVisitor& visit) {
  auto a = io::EventReader::open(before);
  if (!a) return a.error();
  auto b = io::EventReader::open(after);
  if (!b) return b.error();
  EventCursor ca(std::move(*a)), cb(std::move(*b));
  for (;;) {
    auto ea = ca.next();
    if (!ea) return ea.error();
    auto eb = cb.next();
    if (!eb) return eb.error();
    if (ea->empty() != eb->empty() || ea->size() != eb->size()) {
      return Error{
          "the corrected events are not the same events as the uncorrected ones (another file, or another "
          "order)"};
    }
    if (ea->empty()) return {};
    for (std::size_t k = 0; k < ea->size(); ++k) {
      if (!sameEvent((*eb)[k], (*ea)[k])) {
        return Error{fmt::format("run {} event {}: the corrected file holds run {} event {} at its place", (*ea)[k].run,
                                 (*ea)[k].event, (*eb)[k].run, (*eb)[k].event)};
      }
    }
    if (Status s = visit(*ea, *eb); !s) return s;
  }
}

// The two photons' values of a γγ event, in degrees.
void acollinearity(const ParticleRow& g1, const ParticleRow& g2, double& dphi, double& dtheta) {
  dphi = std::abs(g1.phiEmc - g2.phiEmc) / kDeg - 180.0;
  dtheta = (g1.thetaEmc + g2.thetaEmc) / kDeg - 180.0;
}

// The kinematic-fit input of a selected π+π−π0 event (tracks, then photons, by index).
ThreePionEvent threePionEvent(std::span<const ParticleRow> rows, const std::array<std::size_t, 2>& tracks,
                              const std::array<std::size_t, 2>& photons, const geometry::ShowerDepth& depth,
                              const ResolutionModel& res) {
  ThreePionEvent e;
  const double z = 0.5 * (rows[tracks[0]].z0 + rows[tracks[1]].z0);
  for (std::size_t i = 0; i < 2; ++i) {
    const ParticleRow& g = rows[photons[i]];
    const Vec3 point = geometry::pointAt(depth.radius(g.energy, g.thetaEmc), g.thetaEmc, g.phiEmc) - Vec3(0.0, 0.0, z);
    const double theta = geometry::polar(point), phi = geometry::azimuth(point);
    e.photons[i] = {g.energy,
                    theta,
                    phi,
                    res.photonEnergyStochastic * g.energy / std::pow(g.energy / 1000.0, 0.25),
                    res.photonTheta,
                    res.photonPhiSinTheta / std::sin(theta)};
  }
  for (std::size_t j = 0; j < 2; ++j) {
    const ParticleRow& t = rows[tracks[j]];
    e.pions[j] = {t.thetaTs, t.phiTs, res.trackTheta, res.trackPhi};
  }
  e.totalEnergy = 2.0 * rows[0].beamEnergy;
  return e;
}

// A distribution's core as check.json gives it: in degrees, NaN where the core was not fitted.
CheckWidth checkWidth(const CoreWidth& w) {
  const double nan = std::nan("");
  return {.width = w.fitted ? w.width : nan,
          .widthError = w.fitted ? w.widthError : nan,
          .mean = w.fitted ? w.mean : nan,
          .rms = w.rms};
}

double improvement(double before, double after) {
  return before > 0.0 && std::isfinite(before) && std::isfinite(after) ? 100.0 * (before - after) / before
                                                                       : std::nan("");
}

}  // namespace

std::string_view name(CheckProcess process) { return process == CheckProcess::GammaGamma ? "gg" : "3pi"; }

std::optional<CheckProcess> checkProcessFromName(std::string_view name) {
  if (name == "gg") return CheckProcess::GammaGamma;
  if (name == "3pi") return CheckProcess::ThreePion;
  return std::nullopt;
}

std::string_view finalState(CheckProcess process) {
  return process == CheckProcess::GammaGamma ? "e+e- -> gamma gamma" : "e+e- -> pi+ pi- pi0";
}

Json CheckCutFlow::json() const {
  Json j = Json::object();
  for (std::size_t k = 0; k < names.size(); ++k) j[names[k]] = events[k];
  return j;
}

Status CheckCutFlow::requireSelected(CheckProcess process) const {
  if (!events.empty() && events.back() > 0) return {};
  std::string text;
  for (std::size_t k = 0; k < names.size() && k < events.size(); ++k) {
    text += fmt::format("{}{} {}", k ? ", " : "", names[k], events[k]);
  }
  return Error{fmt::format("no event passes the {} selection ({}): nothing to check", finalState(process), text)};
}

CoreWidth gaussianCore(std::span<const double> values) {
  CoreWidth w;
  std::vector<double> v;
  for (double x : values) {
    if (std::isfinite(x)) v.push_back(x);
  }
  w.entries = static_cast<std::int64_t>(v.size());
  if (v.empty()) return w;
  const double n = static_cast<double>(v.size());
  const double mean = std::accumulate(v.begin(), v.end(), 0.0) / n;
  double ss = 0.0;
  for (double x : v) ss += (x - mean) * (x - mean);
  w.rms = std::sqrt(ss / n);
  if (v.size() < 20) return w;
  // Start: the median and the MAD (σ of a Gaussian = 1.4826 MAD).
  double mu = median(v);
  std::vector<double> dev;
  dev.reserve(v.size());
  for (double x : v) dev.push_back(std::abs(x - mu));
  double sigma = 1.4826 * median(dev);
  if (!(sigma > 0.0)) return w;
  // Binned Poisson likelihood of N·Gauss(μ, σ) over [μ − 2σ, μ + 2σ], Newton steps on
  // (N, μ, σ); the window follows the fit.
  Eigen::Matrix3d fisher = Eigen::Matrix3d::Zero();
  for (int pass = 0; pass < 4; ++pass) {
    const double low = mu - 2.0 * sigma, high = mu + 2.0 * sigma;
    const int bins = std::clamp(static_cast<int>(std::sqrt(n) / 2.0), 10, 60);
    const double width = (high - low) / bins;
    std::vector<double> counts(static_cast<std::size_t>(bins), 0.0);
    for (double x : v) {
      if (x >= low && x < high) counts[static_cast<std::size_t>((x - low) / width)] += 1.0;
    }
    double amplitude =
        std::accumulate(counts.begin(), counts.end(), 0.0) / 0.9545 * width / (sigma * std::sqrt(2.0 * M_PI));
    for (int it = 0; it < 50; ++it) {
      Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
      fisher.setZero();
      for (int k = 0; k < bins; ++k) {
        const double x = low + (k + 0.5) * width, t = (x - mu) / sigma;
        const double g = std::exp(-0.5 * t * t);
        const double f = amplitude * g;
        const Eigen::Vector3d d(g, f * t / sigma, f * t * t / sigma);  // ∂f/∂(A, μ, σ)
        const double nk = counts[static_cast<std::size_t>(k)];
        gradient += (nk / std::max(f, 1e-12) - 1.0) * d;
        fisher += d * d.transpose() / std::max(f, 1e-12);
      }
      const Eigen::Vector3d step = fisher.ldlt().solve(gradient);
      if (!step.allFinite()) return w;
      amplitude += step[0];
      mu += step[1];
      sigma = std::abs(sigma + step[2]);
      if (std::abs(step[1]) < 1e-9 * sigma && std::abs(step[2]) < 1e-9 * sigma) break;
    }
    if (!(sigma > 0.0 && amplitude > 0.0)) return w;
  }
  const Eigen::Matrix3d covariance = fisher.inverse();
  w.mean = mu;
  w.width = sigma;
  w.meanError = std::sqrt(covariance(1, 1));
  w.widthError = std::sqrt(covariance(2, 2));
  w.fitted = std::isfinite(w.widthError) && std::isfinite(w.meanError);
  return w;
}

Result<GammaGammaCheck> checkGammaGamma(const std::vector<std::string>& before, const std::vector<std::string>& after) {
  GammaGammaCheck c;
  c.cutFlow.names = {"events",       "two photons, no track", "E > 0.7 E_beam", "|E1 - E2| < 150 MeV",
                     "no muon veto", "36 < theta < 144 deg"};
  c.cutFlow.events.assign(c.cutFlow.names.size(), 0);
  Status s =
      forEachEventPair(before, after, [&](std::span<const ParticleRow> rows, std::span<const ParticleRow> corrected) {
        auto& flow = c.cutFlow.events;
        ++flow[0];
        if (rows.size() != 2) return Status{};
        for (const auto& r : rows) {
          if (r.hasTrack() || r.charged != 0 || !r.hasCluster()) return Status{};
        }
        ++flow[1];
        const double beam = rows[0].beamEnergy;
        if (!(rows[0].energy > 0.7 * beam && rows[1].energy > 0.7 * beam)) return Status{};
        ++flow[2];
        if (!(std::abs(rows[0].energy - rows[1].energy) < 150.0 * units::MeV)) return Status{};
        ++flow[3];
        if (rows[0].muonVeto != 0) return Status{};
        ++flow[4];
        for (const auto& r : rows) {
          if (!(r.thetaEmc > 36.0 * kDeg && r.thetaEmc < 144.0 * kDeg)) return Status{};
        }
        ++flow[5];
        for (int k = 0; k < 2; ++k) {
          const auto& ev = k == 0 ? rows : corrected;
          double dphi = 0.0, dtheta = 0.0;
          acollinearity(ev[0], ev[1], dphi, dtheta);
          c.dphi[static_cast<std::size_t>(k)].push_back(dphi);
          c.dtheta[static_cast<std::size_t>(k)].push_back(dtheta);
        }
        return Status{};
      });
  if (!s) return s.error();
  return c;
}

Result<ThreePionCheck> checkThreePion(const std::vector<std::string>& before, const std::vector<std::string>& after,
                                      const geometry::DepthAtEnergy& depthAt, const ResolutionModel& resolution) {
  ThreePionCheck c;
  geometry::ShowerDepth depth;  // at depthEnergy
  double depthEnergy = std::numeric_limits<double>::quiet_NaN();
  c.cutFlow.names = {"events",
                     "two tracks, two photons",
                     "36 < theta_tracks < 144 deg",
                     "tracks not collinear in phi (> 10 deg)",
                     "angle between tracks < 147 deg",
                     "E_gamma1 + E_gamma2 > 100 MeV"};
  c.cutFlow.events.assign(c.cutFlow.names.size(), 0);
  Status s =
      forEachEventPair(before, after, [&](std::span<const ParticleRow> rows, std::span<const ParticleRow> corrected) {
        auto& flow = c.cutFlow.events;
        ++flow[0];
        std::array<std::size_t, 2> tracks{}, photons{};
        std::size_t nTracks = 0, nPhotons = 0;
        for (std::size_t k = 0; k < rows.size(); ++k) {
          if (rows[k].hasTrack()) {
            if (nTracks < 2) tracks[nTracks] = k;
            ++nTracks;
          } else if (rows[k].hasCluster()) {
            if (nPhotons < 2) photons[nPhotons] = k;
            ++nPhotons;
          }
        }
        if (nTracks != 2 || nPhotons != 2) return Status{};
        ++flow[1];
        const ParticleRow &t1 = rows[tracks[0]], &t2 = rows[tracks[1]];
        for (const ParticleRow* t : {&t1, &t2}) {
          if (!(t->thetaTs > 36.0 * kDeg && t->thetaTs < 144.0 * kDeg)) return Status{};
        }
        ++flow[2];
        if (!(std::abs(180.0 - std::abs(t1.phiTs - t2.phiTs) / kDeg) > 10.0)) return Status{};
        ++flow[3];
        const double cosAngle =
            geometry::pointAt(1.0, t1.thetaTs, t1.phiTs).dot(geometry::pointAt(1.0, t2.thetaTs, t2.phiTs));
        if (!(std::acos(std::clamp(cosAngle, -1.0, 1.0)) < 147.0 * kDeg)) return Status{};
        ++flow[4];
        if (!(rows[photons[0]].energy + rows[photons[1]].energy > 100.0 * units::MeV)) return Status{};
        ++flow[5];
        if (rows[0].beamEnergy != depthEnergy) {
          auto d = depthAt(rows[0].beamEnergy);
          if (!d)
            return Status{
                Error{fmt::format("run {} ({} MeV): {}", rows[0].run, rows[0].beamEnergy, d.error().message)}};
          depth = *d;
          depthEnergy = rows[0].beamEnergy;
        }
        for (int k = 0; k < 2; ++k) {
          const auto& ev = k == 0 ? rows : corrected;
          c.fits[static_cast<std::size_t>(k)].push_back(
              fitThreePion(threePionEvent(ev, tracks, photons, depth, resolution)));
        }
        return Status{};
      });
  if (!s) return s.error();
  return c;
}

CheckRecord checkRecord(const GammaGammaCheck& c) {
  CheckRecord r{.process = CheckProcess::GammaGamma,
                .selected = static_cast<std::int64_t>(c.dphi[0].size()),
                .cutFlow = c.cutFlow,
                .vertex = "the origin (a gamma-gamma event has no track)"};
  std::array<CoreWidth, 2> phi, theta;
  for (std::size_t k = 0; k < 2; ++k) {
    phi[k] = gaussianCore(c.dphi[k]);
    theta[k] = gaussianCore(c.dtheta[k]);
    CheckSide& side = k == 0 ? r.before : r.after;
    side.dphi = checkWidth(phi[k]);
    side.dtheta = checkWidth(theta[k]);
  }
  r.improvement = {.dphiWidth = improvement(phi[0].width, phi[1].width),
                   .dphiRms = improvement(phi[0].rms, phi[1].rms),
                   .dthetaWidth = improvement(theta[0].width, theta[1].width),
                   .dthetaRms = improvement(theta[0].rms, theta[1].rms)};
  return r;
}

CheckRecord checkRecord(const ThreePionCheck& c) {
  CheckRecord r{.process = CheckProcess::ThreePion,
                .selected = static_cast<std::int64_t>(c.fits[0].size()),
                .ndf = KinematicFitResult::kNdf,
                .cutFlow = c.cutFlow,
                .vertex = "z: the mean z0 of the two tracks"};
  for (std::size_t k = 0; k < 2; ++k) {
    std::vector<double> chi2;
    std::int64_t failed = 0;
    double pSum = 0.0;
    for (const auto& f : c.fits[k]) {
      if (f.converged) {
        chi2.push_back(f.chi2);
        pSum += f.pValue;
      } else {
        ++failed;
      }
    }
    double truncated = 0.0;
    std::int64_t inCore = 0;
    for (double x : chi2) {
      if (x < kChi2Tail) {
        truncated += x;
        ++inCore;
      }
    }
    const double n = static_cast<double>(chi2.size());
    CheckSide& side = k == 0 ? r.before : r.after;
    side.chi2Mean = chi2.empty() ? std::nan("") : std::accumulate(chi2.begin(), chi2.end(), 0.0) / n;
    side.chi2Median = median(chi2);
    side.chi2MeanBelow20 = inCore > 0 ? truncated / static_cast<double>(inCore) : std::nan("");
    side.fractionAbove20 = chi2.empty() ? std::nan("") : 1.0 - static_cast<double>(inCore) / n;
    side.pValueMean = chi2.empty() ? std::nan("") : pSum / n;
    side.converged = static_cast<std::int64_t>(chi2.size());
    side.notConverged = failed;
  }
  r.improvement = {.chi2Mean = improvement(r.before.chi2Mean, r.after.chi2Mean),
                   .chi2Median = improvement(r.before.chi2Median, r.after.chi2Median)};
  return r;
}

}  // namespace emcalign::apply
