#include "emcalign/sim/calorimeter_response.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include <fmt/format.h>

#include "emcalign/core/special_functions.hpp"
#include "emcalign/core/units.hpp"

namespace emcalign::sim {

using geometry::Hemisphere;
using geometry::Region;
using geometry::Support;

Status EmcOptions::validate(int counters) const {
  if (!(moliereRadius > 0.0) || !(profileB > 0.0) || !(coreRadius > 0.0) || !(tailRadius > 0.0) || !(maxRadius > 0.0)) {
    return Error{"emc: Moliere radius, profile b and lateral radii must be positive"};
  }
  if (!(coreFraction >= 0.0 && coreFraction <= 1.0)) return Error{"emc: coreFraction must be in [0, 1]"};
  if (spotsLongitudinal < 1 || spotsLateral < 1) return Error{"emc: need at least one spot"};
  if (!(resolutionAt1GeV >= 0.0) || !(smearingShare >= 0.0 && smearingShare <= 1.0)) {
    return Error{"emc: resolution must be non-negative and its smearing share in [0, 1]"};
  }
  if (!(noiseSigma >= 0.0) || !(counterThreshold >= 0.0)) return Error{"emc: noise and threshold must be >= 0"};
  if (!(mipDedx >= 0.0) || !(nuclearInteractionLength > 0.0)) return Error{"emc: bad ionisation constants"};
  if (!(backgroundHitsPerEvent >= 0.0) || !(backgroundMeanEnergy > 0.0)) return Error{"emc: bad background"};
  for (int c : deadCounters) {
    if (c < 0 || c >= counters) {
      return Error{fmt::format("dead counter {} does not exist (counters are 0..{})", c, counters - 1)};
    }
  }
  if (!layer3Offset.allFinite()) return Error{"emc: layer-3 offset must be finite"};
  if (!std::isfinite(tMaxShift) || std::abs(tMaxShift) > 5.0) return Error{"emc: the t_max shift must be within ±5 X0"};
  if (!(tMaxFluctuationScale >= 0.0 && tMaxFluctuationScale <= 10.0)) {
    return Error{"emc: the t_max fluctuation scale must be in [0, 10]"};
  }
  if (preshowerMaterial && !(*preshowerMaterial >= 0.0 && *preshowerMaterial <= 10.0)) {
    return Error{"emc: the material before the EMC must be in [0, 10] X0"};
  }
  if (!(counterGainSpread >= 0.0 && counterGainSpread <= 0.5)) return Error{"emc: the gain spread must be in [0, 0.5]"};
  return {};
}

ActualPlacement::ActualPlacement(const geometry::AlignmentTransform& truth, const Vec3& layer3Offset) {
  for (Support s : {Support::Inner, Support::Outer}) {
    for (Hemisphere h : {Hemisphere::Plus, Hemisphere::Minus}) {
      geometry::RigidTransform t = truth.placement(h, s);
      if (s == Support::Outer) t.translation += layer3Offset;
      placements_[(h == Hemisphere::Plus ? 0 : 1) + (s == Support::Outer ? 2 : 0)] = t;
    }
  }
}

// ------------------------------------------------------------------- CounterHits

CounterHits::CounterHits(int counters)
    : energy_(static_cast<std::size_t>(counters), 0.0),
      contrib_(static_cast<std::size_t>(counters), std::array<float, kMaxSources>{}),
      nominalMoment_(static_cast<std::size_t>(counters), Vec3::Zero()),
      recorded_(static_cast<std::size_t>(counters), 0.0),
      hasRecorded_(static_cast<std::size_t>(counters), 0) {
  touched_.reserve(256);
  fired_.reserve(256);
  sourceSum_.fill(Vec3::Zero());
}

void CounterHits::clear() {
  for (int c : touched_) {
    energy_[static_cast<std::size_t>(c)] = 0.0;
    contrib_[static_cast<std::size_t>(c)].fill(0.0f);
    nominalMoment_[static_cast<std::size_t>(c)].setZero();
    recorded_[static_cast<std::size_t>(c)] = 0.0;
    hasRecorded_[static_cast<std::size_t>(c)] = 0;
  }
  touched_.clear();
  fired_.clear();
  sourceSum_.fill(Vec3::Zero());
  sourceEnergy_.fill(0.0);
}

void CounterHits::add(int counter, int source, double energy, const Vec3& where, const Vec3& nominal) {
  addToCounter(counter, source, energy, nominal);
  addToSource(source, energy, energy * where);
}

void CounterHits::addToCounter(int counter, int source, double energy, const Vec3& nominal) {
  const auto c = static_cast<std::size_t>(counter);
  if (energy_[c] == 0.0) touched_.push_back(counter);
  energy_[c] += energy;
  nominalMoment_[c] += energy * nominal;
  contrib_[c][static_cast<std::size_t>(source)] += static_cast<float>(energy);
}

void CounterHits::addToSource(int source, double energy, const Vec3& moment) {
  sourceSum_[static_cast<std::size_t>(source)] += moment;
  sourceEnergy_[static_cast<std::size_t>(source)] += energy;
}

void CounterHits::addRecorded(int counter, double energy, const Vec3& centre) {
  const auto c = static_cast<std::size_t>(counter);
  if (energy_[c] == 0.0 && hasRecorded_[c] == 0) touched_.push_back(counter);
  recorded_[c] += energy;
  hasRecorded_[c] = 1;
  nominalMoment_[c] += energy * centre;
  contrib_[c][kBackground] += static_cast<float>(energy);
  addToSource(kBackground, energy, energy * centre);
}

void CounterHits::digitize(const EmcOptions& o, std::span<const double> gains, Rng& rng) {
  // Only counters with a deposit get noise: with σ = 0.3 MeV and a 2 MeV threshold a
  // noise-only counter fires with probability ~1e-11.
  std::sort(touched_.begin(), touched_.end());
  for (int c : touched_) {
    double& e = energy_[static_cast<std::size_t>(c)];
    if (!gains.empty()) e *= gains[static_cast<std::size_t>(c)];
    if (hasRecorded_[static_cast<std::size_t>(c)] != 0) {
      e += recorded_[static_cast<std::size_t>(c)];
    } else if (o.noise) {
      e += o.noiseSigma * rng.normal();
    }
    if (e >= o.counterThreshold) fired_.push_back(c);
  }
}

Vec3 CounterHits::sourceCentre(int source) const {
  const auto s = static_cast<std::size_t>(source);
  if (sourceEnergy_[s] <= 0.0) return Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  return sourceSum_[s] / sourceEnergy_[s];
}

// ------------------------------------------------------------------- response

CalorimeterResponse::CalorimeterResponse(const geometry::Calorimeter& calo, const geometry::AlignmentTransform& truth,
                                         EmcOptions options)
    : calo_(&calo),
      actual_(truth, options.layer3OffsetOn ? options.layer3Offset : Vec3::Zero()),
      options_(std::move(options)),
      dead_(static_cast<std::size_t>(calo.size()), 0) {
  if (options_.deadCountersOn) {
    for (int c : options_.deadCounters) dead_[static_cast<std::size_t>(c)] = 1;
  }
  if (options_.counterGainSpread > 0.0) {
    gains_.resize(static_cast<std::size_t>(calo.size()));
    for (std::size_t c = 0; c < gains_.size(); ++c) {
      Rng rng(options_.gainSeed, c);
      gains_[c] = std::max(0.0, 1.0 + options_.counterGainSpread * rng.normal());
    }
  }
  const double r1 = calo.description().supports[0].rOuter;
  r1Squared_ = r1 * r1;
  auto cdf = [&](double radius) {
    const double x = options_.maxRadius / radius;
    return x * x / (x * x + 1.0);
  };
  constexpr double kMargin = 12.0 * units::deg;
  cosCoverageMin_ = std::cos(std::max(0.0, calo.description().thetaMin - kMargin));
  cosCoverageMax_ = std::cos(std::min(std::numbers::pi, calo.description().thetaMax + kMargin));
  lateralCos_ = std::cos(2.0 * std::numbers::pi / options_.spotsLateral);
  lateralSin_ = std::sin(2.0 * std::numbers::pi / options_.spotsLateral);
  coreCdfMax_ = cdf(options_.coreRadius);
  tailCdfMax_ = cdf(options_.tailRadius);
}

bool CalorimeterResponse::nearCoverage(const Vec3& p) const {
  // Within 12° of the covered θ range: a shower further out cannot reach a counter (its
  // spots stay within 2 Molière radii ≈ 8 cm, under 12° at the inner radius).
  const double cosTheta = p.z() / p.norm();
  return cosTheta < cosCoverageMin_ && cosTheta > cosCoverageMax_;
}

template <typename OuterFrame>
std::optional<int> CalorimeterResponse::counterOnSide(Hemisphere h, const Vec3& inner, OuterFrame outer,
                                                      Vec3& nominal) const {
  if (geometry::hemisphereOf(inner.x()) != h) return std::nullopt;
  nominal = inner;
  if (inner.squaredNorm() >= r1Squared_) {  // beyond support sphere 1: layer 3's own placement
    nominal = outer();
    if (geometry::hemisphereOf(nominal.x()) != h) return std::nullopt;
  }
  const geometry::Location loc = calo_->locate(nominal);
  return loc.region == Region::Counter && !isDead(loc.counter) ? loc.counter : -1;
}

int CalorimeterResponse::counterAt(const Vec3& p, Hemisphere hint, Vec3* nominalOut) const {
  const Hemisphere other = hint == Hemisphere::Plus ? Hemisphere::Minus : Hemisphere::Plus;
  for (Hemisphere h : {hint, other}) {
    Vec3 nominal;
    const auto c = counterOnSide(
        h, actual_.placement(h, Support::Inner).applyInverse(p),
        [&] { return actual_.placement(h, Support::Outer).applyInverse(p); }, nominal);
    if (!c) continue;
    if (*c >= 0 && nominalOut != nullptr) *nominalOut = nominal;
    return *c;
  }
  return -1;  // between the hemispheres
}

void CalorimeterResponse::deposit(CounterHits& hits, int source, double energy, const Vec3& where,
                                  Hemisphere hint) const {
  Vec3 nominal;
  const int c = counterAt(where, hint, &nominal);
  if (c >= 0) hits.add(c, source, energy, where, nominal);
}

double CalorimeterResponse::entry(const Vec3& p, const Vec3& d, Hemisphere& hemisphere) const {
  // In a hemisphere's own frame its inner surface is the sphere |q| = R0; rigid motions keep
  // the line parameter, so the entry is p + s·d with s found in that frame.
  const double r0 = calo_->description().r0();
  auto crossing = [r0](const Vec3& q, const Vec3& e) {
    const double b = q.dot(e);
    const double disc = b * b - q.squaredNorm() + r0 * r0;
    return disc < 0.0 ? -1.0 : -b + std::sqrt(disc);
  };
  const Vec3 guess = p + crossing(p, d) * d;
  const Hemisphere first = geometry::hemisphereOf(guess.x());
  for (Hemisphere h : {first, first == Hemisphere::Plus ? Hemisphere::Minus : Hemisphere::Plus}) {
    const auto& t = actual_.placement(h, Support::Inner);
    const Vec3 q = t.applyInverse(p), e = t.rotation.transpose() * d;
    const double s = crossing(q, e);
    if (s >= 0.0 && geometry::hemisphereOf((q + s * e).x()) == h) {
      hemisphere = h;
      return s;
    }
  }
  hemisphere = first;  // enters through the gap: the spots find their own hemisphere
  return crossing(p, d);
}

namespace {

// The share of the shower's energy the counters see: the stochastic term's smearing (its share
// of the resolution σ/E^¼ at 1 GeV) drawn, or 1 without it.
inline double showerGain(const EmcOptions& o, double energy, Rng& rng) {
  double gain = 1.0;
  if (o.energyResolution && o.resolutionAt1GeV > 0.0) {
    const double sigma = o.smearingShare * o.resolutionAt1GeV / std::pow(energy / 1000.0, 0.25);
    gain = std::max(0.0, 1.0 + sigma * rng.normal());
  }
  return gain;
}

// The shower maximum t_max in X0 from the shower start: ln(E/Ec) + 0.5 for a photon, − 0.5 for
// an electron, shifted, its log-normal fluctuation drawn.
inline double showerMaximum(const EmcOptions& o, double lnY, bool photon, Rng& rng) {
  double tMax = std::max(0.3, lnY + (photon ? 0.5 : -0.5) + o.tMaxShift);
  if (o.showerFluctuations) {
    const double sigmaLn = o.tMaxFluctuationScale * std::clamp(1.0 / (1.26 * lnY - 1.4), 0.05, 0.5);
    tMax = std::max(0.3, tMax * std::exp(sigmaLn * rng.normal() - 0.5 * sigmaLn * sigmaLn));
  }
  return tMax;
}

// Depth along the axis is counted in radiation lengths of material (τ, from the shower start in
// the pre-material): pre-material [0, p), NaI up to support sphere 1, the support (aluminium,
// thin in X0), NaI of layer 3, exit. Energy falling in the pre-material, the support or beyond
// the exit is lost; the fractions come from the Gamma CDF and spot depths are drawn inside the
// NaI only, so that the losses follow t_max smoothly instead of jumping by whole spots.
struct AxisMaterial {
  double preshower = 0.0;  // X0 before the EMC
  double tauA = 0.0;       // the support begins
  double tauB = 0.0;       // the support ends
  double tauEnd = 0.0;     // layer 3 ends
  double sB = 0.0;         // cm along the axis from the start to the support's end
  double x0 = 0.0;         // cm, NaI's radiation length

