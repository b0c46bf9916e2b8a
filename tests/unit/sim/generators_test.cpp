// The event generators: angular distributions against the lowest-order formulas (binned χ²),
// exact kinematics, the radiative tails, the ρπ Dalitz plot and φ polarisation of 3π,
// determinism, and the refusals of validate().

#include "emcalign/sim/generators.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <complex>
#include <cstdint>
#include <functional>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"

namespace emcalign::sim {
namespace {

using std::numbers::pi;
using units::deg;

// ---- helpers

struct FourMomentum {
  double e = 0.0;
  Vec3 p = Vec3::Zero();
  FourMomentum& operator+=(const GeneratedParticle& q) {
    e += q.energy;
    p += q.momentum;
    return *this;
  }
  double mass() const { return std::sqrt(std::max(0.0, e * e - p.squaredNorm())); }
};

FourMomentum sum(const GeneratedEvent& ev) {
  FourMomentum t;
  for (const auto& q : ev.particles) t += q;
  return t;
}

double cosTheta(const Vec3& p) { return p.z() / p.norm(); }
double angle(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

/// p-value of χ² with ndf degrees of freedom (Wilson–Hilferty; good to ~1e-3 relative here).
double chi2PValue(double chi2, int ndf) {
  const double k = ndf;
  const double z = (std::cbrt(chi2 / k) - (1.0 - 2.0 / (9.0 * k))) / std::sqrt(2.0 / (9.0 * k));
  return 0.5 * std::erfc(z / std::sqrt(2.0));
}

/// χ² of a histogram of `values` in `bins` equal bins over [lo, hi] against the density f
/// (unnormalised; normalised here over [lo, hi] by Simpson's rule), ndf = bins − 1.
double chi2Against(const std::vector<double>& values, double lo, double hi, int bins,
                   const std::function<double(double)>& f) {
  std::vector<double> counts(bins, 0.0), expected(bins, 0.0);
  const double width = (hi - lo) / bins;
  for (double v : values) {
    const int b = std::clamp(static_cast<int>((v - lo) / width), 0, bins - 1);
    counts[b] += 1.0;
  }
  constexpr int kSub = 200;  // Simpson panels per bin (even)
  double total = 0.0;
  for (int b = 0; b < bins; ++b) {
    const double a = lo + b * width, h = width / kSub;
    double s = f(a) + f(a + width);
    for (int i = 1; i < kSub; ++i) s += (i % 2 ? 4.0 : 2.0) * f(a + i * h);
    expected[b] = s * h / 3.0;
    total += expected[b];
  }
  double chi2 = 0.0;
  for (int b = 0; b < bins; ++b) {
    const double mu = expected[b] / total * static_cast<double>(values.size());
    chi2 += (counts[b] - mu) * (counts[b] - mu) / mu;
  }
  return chi2;
}

GeneratorOptions optionsFor(Process process) {
  GeneratorOptions o;
  o.process = process;
  o.beamEnergy = defaultBeamEnergy(process);
  return o;
}

// ---- options

TEST(GeneratorOptions, ProcessNamesRoundTrip) {
  for (Process p : {Process::Bhabha, Process::GammaGamma, Process::ThreePion}) {
    ASSERT_TRUE(processFromName(name(p)).has_value());
    EXPECT_EQ(*processFromName(name(p)), p);
  }
  EXPECT_EQ(name(Process::Bhabha), "ee");
  EXPECT_EQ(name(Process::GammaGamma), "gg");
  EXPECT_EQ(name(Process::ThreePion), "3pi");
  EXPECT_FALSE(processFromName("mumu").has_value());
  EXPECT_FALSE(processFromName("").has_value());
  EXPECT_DOUBLE_EQ(defaultBeamEnergy(Process::Bhabha), 612.5);
  EXPECT_DOUBLE_EQ(defaultBeamEnergy(Process::GammaGamma), 612.5);
  EXPECT_DOUBLE_EQ(defaultBeamEnergy(Process::ThreePion), 510.0);
}

TEST(GeneratorOptions, DefaultsAreValidForEveryProcess) {
  for (Process p : {Process::Bhabha, Process::GammaGamma, Process::ThreePion}) {
    const Status s = optionsFor(p).validate();
    EXPECT_TRUE(s.ok()) << s.error().message;
  }
  GeneratorOptions still;  // no spreads at all is allowed
  still.beamEnergySpread = 0.0;
  still.vertexSigma = Vec3::Zero();
  EXPECT_TRUE(still.validate().ok());
}

TEST(GeneratorOptions, ValidateRefusesBadInputNamingIt) {
  auto refused = [](const GeneratorOptions& o, const std::string& word) {
    const Status s = o.validate();
    EXPECT_FALSE(s.ok()) << "accepted, expected a complaint about " << word;
    if (!s.ok()) {
      EXPECT_NE(s.error().message.find(word), std::string::npos) << s.error().message;
    }
  };
  GeneratorOptions o;
  o.beamEnergy = 0.0;
  refused(o, "beam energy");
  o.beamEnergy = -612.5;
  refused(o, "beam energy");
  o.beamEnergy = std::nan("");
  refused(o, "beam energy");

  o.beamEnergy = 1e308;  // once an endless loop of the Bhabha generator (√s overflows)
  refused(o, "outside [20, 5000] MeV");
  o.beamEnergy = 0.6125;  // GeV for MeV
  refused(o, "energies are in MeV");
  o.beamEnergy = 5000.0;
  EXPECT_TRUE(o.validate().ok());

  o = GeneratorOptions{};
  o.beamEnergySpread = -0.1;
  refused(o, "spread");
  o.beamEnergySpread = 100.0;
  refused(o, "spread");

  o = GeneratorOptions{};
  o.vertexSigma = Vec3(0.05, -0.05, 2.5);
  refused(o, "vertex");

  o = GeneratorOptions{};
  o.thetaMin = 100.0 * deg;
  o.thetaMax = 100.0 * deg;
  refused(o, "thetaMin");
  o.thetaMin = 120.0 * deg;
  o.thetaMax = 60.0 * deg;
  refused(o, "thetaMin");
  o.thetaMin = 0.0;  // the Bhabha cross section diverges at 0
  o.thetaMax = 170.0 * deg;
  refused(o, "polar range");
  o.thetaMin = 100.0 * deg;  // a back-to-back pair cannot both lie in 100°–170°
  refused(o, "polar range");

  o = optionsFor(Process::ThreePion);
  o.beamEnergy = 200.0;  // 2E = 400 MeV < 2 m(π±) + m(π0) = 414 MeV
  refused(o, "threshold");
  o.beamEnergy = 208.0;
  EXPECT_TRUE(o.validate().ok());
  o.beamEnergy = 1500.0;  // beyond the φ-region ρπ model
  refused(o, "outside [20, 1000] MeV");
}

TEST(GeneratorOptions, EveryProcessMakesEventsAtTheEdgesOfItsRange) {
  for (Process p : {Process::Bhabha, Process::GammaGamma, Process::ThreePion}) {
    for (double e : {p == Process::ThreePion ? 208.0 : kMinBeamEnergy,
                     p == Process::ThreePion ? kMaxThreePionBeamEnergy : kMaxBeamEnergy}) {
      GeneratorOptions o = optionsFor(p);
      o.beamEnergy = e;
      o.beamEnergySpread = 0.0;
      ASSERT_TRUE(o.validate().ok()) << name(p) << " " << e;
      Rng rng(7, 0);
      GeneratedEvent ev;
      for (int i = 0; i < 200; ++i) {
        const Collision c = generate(o, rng, ev);
        ASSERT_TRUE(c.made()) << name(p) << " at " << e << " MeV";
        for (const auto& particle : ev.particles) ASSERT_TRUE(particle.momentum.allFinite());
      }
    }
  }
}

// ---- e+e- → e+e-

TEST(BhabhaBorn, AngularDistributionFollowsLowestOrderQed) {
  GeneratorOptions o = optionsFor(Process::Bhabha);
  o.radiation = false;
  o.beamEnergySpread = 0.0;
  Rng rng(2024, 0);
  GeneratedEvent ev;
  constexpr int kEvents = 100000;
  std::vector<double> c;
  c.reserve(kEvents);
  for (int i = 0; i < kEvents; ++i) {
    (void)generate(o, rng, ev);
    ASSERT_EQ(ev.particles.size(), 2u);
    const auto& em = ev.particles[0];
    const auto& ep = ev.particles[1];
    ASSERT_EQ(em.pdg, pdg::Electron);
    ASSERT_EQ(ep.pdg, pdg::Positron);
    // Born kinematics: exactly back to back, each lepton at the beam energy, on shell.
    ASSERT_EQ(em.momentum, -ep.momentum);
    ASSERT_EQ(em.energy, o.beamEnergy);
    ASSERT_EQ(ep.energy, o.beamEnergy);
    ASSERT_NEAR(em.energy * em.energy - em.momentum.squaredNorm(), mass::Electron * mass::Electron, 1e-6);
    c.push_back(cosTheta(em.momentum));
  }
  const double lo = std::cos(o.thetaMax), hi = std::cos(o.thetaMin);
  EXPECT_GE(*std::min_element(c.begin(), c.end()), lo);
  EXPECT_LE(*std::max_element(c.begin(), c.end()), hi);
  auto bhabha = [](double x) { return std::pow((3.0 + x * x) / (1.0 - x), 2); };
  const double chi2 = chi2Against(c, lo, hi, 40, bhabha);
  EXPECT_GT(chi2PValue(chi2, 39), 1e-3) << "chi2 = " << chi2;
  // The test has power: the t-channel photon alone (no s-channel, no interference) fails.
  auto tOnly = [](double x) { return (1.0 + std::pow(0.5 * (1.0 + x), 2)) / std::pow(1.0 - x, 2); };
  EXPECT_LT(chi2PValue(chi2Against(c, lo, hi, 40, tOnly), 39), 1e-6);
}

TEST(BhabhaRadiative, BalancesEnergyAndHasRadiativeTails) {
  const GeneratorOptions o = optionsFor(Process::Bhabha);  // radiation on, spreads on
  ASSERT_TRUE(o.radiation);
  Rng rng(77, 3);
  GeneratedEvent ev;
  constexpr int kEvents = 100000;
  int acollinear = 0, wideHardPhoton = 0, withPhoton = 0, isr = 0;
  double leptonEnergy = 0.0, worstImbalance = 0.0;
  const double cosLo = std::cos(o.thetaMax), cosHi = std::cos(o.thetaMin);
  for (int i = 0; i < kEvents; ++i) {
    const Collision col = generate(o, rng, ev);
    ASSERT_GE(ev.particles.size(), 2u);
    ASSERT_LE(ev.particles.size(), 4u);
    const auto& em = ev.particles[0];
    const auto& ep = ev.particles[1];
    ASSERT_EQ(em.pdg, pdg::Electron);
    ASSERT_EQ(ep.pdg, pdg::Positron);
    // The ISR-reduced initial state, and the final state summing to it.
    ASSERT_LE(col.electronEnergy, col.electronBeam);
    ASSERT_LE(col.positronEnergy, col.positronBeam);
    ASSERT_GE(col.electronEnergy, (1.0 - kMaxPhotonFraction) * col.electronBeam * (1.0 - 1e-12));
    if (col.electronEnergy < col.electronBeam || col.positronEnergy < col.positronBeam) ++isr;
    const FourMomentum f = sum(ev);
    // Each imbalance on its own: a NaN fails here (std::max would drop it).
    for (double d : {f.e - col.energy(), f.p.x(), f.p.y(), f.p.z() - col.momentumZ()}) {
      ASSERT_TRUE(std::isfinite(d));
      worstImbalance = std::max(worstImbalance, std::abs(d));
    }
    // Both leptons in the generated range; every particle on its mass shell.
    ASSERT_GE(cosTheta(em.momentum), cosLo);
    ASSERT_LE(cosTheta(em.momentum), cosHi);
    ASSERT_GE(cosTheta(ep.momentum), cosLo);
    ASSERT_LE(cosTheta(ep.momentum), cosHi);
    for (const auto& q : ev.particles) {
      ASSERT_NEAR(q.energy * q.energy - q.momentum.squaredNorm(), q.mass() * q.mass(), 1e-6 * q.energy);
    }
    if (angle(em.momentum, -ep.momentum) > 5.0 * deg) ++acollinear;
    leptonEnergy += em.energy + ep.energy;
    if (ev.particles.size() > 2) ++withPhoton;
    for (std::size_t k = 2; k < ev.particles.size(); ++k) {
      const auto& g = ev.particles[k];
      ASSERT_EQ(g.pdg, pdg::Photon);
      // The infrared cut-off: 1 MeV as a fraction of the beam energy, in the CM frame; the lab
      // boost after hard ISR can lower it by a factor √(1 − x) ≥ 0.3.
      ASSERT_GT(g.energy, 0.1 * kMinPhotonEnergy);
      if (g.energy > 20.0 && angle(g.momentum, em.momentum) > 10.0 * deg &&
          angle(g.momentum, ep.momentum) > 10.0 * deg) {
        ++wideHardPhoton;
        break;
      }
    }
  }
  EXPECT_LT(worstImbalance, 1e-9 * 2.0 * o.beamEnergy);
  const double n = kEvents;
  EXPECT_GT(isr / n, 0.2);
  EXPECT_LT(isr / n, 0.8);
  EXPECT_GT(withPhoton / n, 0.2);
  EXPECT_GT(acollinear / n, 0.01) << acollinear;
  EXPECT_GT(wideHardPhoton / n, 0.02) << wideHardPhoton;  // 6.4 % with these seeds
  EXPECT_LT(wideHardPhoton / n, 0.12) << wideHardPhoton;
  EXPECT_LT(leptonEnergy / (2.0 * n), o.beamEnergy - 5.0);
  EXPECT_GT(leptonEnergy / (2.0 * n), 0.8 * o.beamEnergy);
}

// ---- e+e- → γγ

TEST(GammaGamma, AngularDistributionFollowsLowestOrderQed) {
  GeneratorOptions o = optionsFor(Process::GammaGamma);
  o.radiation = false;
  o.beamEnergySpread = 0.0;
  Rng rng(99, 1);
  GeneratedEvent ev;
  constexpr int kEvents = 100000;
  std::vector<double> c;
  c.reserve(kEvents);
  for (int i = 0; i < kEvents; ++i) {
    (void)generate(o, rng, ev);
    ASSERT_EQ(ev.particles.size(), 2u);
    ASSERT_EQ(ev.particles[0].pdg, pdg::Photon);
    ASSERT_EQ(ev.particles[1].pdg, pdg::Photon);
    ASSERT_EQ(ev.particles[0].momentum, -ev.particles[1].momentum);
    ASSERT_EQ(ev.particles[0].energy, o.beamEnergy);
    ASSERT_NEAR(ev.particles[0].momentum.norm(), o.beamEnergy, 1e-9);
    c.push_back(cosTheta(ev.particles[0].momentum));
  }
  const double lo = std::cos(o.thetaMax), hi = std::cos(o.thetaMin);
  auto gg = [](double x) { return (1.0 + x * x) / (1.0 - x * x); };
  const double chi2 = chi2Against(c, lo, hi, 40, gg);
  EXPECT_GT(chi2PValue(chi2, 39), 1e-3) << "chi2 = " << chi2;
  auto flat = [](double x) { return 1.0 / (1.0 - x * x); };  // without the (1 + c²)
  EXPECT_LT(chi2PValue(chi2Against(c, lo, hi, 40, flat), 39), 1e-6);
}

TEST(GammaGamma, InitialStateRadiationOnlyBoostsAlongTheBeam) {
  const GeneratorOptions o = optionsFor(Process::GammaGamma);
  Rng rng(5, 5);
  GeneratedEvent ev;
  int acollinear = 0;
  for (int i = 0; i < 20000; ++i) {
    const Collision col = generate(o, rng, ev);
    ASSERT_EQ(ev.particles.size(), 2u);
    const FourMomentum f = sum(ev);
    ASSERT_NEAR(f.e, col.energy(), 1e-9 * f.e);
    ASSERT_NEAR(f.p.z(), col.momentumZ(), 1e-9 * f.e);
    ASSERT_NEAR(f.p.x(), 0.0, 1e-9 * f.e);
    ASSERT_NEAR(f.p.y(), 0.0, 1e-9 * f.e);
    ASSERT_NEAR(f.mass(), 2.0 * std::sqrt(col.electronEnergy * col.positronEnergy), 1e-6 * f.e);
    for (const auto& g : ev.particles) {
      ASSERT_GE(cosTheta(g.momentum), std::cos(o.thetaMax));
      ASSERT_LE(cosTheta(g.momentum), std::cos(o.thetaMin));
    }
    // The boost is along z: the photons stay back to back in φ.
    const Vec3 a = ev.particles[0].momentum, b = ev.particles[1].momentum;
    ASSERT_NEAR(a.x() * b.y() - a.y() * b.x(), 0.0, 1e-9 * a.norm() * b.norm());
    if (angle(a, -b) > 5.0 * deg) ++acollinear;
  }
  EXPECT_GT(acollinear, 200);
}

TEST(GammaGamma, InitialStateRadiationPerBeamFollowsTheStructureFunction) {
  // Each beam radiates with density ∝ b·x^(b−1) on (0, 0.9], b = (α/π)(ln(s/m_e²) − 1) — the
  // exponent of one particle, half the pair's β — and not below x_min = 1 MeV/E_beam:
  // P(x > x_min) = 1 − (x_min/0.9)^b ≈ 0.19 and P(x > 0.1) = 1 − (0.1/0.9)^b ≈ 0.07 (with the
  // pair's β per beam they would be 0.34 and 0.14). A wide polar range keeps the events that
  // the boost takes out of range (and are drawn again) rare: they lower the hard fraction by
  // about 5 % of itself (0.068 instead of 0.072), the documented bias of the CM-range cut.
  GeneratorOptions o = optionsFor(Process::GammaGamma);
  o.beamEnergySpread = 0.0;
  o.thetaMin = 1.0 * deg;
  o.thetaMax = 179.0 * deg;
  const double E = o.beamEnergy;
  const double b = kAlpha / pi * (std::log(4.0 * E * E / (mass::Electron * mass::Electron)) - 1.0);
  const double pEmit = 1.0 - std::pow(kMinPhotonEnergy / E / kMaxPhotonFraction, b);
  const double pHard = 1.0 - std::pow(0.1 / kMaxPhotonFraction, b);
  Rng rng(64, 0);
  GeneratedEvent ev;
  constexpr int kEvents = 50000;
  int emitted = 0, hard = 0;
  for (int i = 0; i < kEvents; ++i) {
    const Collision col = generate(o, rng, ev);
    for (double x : {1.0 - col.electronEnergy / col.electronBeam, 1.0 - col.positronEnergy / col.positronBeam}) {
      ASSERT_LE(x, kMaxPhotonFraction + 1e-12);
      if (x > 0.0) {
        ++emitted;
        ASSERT_GE(x, kMinPhotonEnergy / E * (1.0 - 1e-9));
      }
      if (x > 0.1) ++hard;
    }
  }
  const double n = 2.0 * kEvents;
  EXPECT_NEAR(emitted / n, pEmit, 0.01) << "expected " << pEmit;
  EXPECT_NEAR(hard / n, pHard, 0.008) << "expected " << pHard;
}

// ---- e+e- → π+π−π0

/// Whether (s+0, s0−) lies inside the Dalitz plot at mass M (PDG kinematics review: the range
/// of m23² at fixed m12², particles 1 = π+, 2 = π0, 3 = π−).
bool insideDalitz(double M, double s12, double s23) {
  const double m1 = mass::PiCharged, m2 = mass::Pi0, m3 = mass::PiCharged;
  const double m12 = std::sqrt(s12);
  if (m12 <= m1 + m2 || m12 >= M - m3) return false;
  const double e2 = (s12 - m1 * m1 + m2 * m2) / (2.0 * m12);
  const double e3 = (M * M - s12 - m3 * m3) / (2.0 * m12);
  const double p2 = std::sqrt(e2 * e2 - m2 * m2), p3 = std::sqrt(e3 * e3 - m3 * m3);
  const double e23 = (e2 + e3) * (e2 + e3);
  return s23 > e23 - (p2 + p3) * (p2 + p3) && s23 < e23 - (p2 - p3) * (p2 - p3);
}

/// The ρπ model written out again: |p+ × p−|² (3π rest frame) times |Σ BW|², p-wave width.
struct RhoPiModel {
  double M;
  std::complex<double> bw(double s, double ma, double mb) const {
    auto q = [&](double x) {
      return std::sqrt(std::max(0.0, (x - (ma + mb) * (ma + mb)) * (x - (ma - mb) * (ma - mb)) / (4.0 * x)));
    };
    const double mr = mass::Rho, width = 149.1 * std::pow(q(s) / q(mr * mr), 3) * mr / std::sqrt(s);
    return 1.0 / std::complex<double>(mr * mr - s, -mr * width);
  }
  /// |p+ × p−|², from the energies of π+ and π− in the 3π rest frame.
  double cross2(double sP0, double sM0) const {
    const double mc = mass::PiCharged, m0 = mass::Pi0;
    const double ep = (M * M + mc * mc - sM0) / (2.0 * M), em = (M * M + mc * mc - sP0) / (2.0 * M);
    const double e0 = M - ep - em;
    const double pp2 = ep * ep - mc * mc, pm2 = em * em - mc * mc, p02 = e0 * e0 - m0 * m0;
    const double cosine = (p02 - pp2 - pm2) / (2.0 * std::sqrt(pp2 * pm2));
    return pp2 * pm2 * std::max(0.0, 1.0 - cosine * cosine);
  }
  double weight(double sP0, double sM0) const {
    const double sPM = M * M + 2.0 * mass::PiCharged * mass::PiCharged + mass::Pi0 * mass::Pi0 - sP0 - sM0;
    const std::complex<double> a = bw(sPM, mass::PiCharged, mass::PiCharged) + bw(sP0, mass::PiCharged, mass::Pi0) +
                                   bw(sM0, mass::PiCharged, mass::Pi0);
    return cross2(sP0, sM0) * std::norm(a);
  }
};

TEST(ThreePion, ConservesFourMomentumAndFollowsThePhiPolarisation) {
  GeneratorOptions o = optionsFor(Process::ThreePion);
  o.beamEnergySpread = 0.0;  // the 3π rest frame is the lab: the plane normal is undistorted
  Rng rng(31, 4);
  GeneratedEvent ev;
  resetThreePionSamplingStats();
  constexpr int kEvents = 30000;
  const double M = 2.0 * o.beamEnergy;
  double cos2 = 0.0;
  for (int i = 0; i < kEvents; ++i) {
    const Collision col = generate(o, rng, ev);
    ASSERT_EQ(ev.particles.size(), 4u);
    ASSERT_EQ(ev.particles[0].pdg, pdg::PiPlus);
    ASSERT_EQ(ev.particles[1].pdg, pdg::PiMinus);
    ASSERT_EQ(ev.particles[2].pdg, pdg::Photon);
    ASSERT_EQ(ev.particles[3].pdg, pdg::Photon);
    const FourMomentum f = sum(ev);
    ASSERT_NEAR(f.e, col.energy(), 1e-9 * M);
    ASSERT_NEAR(f.e, M, 1e-9 * M);
    ASSERT_LT(f.p.norm(), 1e-9 * M);
    for (const auto& q : ev.particles) {
      ASSERT_NEAR(q.energy * q.energy - q.momentum.squaredNorm(), q.mass() * q.mass(), 1e-6 * q.energy);
    }
    FourMomentum pi0;
    (pi0 += ev.particles[2]) += ev.particles[3];
    ASSERT_NEAR(pi0.mass(), mass::Pi0, 1e-6);
    const Vec3 n = ev.particles[0].momentum.cross(ev.particles[1].momentum).normalized();
    cos2 += n.z() * n.z();
  }
  const ThreePionSamplingStats stats = threePionSamplingStats();
  EXPECT_EQ(stats.accepted, kEvents);
  EXPECT_EQ(stats.overflows, 0) << "a weight exceeded the accept-reject bound";
  EXPECT_LT(stats.maxWeightRatio, 1.0);
  EXPECT_GT(stats.maxWeightRatio, 0.5) << "the bound is needlessly loose";

  // ⟨cos²θ_n⟩ = 1/5 for dN/dcosθ_n ∝ sin²θ_n (1/3 if isotropic); σ ≈ 0.214/√N.
  const double meanCos2 = cos2 / kEvents;
  EXPECT_NEAR(meanCos2, 0.2, 5.0 * 0.214 / std::sqrt(kEvents));
}

// At √s = m_φ the ρ (Γ = 149 MeV) is broad on the scale of the Dalitz plot (m(ππ) from 279 to
// 885 MeV): the bands |m(ππ) − m_ρ| < Γ/2 of the three pairs already cover 71 % of uniform
// phase space, and the coherent sum of the three BW tails makes the centre of the plot the
// densest region (model: 57 % in the bands; |p+ × p−|² alone: 60 %). So the ρ is tested by the
// shape: a 2D binned χ² of (s+0, s−0) against the ρπ weight, integrated by the test on its
// own; the same histogram must fail against phase space and against |p+ × p−|² without ρ.
TEST(ThreePion, DalitzPlotFollowsTheRhoPiModel) {
  GeneratorOptions o = optionsFor(Process::ThreePion);
  o.beamEnergySpread = 0.0;
  const double M = 2.0 * o.beamEnergy;
  const RhoPiModel model{M};
  const double lo = std::pow(mass::PiCharged + mass::Pi0, 2), hi = std::pow(M - mass::PiCharged, 2);
  constexpr int kBins = 14;
  auto bin = [&](double sP0, double sM0) {
    const int i = std::clamp(static_cast<int>((sP0 - lo) / (hi - lo) * kBins), 0, kBins - 1);
    const int j = std::clamp(static_cast<int>((sM0 - lo) / (hi - lo) * kBins), 0, kBins - 1);
    return i * kBins + j;
  };

  constexpr int kEvents = 40000;
  std::vector<double> counts(kBins * kBins, 0.0);
  Rng rng(11, 2);
  GeneratedEvent ev;
  for (int i = 0; i < kEvents; ++i) {
    (void)generate(o, rng, ev);
    FourMomentum p0, m0;
    ((p0 += ev.particles[0]) += ev.particles[2]) += ev.particles[3];
    ((m0 += ev.particles[1]) += ev.particles[2]) += ev.particles[3];
    const double sP0 = p0.e * p0.e - p0.p.squaredNorm(), sM0 = m0.e * m0.e - m0.p.squaredNorm();
    ASSERT_TRUE(insideDalitz(M, sP0, sM0));
    counts[bin(sP0, sM0)] += 1.0;
  }

  // Expected histograms: uniform phase space points, weighted.
  struct Expectation {
    std::vector<double> w, w2;
    double total = 0.0;
  };
  std::array<Expectation, 3> expect;  // ρπ, |p+ × p−|² only, flat
  for (auto& e : expect) e.w.assign(kBins * kBins, 0.0), e.w2.assign(kBins * kBins, 0.0);
  Rng flat(8, 8);
  for (int n = 0; n < 400000;) {
    const double sP0 = flat.uniform(lo, hi), sM0 = flat.uniform(lo, hi);
    if (!insideDalitz(M, sP0, sM0)) continue;
    ++n;
    const int b = bin(sP0, sM0);
    const std::array<double, 3> w = {model.weight(sP0, sM0), model.cross2(sP0, sM0), 1.0};
    for (int k = 0; k < 3; ++k) {
      expect[k].w[b] += w[k];
      expect[k].w2[b] += w[k] * w[k];
      expect[k].total += w[k];
    }
  }
  auto chi2 = [&](const Expectation& e, int& ndf) {
    double c = 0.0;
    ndf = -1;
    for (int b = 0; b < kBins * kBins; ++b) {
      const double mu = kEvents * e.w[b] / e.total;
      if (mu < 20.0) continue;  // the boundary bins: few entries
      const double varMu = kEvents * kEvents * e.w2[b] / (e.total * e.total);
      c += (counts[b] - mu) * (counts[b] - mu) / (mu + varMu);
      ++ndf;
    }
    return c;
  };
  int ndf = 0;
  const double chi2Model = chi2(expect[0], ndf);
  ASSERT_GT(ndf, 80);
  EXPECT_GT(chi2PValue(chi2Model, ndf), 1e-3) << "chi2/ndf = " << chi2Model << "/" << ndf;
  const double chi2NoRho = chi2(expect[1], ndf);
  EXPECT_LT(chi2PValue(chi2NoRho, ndf), 1e-6) << "chi2/ndf = " << chi2NoRho << "/" << ndf;
  const double chi2Flat = chi2(expect[2], ndf);
  EXPECT_LT(chi2PValue(chi2Flat, ndf), 1e-6) << "chi2/ndf = " << chi2Flat << "/" << ndf;
}

TEST(ThreePion, FollowsTheBeamEnergyAndItsSpread) {
  GeneratorOptions o = optionsFor(Process::ThreePion);
  o.beamEnergy = 700.0;
  o.beamEnergySpread = 2.0;
  Rng rng(3, 3);
  GeneratedEvent ev;
  resetThreePionSamplingStats();
  for (int i = 0; i < 3000; ++i) {
    const Collision col = generate(o, rng, ev);
    const FourMomentum f = sum(ev);
    ASSERT_NEAR(f.e, col.energy(), 1e-9 * f.e);
    ASSERT_NEAR(f.p.z(), col.momentumZ(), 1e-9 * f.e);
    ASSERT_NEAR(f.mass(), 2.0 * std::sqrt(col.electronBeam * col.positronBeam), 1e-6 * f.e);
  }
  EXPECT_EQ(threePionSamplingStats().overflows, 0);
}

// ---- determinism

TEST(GeneratorDeterminism, SameSeedSameEventBitForBit) {
  auto bits = [](double x) { return std::bit_cast<std::uint64_t>(x); };
  for (Process p : {Process::Bhabha, Process::GammaGamma, Process::ThreePion}) {
    const GeneratorOptions o = optionsFor(p);
    for (std::uint64_t stream = 0; stream < 50; ++stream) {
      Rng r1(123, stream), r2(123, stream);
      const GeneratedEvent a = generate(o, r1);
      GeneratedEvent b;
      b.particles.resize(7);  // stale content must not matter
      (void)generate(o, r2, b);
      ASSERT_EQ(a.particles.size(), b.particles.size());
      for (int k = 0; k < 3; ++k) ASSERT_EQ(bits(a.vertex[k]), bits(b.vertex[k]));
      for (std::size_t i = 0; i < a.particles.size(); ++i) {
        ASSERT_EQ(a.particles[i].pdg, b.particles[i].pdg);
        ASSERT_EQ(bits(a.particles[i].energy), bits(b.particles[i].energy));
        for (int k = 0; k < 3; ++k) {
          ASSERT_EQ(bits(a.particles[i].momentum[k]), bits(b.particles[i].momentum[k]));
        }
      }
      ASSERT_EQ(bits(r1.uniform()), bits(r2.uniform()));  // the same numbers were used
    }
    Rng r1(1, 0), r2(2, 0);
    EXPECT_NE(generate(o, r1).particles[0].momentum, generate(o, r2).particles[0].momentum);
  }
}

TEST(GeneratorVertex, IsGaussianWithTheGivenSigmas) {
  GeneratorOptions o = optionsFor(Process::GammaGamma);
  o.vertexSigma = Vec3(0.1, 0.02, 3.0);
  Rng rng(17, 0);
  GeneratedEvent ev;
  constexpr int kEvents = 20000;
  Vec3 s = Vec3::Zero(), s2 = Vec3::Zero();
  for (int i = 0; i < kEvents; ++i) {
    (void)generate(o, rng, ev);
    s += ev.vertex;
    s2 += ev.vertex.cwiseProduct(ev.vertex);
  }
  for (int k = 0; k < 3; ++k) {
    const double sigma = o.vertexSigma[k];
    EXPECT_NEAR(s[k] / kEvents, 0.0, 5.0 * sigma / std::sqrt(kEvents));
    EXPECT_NEAR(std::sqrt(s2[k] / kEvents), sigma, 5.0 * sigma / std::sqrt(2.0 * kEvents));
  }
}

}  // namespace
}  // namespace emcalign::sim
