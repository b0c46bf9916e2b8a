#include "emcalign/sim/generators.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

namespace emcalign::sim {

namespace {

using std::numbers::pi;
using units::deg;

constexpr double kMe2 = mass::Electron * mass::Electron;
constexpr double kAlphaOverPi = kAlpha / pi;
constexpr double kPiThreshold = 2.0 * mass::PiCharged + mass::Pi0;
/// ρ(770) width (PDG); the mass is mass::Rho.
constexpr double kRhoWidth = 149.1 * units::MeV;
/// Largest angle of a final-state photon to its lepton (assumed: each lepton radiates into its
/// own hemisphere of the CM frame, so the two collinear laws tile the sphere).
constexpr double kMaxFsrAngle = 0.5 * pi;
/// Safety factor on the largest π+π−π0 weight found on the grid.
constexpr double kThreePionMargin = 1.25;
constexpr int kThreePionGrid = 200;

// ---------------------------------------------------------------------------------------
// Small kinematics

/// Unit vectors e1, e2 with (e1, e2, n) right-handed and orthonormal, for a unit n, without
/// trigonometry or a branch on a near-degenerate case (Duff et al., JCGT 6(1) 2017).
void orthonormalBasis(const Vec3& n, Vec3& e1, Vec3& e2) {
  const double sign = std::copysign(1.0, n.z());
  const double a = -1.0 / (sign + n.z());
  const double b = n.x() * n.y() * a;
  e1 = Vec3(1.0 + sign * n.x() * n.x() * a, sign * b, -sign * n.x());
  e2 = Vec3(b, sign + n.y() * n.y() * a, -n.y());
}

/// A unit vector at polar cosine c and a uniformly random azimuth.
Vec3 directionAt(double c, Rng& rng) {
  double cphi, sphi;
  rng.unitCircle(cphi, sphi);
  const double s = std::sqrt(std::max(0.0, 1.0 - c * c));
  return {s * cphi, s * sphi, c};
}

/// Boost along z by (γ, γβ).
void boostZ(GeneratedParticle& q, double gamma, double gammaBeta) {
  const double e = q.energy, pz = q.momentum.z();
  q.energy = gamma * e + gammaBeta * pz;
  q.momentum.z() = gamma * pz + gammaBeta * e;
}

/// From the CM frame of the colliding pair (massless e- of energy e1 along +z, e+ of e2
/// along −z) to the lab. Nothing to do for equal energies.
void toLab(GeneratedEvent& event, std::size_t first, double e1, double e2) {
  if (e1 == e2) return;
  const double sqrtS = 2.0 * std::sqrt(e1 * e2);
  const double gamma = (e1 + e2) / sqrtS, gammaBeta = (e1 - e2) / sqrtS;
  for (std::size_t i = first; i < event.particles.size(); ++i) {
    boostZ(event.particles[i], gamma, gammaBeta);
  }
}

/// Whether the polar angle of p lies in the range [acos(cosHi), acos(cosLo)].
bool inPolarRange(const Vec3& p, double cosLo, double cosHi) {
  const double norm = p.norm();
  return p.z() >= cosLo * norm && p.z() <= cosHi * norm;
}

// ---------------------------------------------------------------------------------------
// Radiation: the leading-log structure function, one photon per emitter

/// The exponent of the leading-log structure function of ONE radiating electron or positron
/// at invariant mass² s of the pair: β/2 = (α/π)(ln(s/m_e²) − 1). The familiar
/// β = (2α/π)(ln(s/m_e²) − 1) belongs to the pair (the convolution of two β/2 laws is the
/// β x^(β−1) law of the total fraction lost); using β per particle would double the radiation.
double radiatorPerParticle(double s) { return kAlphaOverPi * (std::log(s / kMe2) - 1.0); }

/// The energy fraction x of one photon from the density β·x^(β−1) truncated to
/// (0, kMaxPhotonFraction], drawn exactly as x = x_max·u^(1/β). `softProbability` =
/// (x_min/x_max)^β is the probability of x < x_min, returned as 0 (no emission): then only a
/// uniform number is spent, no logarithm.
double radiatedFraction(double beta, double softProbability, Rng& rng) {
  const double u = rng.uniformOpen();
  if (u <= softProbability) return 0.0;
  return kMaxPhotonFraction * std::exp(std::log(u) / beta);
}

/// The energies of the colliding e- and e+ after initial-state radiation.
struct Beams {
  double e1, e2;  ///< energies entering the hard process; NaN: no event within kMaxTrials
};

// Every accept-reject loop gives up after this many trials. With options that pass
// validate() the acceptance is at least a few per cent, so this is never reached; it turns
// a degenerate setting into an error instead of a hang.
constexpr int kMaxTrials = 1 << 20;
constexpr Beams kNoEvent{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};

// ---------------------------------------------------------------------------------------
// Lowest-order angular distributions (CM frame, c = cosθ in [cLo, cHi])

/// Bhabha: ((3 + c²)/(1 − c))². Envelope ∝ 1/(1 − c)², drawn as w = 1/(1 − c) uniform; the
/// acceptance (3 + c²)²/max is at least 9/16.
double bhabhaCos(double cLo, double cHi, Rng& rng) {
  const double wLo = 1.0 / (1.0 - cLo), wHi = 1.0 / (1.0 - cHi);
  const double t = 3.0 + std::max(cLo * cLo, cHi * cHi);
  const double bound = t * t;
  for (int trial = 0; trial < kMaxTrials; ++trial) {
    const double w = wLo + (wHi - wLo) * rng.uniform();
    const double c = 1.0 - 1.0 / w;
    const double f = 3.0 + c * c;
    if (rng.uniform() * bound < f * f) return c;
  }
  return std::numeric_limits<double>::quiet_NaN();
}

/// γγ: (1 + c²)/(1 − c²). Envelope ∝ 1/(1 − c²), drawn as c = tanh(u), u uniform; acceptance
/// (1 + c²)/2 ≥ 1/2.
double gammaGammaCos(double cLo, double cHi, Rng& rng) {
  const double uLo = std::atanh(cLo), uHi = std::atanh(cHi);
  for (int trial = 0; trial < kMaxTrials; ++trial) {
    const double c = std::tanh(uLo + (uHi - uLo) * rng.uniform());
    if (2.0 * rng.uniform() < 1.0 + c * c) return c;
  }
  return std::numeric_limits<double>::quiet_NaN();
}

// ---------------------------------------------------------------------------------------
// Bhabha and γγ

struct PolarRange {
  double cosLo, cosHi;  ///< lab: cos(thetaMax), cos(thetaMin)
  double cmLo, cmHi;    ///< CM range of the first particle that keeps its partner in range
};

PolarRange polarRange(const GeneratorOptions& o) {
  PolarRange r;
  r.cosLo = std::cos(o.thetaMax);
  r.cosHi = std::cos(o.thetaMin);
  r.cmLo = std::max(r.cosLo, -r.cosHi);
  r.cmHi = std::min(r.cosHi, -r.cosLo);
  return r;
}

/// Final-state photon of a lepton of momentum p (|p| = pAbs) and CM energy eL: energy
/// fraction y, angle θ to the lepton from dN/dθ ∝ θ/(θ² + θ0²) on [0, kMaxFsrAngle], i.e.
/// θ² = θ0²·((1 + θmax²/θ0²)^v − 1), v uniform; `logRange` = ln(1 + θmax²/θ0²).
Vec3 fsrPhoton(const Vec3& p, double pAbs, double k, double theta0, double logRange, Rng& rng) {
  const double theta = theta0 * std::sqrt(std::expm1(rng.uniform() * logRange));
  const Vec3 d = p / pAbs;
  Vec3 e1, e2;
  orthonormalBasis(d, e1, e2);
  double cphi, sphi;
  rng.unitCircle(cphi, sphi);
  const Vec3 dir = std::cos(theta) * d + std::sin(theta) * (cphi * e1 + sphi * e2);
  return k * dir;
}

/// The common factor λ of all CM momenta (leptons q1, q2 with |q|² = q1sq, q2sq; photons of
/// total energy kSum) that makes the total energy √s: f(λ) = Σ√(λ²|q|² + m²) + λ·kSum − √s
/// is increasing and convex with f(1) ≥ 0 (|p − k| + |k| ≥ |p|), so Newton from λ = 1
/// descends monotonically onto the root (2–3 steps at these energies).
double energyScale(double q1sq, double q2sq, double kSum, double sqrtS) {
  double l = 1.0;
  for (int i = 0; i < 30; ++i) {
    const double e1 = std::sqrt(l * l * q1sq + kMe2), e2 = std::sqrt(l * l * q2sq + kMe2);
    const double f = e1 + e2 + l * kSum - sqrtS;
    const double df = l * q1sq / e1 + l * q2sq / e2 + kSum;
    const double step = f / df;
    l -= step;
    if (!(std::abs(step) > 1e-15 * l)) break;
  }
  return l;
}

/// e+e- → e+e- from beams of energies beam1 (e-, +z) and beam2 (e+, −z). Each pass draws the
/// ISR fractions, the Born angle in the CM range, the FSR photons, boosts to the lab and keeps
/// the event if both leptons lie in the lab range; otherwise everything but the beam energies
/// is drawn again.
Beams bhabha(const GeneratorOptions& o, double beam1, double beam2, Rng& rng, GeneratedEvent& event) {
  const PolarRange range = polarRange(o);
  const std::size_t first = event.particles.size();
  double bIsr = 0.0, softIsr = 1.0, logSoftRatio = 0.0;
  if (o.radiation) {
    bIsr = radiatorPerParticle(4.0 * beam1 * beam2);
    logSoftRatio = std::log(kMinPhotonEnergy / (o.beamEnergy * kMaxPhotonFraction));
    softIsr = std::exp(bIsr * logSoftRatio);
  }
  for (int trial = 0; trial < kMaxTrials; ++trial) {
    event.particles.resize(first);
    const double x1 = o.radiation ? radiatedFraction(bIsr, softIsr, rng) : 0.0;
    const double x2 = o.radiation ? radiatedFraction(bIsr, softIsr, rng) : 0.0;
    const double e1 = beam1 * (1.0 - x1), e2 = beam2 * (1.0 - x2);
    const double sqrtS = 2.0 * std::sqrt(e1 * e2);
    const double eL = 0.5 * sqrtS;
    const double cosTheta = bhabhaCos(range.cmLo, range.cmHi, rng);
    if (std::isnan(cosTheta)) break;
    const Vec3 d = directionAt(cosTheta, rng);
    const double pL = std::sqrt(eL * eL - kMe2);

    double y1 = 0.0, y2 = 0.0;
    if (o.radiation) {
      // Final-state radiator of each lepton, from the reduced pair: (α/π)(ln(s'/m_e²) − 1).
      double bFsr = bIsr, softFsr = softIsr;
      if (x1 > 0.0 || x2 > 0.0) {
        bFsr = radiatorPerParticle(sqrtS * sqrtS);
        softFsr = std::exp(bFsr * logSoftRatio);
      }
      y1 = radiatedFraction(bFsr, softFsr, rng);
      y2 = radiatedFraction(bFsr, softFsr, rng);
    }
    if (y1 == 0.0 && y2 == 0.0) {
      event.particles.push_back({pdg::Electron, pL * d, eL});
      event.particles.push_back({pdg::Positron, -pL * d, eL});
    } else {
      const double theta0 = mass::Electron / eL;
      const double logRange = std::log1p(kMaxFsrAngle * kMaxFsrAngle / (theta0 * theta0));
      const Vec3 p1 = pL * d;
      const Vec3 k1 = y1 > 0.0 ? fsrPhoton(p1, pL, y1 * eL, theta0, logRange, rng) : Vec3::Zero();
      const Vec3 k2 = y2 > 0.0 ? fsrPhoton(-p1, pL, y2 * eL, theta0, logRange, rng) : Vec3::Zero();
      const Vec3 q1 = p1 - k1, q2 = -p1 - k2;
      const double l = energyScale(q1.squaredNorm(), q2.squaredNorm(), (y1 + y2) * eL, sqrtS);
      event.particles.push_back({pdg::Electron, l * q1, std::sqrt(l * l * q1.squaredNorm() + kMe2)});
      event.particles.push_back({pdg::Positron, l * q2, std::sqrt(l * l * q2.squaredNorm() + kMe2)});
      if (y1 > 0.0) event.particles.push_back({pdg::Photon, l * k1, l * y1 * eL});
      if (y2 > 0.0) event.particles.push_back({pdg::Photon, l * k2, l * y2 * eL});
    }
    toLab(event, first, e1, e2);
    if (e1 == e2 && y1 == 0.0 && y2 == 0.0) return {e1, e2};  // back to back in the CM range
    if (inPolarRange(event.particles[first].momentum, range.cosLo, range.cosHi) &&
        inPolarRange(event.particles[first + 1].momentum, range.cosLo, range.cosHi)) {
      return {e1, e2};
    }
  }
  event.particles.resize(first);
  return kNoEvent;
}

/// e+e- → γγ, drawn like bhabha() without final-state radiation.
Beams gammaGamma(const GeneratorOptions& o, double beam1, double beam2, Rng& rng, GeneratedEvent& event) {
  const PolarRange range = polarRange(o);
  const std::size_t first = event.particles.size();
  double bIsr = 0.0, softIsr = 1.0;
  if (o.radiation) {
    bIsr = radiatorPerParticle(4.0 * beam1 * beam2);
    softIsr = std::exp(bIsr * std::log(kMinPhotonEnergy / (o.beamEnergy * kMaxPhotonFraction)));
  }
  for (int trial = 0; trial < kMaxTrials; ++trial) {
    event.particles.resize(first);
    const double x1 = o.radiation ? radiatedFraction(bIsr, softIsr, rng) : 0.0;
    const double x2 = o.radiation ? radiatedFraction(bIsr, softIsr, rng) : 0.0;
    const double e1 = beam1 * (1.0 - x1), e2 = beam2 * (1.0 - x2);
    const double k = std::sqrt(e1 * e2);
    const double cosTheta = gammaGammaCos(range.cmLo, range.cmHi, rng);
    if (std::isnan(cosTheta)) break;
    const Vec3 d = directionAt(cosTheta, rng);
    event.particles.push_back({pdg::Photon, k * d, k});
    event.particles.push_back({pdg::Photon, -k * d, k});
    toLab(event, first, e1, e2);
    if (e1 == e2) return {e1, e2};
    if (inPolarRange(event.particles[first].momentum, range.cosLo, range.cosHi) &&
        inPolarRange(event.particles[first + 1].momentum, range.cosLo, range.cosHi)) {
      return {e1, e2};
    }
  }
  event.particles.resize(first);
  return kNoEvent;
}

// ---------------------------------------------------------------------------------------
// π+π−π0 through ρπ

/// Breakup momentum² of a → a + b at invariant mass² s.
double breakupMomentum2(double s, double ma, double mb) {
  const double sum = ma + mb, diff = ma - mb;
  return (s - sum * sum) * (s - diff * diff) / (4.0 * s);
}

/// ρ → π π' propagator 1/(m² − s − i·m·Γ(s)) with the p-wave width
/// Γ(s) = Γ_ρ·(q(s)/q(m²))³·m/√s, added into (re, im).
struct RhoChannel {
  double ma, mb, q0Cubed;
  explicit RhoChannel(double a, double b)
      : ma(a), mb(b), q0Cubed(std::pow(breakupMomentum2(mass::Rho * mass::Rho, a, b), 1.5)) {}
  void add(double s, double& re, double& im) const {
    const double q2 = std::max(0.0, breakupMomentum2(s, ma, mb));
    const double width = kRhoWidth * q2 * std::sqrt(q2) / q0Cubed * mass::Rho / std::sqrt(s);
    const double a = mass::Rho * mass::Rho - s, b = mass::Rho * width;
    const double inv = 1.0 / (a * a + b * b);
    re += a * inv;
    im += b * inv;
  }
};

const RhoChannel& rho0() {
  static const RhoChannel channel(mass::PiCharged, mass::PiCharged);
  return channel;
}
const RhoChannel& rhoCharged() {
  static const RhoChannel channel(mass::PiCharged, mass::Pi0);
  return channel;
}

/// A point of the Dalitz plot, (s+0, s−0) with s+− from their sum, at √s; momenta in the
/// 3π rest frame.
struct DalitzPoint {
  double pPlus2, pMinus2, dot;  ///< |p+|², |p−|², p+·p−
  double gram;                  ///< |p+ × p−|² (≤ 0: outside the kinematic boundary)
  double sPlusMinus;
};

DalitzPoint dalitzPoint(double sqrtS, double sPlusZero, double sMinusZero) {
  constexpr double mc2 = mass::PiCharged * mass::PiCharged, m02 = mass::Pi0 * mass::Pi0;
  const double s = sqrtS * sqrtS;
  const double half = 0.5 / sqrtS;
  DalitzPoint d;
  d.sPlusMinus = s + 2.0 * mc2 + m02 - sPlusZero - sMinusZero;
  const double ePlus = (s - sMinusZero + mc2) * half;
  const double eMinus = (s - sPlusZero + mc2) * half;
  const double eZero = (s - d.sPlusMinus + m02) * half;
  d.pPlus2 = ePlus * ePlus - mc2;
  d.pMinus2 = eMinus * eMinus - mc2;
  const double pZero2 = eZero * eZero - m02;
  d.dot = 0.5 * (pZero2 - d.pPlus2 - d.pMinus2);
  d.gram = (d.pPlus2 < 0.0 || d.pMinus2 < 0.0 || pZero2 < 0.0) ? -1.0 : d.pPlus2 * d.pMinus2 - d.dot * d.dot;
  return d;
}

/// |p+ × p−|²·|Σ BW|², 0 outside the Dalitz plot.
double threePionWeight(const DalitzPoint& d, double sPlusZero, double sMinusZero) {
  if (!(d.gram > 0.0)) return 0.0;
  double re = 0.0, im = 0.0;
  rho0().add(d.sPlusMinus, re, im);
  rhoCharged().add(sPlusZero, re, im);
  rhoCharged().add(sMinusZero, re, im);
  return d.gram * (re * re + im * im);
}

struct DalitzBox {
  double lo, hi;  ///< range of s+0 and of s−0
};
DalitzBox dalitzBox(double sqrtS) {
  const double lo = mass::PiCharged + mass::Pi0, hi = sqrtS - mass::PiCharged;
  return {lo * lo, hi * hi};
}

/// The largest weight on a kThreePionGrid² grid (cell centres) of the Dalitz box at √s.
double gridMaximum(double sqrtS) {
  const DalitzBox box = dalitzBox(sqrtS);
  const double step = (box.hi - box.lo) / kThreePionGrid;
  double best = 0.0;
  for (int i = 0; i < kThreePionGrid; ++i) {
    const double a = box.lo + (i + 0.5) * step;
    for (int j = 0; j < kThreePionGrid; ++j) {
      const double b = box.lo + (j + 0.5) * step;
      best = std::max(best, threePionWeight(dalitzPoint(sqrtS, a, b), a, b));
    }
  }
  return best;
}

/// The accept-reject bound for the options' beam energies, computed once per thread and
/// options: the grid maximum at 5 values of √s across 2(E ± 6σ), times kThreePionMargin.
struct ThreePionBound {
  double beamEnergy = std::numeric_limits<double>::quiet_NaN();
  double spread = std::numeric_limits<double>::quiet_NaN();
  double maxWeight = 0.0;
};
thread_local ThreePionBound tBound;
thread_local ThreePionSamplingStats tStats;

double threePionBound(const GeneratorOptions& o) {
  if (tBound.beamEnergy == o.beamEnergy && tBound.spread == o.beamEnergySpread) {
    return tBound.maxWeight;
  }
  const double lo = std::max(2.0 * (o.beamEnergy - 6.0 * o.beamEnergySpread), kPiThreshold * (1.0 + 1e-6));
  const double hi = std::max(2.0 * (o.beamEnergy + 6.0 * o.beamEnergySpread), lo);
  double best = 0.0;
  for (int i = 0; i <= 4; ++i) best = std::max(best, gridMaximum(lo + 0.25 * i * (hi - lo)));
  tBound = {o.beamEnergy, o.beamEnergySpread, kThreePionMargin * best};
  return tBound.maxWeight;
}

/// Momentum of a photon of π0 → γγ boosted from the π0 rest frame (photon q, energy k) to
/// the frame where the π0 has (p, e): q' = q + [(p·q)/(m(e + m)) + k/m]·p.
GeneratedParticle boostFromPi0(const Vec3& q, double k, const Vec3& p, double e) {
  constexpr double m = mass::Pi0;
  const double pq = p.dot(q);
  return {pdg::Photon, q + (pq / (m * (e + m)) + k / m) * p, (e * k + pq) / m};
}

Beams threePion(const GeneratorOptions& o, double e1, double e2, Rng& rng, GeneratedEvent& event) {
  const std::size_t first = event.particles.size();
  const double sqrtS = 2.0 * std::sqrt(e1 * e2);
  const double bound = threePionBound(o);
  const DalitzBox box = dalitzBox(sqrtS);

  // Dalitz point: uniform in (s+0, s−0) is uniform in phase space.
  DalitzPoint d;
  bool found = false;
  for (int trial = 0; trial < kMaxTrials && !found; ++trial) {
    const double a = box.lo + (box.hi - box.lo) * rng.uniform();
    const double b = box.lo + (box.hi - box.lo) * rng.uniform();
    d = dalitzPoint(sqrtS, a, b);
    if (!(d.gram > 0.0)) {
      ++tStats.trials;
      continue;
    }
    const double w = threePionWeight(d, a, b);
    ++tStats.trials;
    const double ratio = w / bound;
    if (ratio > 1.0) ++tStats.overflows;
    tStats.maxWeightRatio = std::max(tStats.maxWeightRatio, ratio);
    found = rng.uniform() < ratio;
  }
  if (!found) return kNoEvent;
  ++tStats.accepted;

  // Orientation: decay-plane normal n ∝ sin²θ_n (transverse φ), uniform rotation about n.
  double cn = 0.0;
  for (int trial = 0; trial < kMaxTrials; ++trial) {  // acceptance 2/3
    cn = 2.0 * rng.uniform() - 1.0;
    if (rng.uniform() < 1.0 - cn * cn) break;
  }
  const Vec3 n = directionAt(cn, rng);
  Vec3 e1n, e2n;
  orthonormalBasis(n, e1n, e2n);
  double cpsi, spsi;
  rng.unitCircle(cpsi, spsi);
  const Vec3 x = cpsi * e1n + spsi * e2n;
  const Vec3 y = n.cross(x);

  const double pPlus = std::sqrt(d.pPlus2), pMinus = std::sqrt(d.pMinus2);
  const double cosPM = d.dot / (pPlus * pMinus), sinPM = std::sqrt(d.gram) / (pPlus * pMinus);
  const Vec3 plus = pPlus * x;
  const Vec3 minus = pMinus * (cosPM * x + sinPM * y);
  const Vec3 zero = -(plus + minus);
  constexpr double mc2 = mass::PiCharged * mass::PiCharged;
  const double eZero = std::sqrt(zero.squaredNorm() + mass::Pi0 * mass::Pi0);
  event.particles.push_back({pdg::PiPlus, plus, std::sqrt(d.pPlus2 + mc2)});
  event.particles.push_back({pdg::PiMinus, minus, std::sqrt(d.pMinus2 + mc2)});

  // π0 → γγ, isotropic in the π0 rest frame.
  const double k = 0.5 * mass::Pi0;
  const Vec3 q = k * directionAt(2.0 * rng.uniform() - 1.0, rng);
  event.particles.push_back(boostFromPi0(q, k, zero, eZero));
  event.particles.push_back(boostFromPi0(-q, k, zero, eZero));
  toLab(event, first, e1, e2);
  return {e1, e2};
}

}  // namespace

std::optional<Process> processFromName(std::string_view name) {
  if (name == "ee") return Process::Bhabha;
  if (name == "gg") return Process::GammaGamma;
  if (name == "3pi") return Process::ThreePion;
  return std::nullopt;
}

std::string_view name(Process process) {
  switch (process) {
    case Process::Bhabha:
      return "ee";
    case Process::GammaGamma:
      return "gg";
    case Process::ThreePion:
      return "3pi";
  }
  return "?";
}

double defaultBeamEnergy(Process process) {
  return process == Process::ThreePion ? 510.0 * units::MeV : 612.5 * units::MeV;
}

Status GeneratorOptions::choose(std::string_view processName, std::optional<double> beamEnergyMev,
                                std::optional<double> thetaMinDeg, std::optional<double> thetaMaxDeg) {
  const auto p = processFromName(processName);
  if (!p) return Error{fmt::format("unknown process '{}' (ee, gg, 3pi)", processName)};
  process = *p;
  beamEnergy = beamEnergyMev ? *beamEnergyMev * units::MeV : defaultBeamEnergy(*p);
  if (thetaMinDeg) thetaMin = *thetaMinDeg * units::deg;
  if (thetaMaxDeg) thetaMax = *thetaMaxDeg * units::deg;
  return {};
}

Status GeneratorOptions::validate() const {
  const double maxBeam = process == Process::ThreePion ? kMaxThreePionBeamEnergy : kMaxBeamEnergy;
  if (!(std::isfinite(beamEnergy) && beamEnergy >= kMinBeamEnergy && beamEnergy <= maxBeam)) {
    return Error{fmt::format(
        "generator: the beam energy {:.6g} MeV is outside [{}, {}] MeV, the range the {} generator models (VEPP-2000: "
        "150-1000 MeV per beam; energies are in MeV)",
        beamEnergy / units::MeV, kMinBeamEnergy / units::MeV, maxBeam / units::MeV, name(process))};
  }
  if (!(std::isfinite(beamEnergySpread) && beamEnergySpread >= 0.0)) {
    return Error{fmt::format("generator: the beam energy spread must not be negative (got {} MeV)", beamEnergySpread)};
  }
  if (beamEnergySpread > 0.05 * beamEnergy) {
    return Error{
        fmt::format("generator: the beam energy spread ({} MeV) must not exceed 5 % of the beam "
                    "energy ({} MeV)",
                    beamEnergySpread, beamEnergy)};
  }
  if (!(vertexSigma.allFinite() && vertexSigma.minCoeff() >= 0.0)) {
    return Error{fmt::format("generator: the vertex sigma must not be negative (got {}, {}, {} cm)", vertexSigma.x(),
                             vertexSigma.y(), vertexSigma.z())};
  }
  if (!(std::isfinite(thetaMin) && std::isfinite(thetaMax) && thetaMin >= 0.0 && thetaMax <= pi &&
        thetaMin < thetaMax)) {
    return Error{
        fmt::format("generator: the polar range needs 0 <= thetaMin < thetaMax <= 180 deg (got "
                    "thetaMin {} deg, thetaMax {} deg)",
                    thetaMin / deg, thetaMax / deg)};
  }
  if (process != Process::ThreePion &&
      !(thetaMin > 0.0 && thetaMin < 0.5 * pi && thetaMax > 0.5 * pi && thetaMax < pi)) {
    return Error{
        fmt::format("generator: for {} the polar range must contain 90 deg (both particles fit "
                    "in it back to back) and exclude 0 and 180 deg, where the cross section "
                    "diverges (got thetaMin {} deg, thetaMax {} deg)",
                    name(process), thetaMin / deg, thetaMax / deg)};
  }
  if (process == Process::ThreePion && !(2.0 * beamEnergy > kPiThreshold)) {
    return Error{
        fmt::format("generator: the beam energy {} MeV is below the pi+pi-pi0 threshold ({} MeV "
                    "per beam)",
                    beamEnergy, 0.5 * kPiThreshold)};
  }
  return {};
}

Collision generate(const GeneratorOptions& o, Rng& rng, GeneratedEvent& event) {
  event.particles.clear();
  event.vertex =
      Vec3(o.vertexSigma.x() * rng.normal(), o.vertexSigma.y() * rng.normal(), o.vertexSigma.z() * rng.normal());
  Collision c;
  bool aboveThreshold = false;
  for (int trial = 0; trial < kMaxTrials && !aboveThreshold; ++trial) {
    c.electronBeam = o.beamEnergy + o.beamEnergySpread * rng.normal();
    c.positronBeam = o.beamEnergy + o.beamEnergySpread * rng.normal();
    // Only 3π has a threshold; validate() keeps the other energies far from zero.
    aboveThreshold = o.process != Process::ThreePion ||
                     2.0 * std::sqrt(c.electronBeam * c.positronBeam) > kPiThreshold * (1.0 + 1e-9);
  }
  if (!aboveThreshold) {
    c.electronEnergy = c.positronEnergy = std::numeric_limits<double>::quiet_NaN();
    return c;
  }

  Beams b{};
  switch (o.process) {
    case Process::Bhabha:
      b = bhabha(o, c.electronBeam, c.positronBeam, rng, event);
      break;
    case Process::GammaGamma:
      b = gammaGamma(o, c.electronBeam, c.positronBeam, rng, event);
      break;
    case Process::ThreePion:
      b = threePion(o, c.electronBeam, c.positronBeam, rng, event);
      break;
  }
  c.electronEnergy = b.e1;
  c.positronEnergy = b.e2;
  return c;
}

GeneratedEvent generate(const GeneratorOptions& options, Rng& rng) {
  GeneratedEvent event;
  event.particles.reserve(4);
  (void)generate(options, rng, event);
  return event;
}

ThreePionSamplingStats threePionSamplingStats() { return tStats; }
void resetThreePionSamplingStats() { tStats = {}; }

}  // namespace emcalign::sim