  // Material depth → distance from the start.
  [[nodiscard]] double geometric(double tau) const {
    return tau < tauA ? (tau - preshower) * x0 : sB + (tau - tauB) * x0;
  }

  // The share of the longitudinal profile Gamma(a, b) in the NaI.
  [[nodiscard]] double insideShare(double a, double b) const {
    const double logGammaA = std::log(std::tgamma(a));  // thread-safe, unlike std::lgamma
    const double pPre = regularizedGammaP(a, b * preshower, logGammaA);
    const double pA = regularizedGammaP(a, b * tauA, logGammaA);
    const double pB = regularizedGammaP(a, b * tauB, logGammaA);
    const double pEnd = regularizedGammaP(a, b * tauEnd, logGammaA);
    return (pA - pPre) + (pEnd - pB);
  }

  // A spot's depth τ, drawn from the profile inside the NaI (after 64 tries, the last draw
  // moved into it).
  [[nodiscard]] double drawDepth(double a, double b, Rng& rng) const {
    double tau = 0.0;
    for (int tries = 0; tries < 64; ++tries) {
      tau = rng.gamma(a, 1.0 / b);
      if ((tau >= preshower && tau < tauA) || (tau >= tauB && tau < tauEnd)) break;
      tau = tau < tauA ? std::max(tau, preshower) : std::min(std::max(tau, tauB), tauEnd);  // after 64 tries
    }
    return tau;
  }
};

inline AxisMaterial axisMaterial(const geometry::DetectorDescription& d, const EmcOptions& o, const Vec3& start,
                                 const Vec3& direction, double preshower) {
  auto distanceTo = [&](double radius) {  // along the axis from the start, to |x| = radius
    const double bb = start.dot(direction);
    return -bb + std::sqrt(std::max(0.0, bb * bb - start.squaredNorm() + radius * radius));
  };
  const double sA = distanceTo(d.supports[0].rInner), sB = distanceTo(d.supports[0].rOuter);
  const double sExit = distanceTo(d.supports[1].rInner);
  AxisMaterial m;
  m.x0 = d.material.radiationLength;
  m.preshower = preshower;
  m.sB = sB;
  m.tauA = preshower + sA / m.x0;
  m.tauB = m.tauA + (sB - sA) / o.supportRadiationLength;
  m.tauEnd = m.tauB + std::max(0.0, sExit - sB) / m.x0;
  return m;
}

}  // namespace

void CalorimeterResponse::shower(CounterHits& hits, int source, double energy, Showering particle, const Vec3& point,
                                 const Vec3& direction, Rng& rng) const {
  const auto& o = options_;
  const auto& m = calo_->description().material;
  Hemisphere h;
  const double s = entry(point, direction, h);
  if (s < 0.0) return;
  const Vec3 start = point + s * direction;
  if (!nearCoverage(start)) return;  // through the end-cap holes: nothing to deposit
  const double sinTheta = std::max(1e-3, std::hypot(direction.x(), direction.y()));
  const double preshower = o.preshowerMaterial.value_or(m.preshowerMaterial) / sinTheta;  // X0 before the EMC
  const double lnY = std::log(std::max(energy / m.criticalEnergy, 1.01));
  const double gain = showerGain(o, energy, rng);

  if (o.pointShowers) {
    // The fit model's idealisation: everything at t_max = ln(E/Ec) − 0.5 from the shower
    // start, i.e. at R(E, θ) for a radial line from the origin.
    const double depth = (lnY - 0.5 - preshower) * m.radiationLength;
    deposit(hits, source, gain * energy, start + depth * direction, h);
    return;
  }

  const double tMax = showerMaximum(o, lnY, particle == Showering::Photon, rng);
  const double b = o.profileB, a = 1.0 + b * tMax;
  const AxisMaterial axis = axisMaterial(calo_->description(), o, start, direction, preshower);
  const double inside = axis.insideShare(a, b);
  if (inside <= 0.0) return;

  const Vec3 e1 = (std::abs(direction.z()) < 0.9 ? Vec3::UnitZ() : Vec3::UnitX()).cross(direction).normalized();
  const ShowerFrame frame = showerFrame(h, start, direction, e1, direction.cross(e1));
  const double spotEnergy = gain * energy * inside / (o.spotsLongitudinal * o.spotsLateral);
  // Spots are drawn a batch at a time and then deposited: their square roots and divisions
  // overlap instead of each waiting for the previous spot's counter.
  std::array<Spot, kSpotBatch> batch;
  std::size_t batched = 0;
  for (int i = 0; i < o.spotsLongitudinal; ++i) {
    const double tau = axis.drawDepth(a, b, rng);
    // geometric(tau), rounded as the depth t·X0 always was (the same events as before).
    const double along = axis.geometric(tau) / axis.x0 * m.radiationLength;
    // Lateral spots at azimuths spread evenly from a random start (stratified sampling:
    // one random rotation per depth, then exact turns by 2π/n).
    double c, sn;
    rng.unitCircle(c, sn);
    for (int j = 0; j < o.spotsLateral; ++j) {
      // f(r) ∝ r·R²/(r² + R²)² has F(r) = r²/(r² + R²): r = R·√(u/(1 − u)), with u drawn
      // below F(r_max) so that no spot lands beyond r_max.
      const bool core = rng.uniform() < o.coreFraction;
      const double scale = (core ? o.coreRadius : o.tailRadius) * o.moliereRadius;
      const double u = rng.uniform() * (core ? coreCdfMax_ : tailCdfMax_);
      batch[batched++] = {along, scale * std::sqrt(u / (1.0 - u)), c, sn};
      if (batched == batch.size()) {
        depositSpots(hits, source, spotEnergy, frame, h, {batch.data(), batched});
        batched = 0;
      }
      const double turned = c * lateralCos_ - sn * lateralSin_;
      sn = sn * lateralCos_ + c * lateralSin_;
      c = turned;
    }
  }
  depositSpots(hits, source, spotEnergy, frame, h, {batch.data(), batched});
}

CalorimeterResponse::ShowerFrame CalorimeterResponse::showerFrame(Hemisphere h, const Vec3& start, const Vec3& axis,
                                                                  const Vec3& e1, const Vec3& e2) const {
  const auto nominal = [&](Support s) {
    const geometry::RigidTransform& t = actual_.placement(h, s);
    const Mat3 back = t.rotation.transpose();
    return Basis{t.applyInverse(start), back * axis, back * e1, back * e2};
  };
  return {Basis{start, axis, e1, e2}, nominal(Support::Inner), nominal(Support::Outer)};
}

void CalorimeterResponse::depositSpots(CounterHits& hits, int source, double energy, const ShowerFrame& f, Hemisphere h,
                                       std::span<const Spot> spots) const {
  Vec3 moment = Vec3::Zero();  // Σ where of the deposited spots: the source's centre
  int deposited = 0;
  for (const Spot& spot : spots) {
    const Vec3 where = f.ts.at(spot);
    // counterAt's first try, with the spot placed in the entered hemisphere's frames by the
    // shower's basis instead of a matrix product.
    Vec3 nominal;
    std::optional<int> c = counterOnSide(
        h, f.inner.at(spot), [&] { return f.outer.at(spot); }, nominal);
    if (!c) c = counterAt(where, h == Hemisphere::Plus ? Hemisphere::Minus : Hemisphere::Plus, &nominal);
    if (*c >= 0) {
      hits.addToCounter(*c, source, energy, nominal);
      moment += where;
      ++deposited;
    }
  }
  hits.addToSource(source, deposited * energy, energy * moment);
}

void CalorimeterResponse::track(CounterHits& hits, int source, double kineticEnergy, Tracking particle,
                                const Vec3& point, const Vec3& direction, Rng& rng) const {
  const auto& o = options_;
  Hemisphere h;
  const double s = entry(point, direction, h);
  if (s < 0.0) return;
  const Vec3 start = point + s * direction;
  if (!nearCoverage(start)) return;
  const double thickness = calo_->description().supports[1].rOuter - calo_->description().r0();
  const double length = 1.5 * thickness;  // ample for any slant path through the EMC
  const double interaction = particle == Tracking::Pion ? rng.exponential(o.nuclearInteractionLength) : 1e30;
  const double step = 2.0;
  double deposited = 0.0;
  // Counted, not accumulated: a step that no longer changes a huge length cannot hang.
  const int steps = static_cast<int>(std::clamp(std::ceil(std::min(length, interaction) / step - 0.5), 0.0, 1e4));
  for (int i = 0; i < steps; ++i) {
    const double l = (i + 0.5) * step;
    const double e = o.mipDedx * step;
    deposit(hits, source, e, start + l * direction, h);
    deposited += e;
  }
  if (interaction < length) {
    // A hadronic blob: a fraction of the remaining kinetic energy, spread over ~10 cm.
    const double e = std::max(0.0, kineticEnergy - deposited) * rng.uniform(0.1, 0.7);
    const Vec3 at = start + interaction * direction;
    Vec3 e1 = (std::abs(direction.z()) < 0.9 ? Vec3::UnitZ() : Vec3::UnitX()).cross(direction).normalized();
    const Vec3 e2 = direction.cross(e1);
    constexpr int kSpots = 8;
    for (int i = 0; i < kSpots; ++i) {
      double c, sn;
      rng.unitCircle(c, sn);
      const Vec3 where = at + rng.exponential(8.0) * direction + rng.exponential(4.0) * (c * e1 + sn * e2);
      deposit(hits, source, e / kSpots, where, h);
    }
  }
}

void CalorimeterResponse::background(CounterHits& hits, Rng& rng) const {
  const auto& o = options_;
  if (!o.beamBackground) return;
  const int n = rng.poisson(o.backgroundHitsPerEvent);
  for (int i = 0; i < n; ++i) {
    const int c = static_cast<int>(rng.uniform() * calo_->size());
    if (isDead(c)) continue;
    const Vec3 centre = calo_->counter(c).centre();
    hits.add(c, CounterHits::kBackground, rng.exponential(o.backgroundMeanEnergy), centre, centre);
  }
}

void CalorimeterResponse::mergeRecorded(CounterHits& hits, std::span<const Hit> recorded) const {
  if (!options_.beamBackground) return;
  for (const Hit& h : recorded) {
    if (isDead(h.counter)) continue;
    hits.addRecorded(h.counter, h.energy, calo_->counter(h.counter).centre());
  }
}

}  // namespace emcalign::sim
