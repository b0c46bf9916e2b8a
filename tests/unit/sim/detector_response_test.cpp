// The detector response of the simulation: tracking resolution, shower containment and
// energy resolution, EMC angular resolution and its non-uniformity inside a counter, and the
// sign of a misalignment in the residuals.

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.hpp"

#include "emcalign/core/units.hpp"
#include "emcalign/geometry/residual_model.hpp"
#include "emcalign/sim/simulation.hpp"

namespace emcalign::sim {
namespace {

using geometry::AlignmentParameters;
using geometry::Calorimeter;
using geometry::DetectorDescription;
using units::deg;

const Calorimeter& calorimeter() { return geometry::testing::sndCalorimeter(); }

// Half-width of the central 68.3% of the values: a Gaussian σ robust to tails.
double robustSigma(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const auto at = [&](double q) { return v[static_cast<std::size_t>(q * (v.size() - 1))]; };
  return 0.5 * (at(0.8415) - at(0.1585));
}

double mean(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x;
  return s / v.size();
}

struct Sample {
  std::vector<ParticleRow> rows;
  std::vector<TruthRow> truth;
};

Sample simulate(const SimulationOptions& o, const AlignmentParameters& eta, std::int64_t events) {
  auto sim = Simulation::create(calorimeter(), eta, o);
  EXPECT_TRUE(sim.ok()) << sim.error().message;
  Sample s;
  EventScratch scratch(calorimeter().size());
  for (std::int64_t i = 0; i < events; ++i) sim->simulateEvent(i, scratch, s.rows, s.truth);
  return s;
}

// The neighbour lists look only at the cells around a counter's φ range: they must be the
// lists a scan of every cell of the adjacent rings and layers finds, in the same order (the
// clustering's order, hence the output, depends on it), for the SND-like detector and one
// with rings of 4 and 400 cells side by side.
TEST(Clustering, NeighbourListsEqualAFullScan) {
  DetectorDescription mixed = DetectorDescription::sndDefault();
  mixed.countersPerRing = {4, 400, 8, 36, 36, 400, 4, 12};
  for (const DetectorDescription& d : {DetectorDescription::sndDefault(), mixed}) {
    const auto calo = Calorimeter::create(d);
    ASSERT_TRUE(calo.ok());
    const CounterNeighbours neighbours(*calo);
    const double twoPi = 2.0 * std::numbers::pi;
    for (const auto& a : calo->counters()) {
      std::vector<int> expected;
      for (const auto& b : calo->counters()) {
        if (b.index == a.index || std::abs(b.layer - a.layer) > 1 || std::abs(b.ring - a.ring) > 1) continue;
        for (double shift : {-twoPi, 0.0, twoPi}) {
          if (a.phiMin <= b.phiMax + shift + 1e-9 && b.phiMin + shift <= a.phiMax + 1e-9) {
            expected.push_back(b.index);
            break;
          }
        }
      }
      const auto got = neighbours.of(a.index);
      ASSERT_EQ(std::vector<int>(got.begin(), got.end()), expected) << "counter " << a.index;
    }
  }
}

TEST(Tracking, ResolutionOfRadialTracksIsTheDocumentedOne) {
  TrackingOptions o;
  o.multipleScattering = false;
  TrackingSystem ts(o);
  Rng rng(5, 0);
  std::vector<double> dPhi, dTheta;
  for (int i = 0; i < 20000; ++i) {
    const double phi = rng.uniform(0.0, 2 * std::numbers::pi);
    const Vec3 d = geometry::pointAt(1.0, 90.0 * deg, phi);
    const auto t = ts.measure({Vec3::Zero(), d}, rng);
    ASSERT_TRUE(t);
    dPhi.push_back(std::remainder(t->phi - phi, 2 * std::numbers::pi));
    dTheta.push_back(t->theta - 90.0 * deg);
    EXPECT_LT(std::abs(t->z0), 0.5);
    EXPECT_LT(std::abs(t->rho), 0.5);
  }
  EXPECT_NEAR(robustSigma(dPhi) / deg, 0.26, 0.02);
  EXPECT_NEAR(robustSigma(dTheta) / deg, 0.30, 0.02);
  EXPECT_NEAR(mean(dPhi) / deg, 0.0, 0.01);
}

TEST(Tracking, FitRecoversADisplacedLine) {
  TrackingOptions o;
  o.multipleScattering = false;
  o.sigmaRPhi = 1e-6;
  o.sigmaZ = 1e-6;
  TrackingSystem ts(o);
  Rng rng(6, 0);
  // Closest approach (−rho·sinφ, rho·cosφ, z0) with rho = 0.4, z0 = −3, φ = 40°, θ = 70°.
  const double phi = 40.0 * deg, theta = 70.0 * deg, rho = 0.4, z0 = -3.0;
  const Vec3 c(-rho * std::sin(phi), rho * std::cos(phi), z0);
  const auto t = ts.measure({c, geometry::pointAt(1.0, theta, phi)}, rng);
  ASSERT_TRUE(t);
  EXPECT_NEAR(t->phi, phi, 1e-6);
  EXPECT_NEAR(t->theta, theta, 1e-6);
  EXPECT_NEAR(t->rho, rho, 1e-5);
  EXPECT_NEAR(t->z0, z0, 1e-5);
}

TEST(Calorimeter, ElectronShowersSitMostlyInLayersOneAndTwo) {
  const auto& calo = calorimeter();
  EmcOptions o;
  o.deadCountersOn = false;
  o.energyResolution = false;
  auto truth =
      geometry::AlignmentTransform::create(AlignmentParameters{}, geometry::AlignmentRadii::of(calo.description()));
  CalorimeterResponse response(calo, *truth, o);
  CounterHits hits(calo.size());
  Rng rng(7, 0);
  double layers12 = 0.0, all = 0.0;
  for (int i = 0; i < 2000; ++i) {
    hits.clear();
    const Vec3 d = geometry::pointAt(1.0, rng.uniform(50.0, 130.0) * deg, rng.uniform(0.0, 6.28));
    response.shower(hits, 0, 600.0, CalorimeterResponse::Showering::Electron, Vec3::Zero(), d, rng);
    for (int c = 0; c < calo.size(); ++c) {
      const double e = hits.energy(c);
      all += e;
      if (calo.counter(c).layer <= 2) layers12 += e;
    }
  }
  const double contained = all / (2000 * 600.0);
  EXPECT_GT(layers12 / all, 0.8);
  EXPECT_GT(contained, 0.85);
  EXPECT_LT(contained, 1.0);
}

// The knobs of the systematic variations (docs/systematics.md) move what they say: the
// energy-weighted depth of 600 MeV electron showers with t_max and with the material
// before the EMC, its spread with the fluctuation of t_max, and the gains of the counters.
struct ShowerDepths {
  double mean = 0.0, sigma = 0.0, deposited = 0.0;
};
ShowerDepths showerDepths(const EmcOptions& o) {
  const auto& calo = calorimeter();
  auto truth =
      geometry::AlignmentTransform::create(AlignmentParameters{}, geometry::AlignmentRadii::of(calo.description()));
  CalorimeterResponse response(calo, *truth, o);
  CounterHits hits(calo.size());
  Rng rng(11, 0);
  std::vector<double> depth;
  double all = 0.0;
  for (int i = 0; i < 3000; ++i) {
    hits.clear();
    const Vec3 d = geometry::pointAt(1.0, 90.0 * deg, rng.uniform(0.3, 1.2));  // away from the plane x = 0
    response.shower(hits, 0, 600.0, CalorimeterResponse::Showering::Electron, Vec3::Zero(), d, rng);
    const Vec3 c = hits.sourceCentre(0);
    if (c.allFinite()) depth.push_back(c.norm());
    all += hits.sourceEnergy(0);
  }
  return {mean(depth), robustSigma(depth), all / (3000 * 600.0)};
}

TEST(Calorimeter, VariationKnobsMoveTheShower) {
  EmcOptions o;
  o.deadCountersOn = false;
  o.energyResolution = false;
  const ShowerDepths nominal = showerDepths(o);
  EmcOptions deeper = o;
  deeper.tMaxShift = 0.5;  // X0 of NaI: 2.56 cm deeper in t_max
  const ShowerDepths shifted = showerDepths(deeper);
  EXPECT_NEAR(shifted.mean - nominal.mean, 0.5 * 2.56, 0.4) << nominal.mean << " -> " << shifted.mean;
  EmcOptions calm = o;
  calm.tMaxFluctuationScale = 0.0;  // no event-by-event fluctuation of t_max
  EXPECT_LT(showerDepths(calm).sigma, nominal.sigma);
  EmcOptions thick = o;
  thick.preshowerMaterial = 1.13;  // one X0 more before the EMC: it starts earlier, more is lost
  const ShowerDepths early = showerDepths(thick);
  EXPECT_LT(early.mean, nominal.mean - 1.0);
  EXPECT_LT(early.deposited, nominal.deposited);

  const auto& calo = calorimeter();
  auto truth =
      geometry::AlignmentTransform::create(AlignmentParameters{}, geometry::AlignmentRadii::of(calo.description()));
  EXPECT_TRUE(CalorimeterResponse(calo, *truth, o).gains().empty());
  EmcOptions spread = o;
  spread.counterGainSpread = 0.05;
  const CalorimeterResponse withGains(calo, *truth, spread);
  const std::vector<double> gains(withGains.gains().begin(), withGains.gains().end());
  ASSERT_EQ(gains.size(), static_cast<std::size_t>(calo.size()));
  EXPECT_NEAR(mean(gains), 1.0, 0.005);
  EXPECT_NEAR(robustSigma(gains), 0.05, 0.005);
  const CalorimeterResponse again(calo, *truth, spread);  // fixed by the seed
  EXPECT_TRUE(std::equal(gains.begin(), gains.end(), again.gains().begin()));
  using Edit = void (*)(EmcOptions&);
  for (Edit bad : std::initializer_list<Edit>{
           [](EmcOptions& e) { e.counterGainSpread = 0.9; }, [](EmcOptions& e) { e.tMaxShift = NAN; },
           [](EmcOptions& e) { e.tMaxFluctuationScale = -1.0; }, [](EmcOptions& e) { e.preshowerMaterial = -0.1; }}) {
    EmcOptions e = o;
    bad(e);
    EXPECT_FALSE(e.validate(calo.size()).ok());
  }
}

SimulationOptions cleanOptions(Process process) {
  SimulationOptions o;
  o.generator.process = process;
  o.generator.beamEnergy = 600.0;
  o.generator.radiation = false;
  o.generator.vertexSigma = Vec3::Zero();
  o.generator.beamEnergySpread = 0.0;
  o.cosmicFraction = 0.0;
  o.emc.beamBackground = false;
  o.emc.deadCountersOn = false;
  o.generator.thetaMin = 40.0 * deg;  // Bhabha events are forward-peaked: keep them useful
  o.generator.thetaMax = 140.0 * deg;
  return o;
}

TEST(Calorimeter, EnergyResolutionIsNearTheFormula) {
  // Photons and electrons of 600 MeV in the barrel; split-off fragments (< 30% of the
  // energy) are not the particle's cluster.
  for (Process p : {Process::GammaGamma, Process::Bhabha}) {
    const Sample s = simulate(cleanOptions(p), AlignmentParameters{}, 4000);
    std::vector<double> ratio;
    for (std::size_t i = 0; i < s.rows.size(); ++i) {
      const auto& t = s.truth[i];
      if (s.rows[i].hasCluster() && t.pdg != 0 && t.theta > 45 * deg && t.theta < 135 * deg &&
          s.rows[i].energy > 0.3 * t.energy) {
        ratio.push_back(s.rows[i].energy / t.energy);
      }
    }
    ASSERT_GT(ratio.size(), 2000u) << name(p);
    const double formula = 0.042 / std::pow(0.6, 0.25);  // 4.77% at 600 MeV
    std::vector<double> sorted = ratio;
    std::sort(sorted.begin(), sorted.end());
    EXPECT_NEAR(sorted[sorted.size() / 2], 1.0, 0.02) << name(p);  // the leakage correction
    EXPECT_GT(robustSigma(ratio), 0.8 * formula) << name(p);
    EXPECT_LT(robustSigma(ratio), 1.2 * formula) << name(p);
  }
}

TEST(Calorimeter, AngularResolutionOf600MeVElectronsAndPhotons) {
  for (Process p : {Process::Bhabha, Process::GammaGamma}) {
    const Sample s = simulate(cleanOptions(p), AlignmentParameters{}, 4000);
    std::vector<double> dTheta, dPhi;
    for (std::size_t i = 0; i < s.rows.size(); ++i) {
      const auto& r = s.rows[i];
      const auto& t = s.truth[i];
      if (!r.hasCluster() || t.pdg == 0 || t.theta < 45 * deg || t.theta > 135 * deg) continue;
      dTheta.push_back(r.thetaEmc - t.theta);
      dPhi.push_back(std::remainder(r.phiEmc - t.phi, 2 * std::numbers::pi) * std::sin(t.theta));
    }
    ASSERT_GT(dTheta.size(), 4000u);
    for (double sigma : {robustSigma(dTheta), robustSigma(dPhi)}) {
      EXPECT_GT(sigma / deg, 1.0) << name(p);
      EXPECT_LT(sigma / deg, 2.5) << name(p);
    }
  }
}

TEST(Calorimeter, ReconstructedAngleIsNonUniformInsideACounter) {
  // Directions from counter centres pull the angle towards the centre of the hit counter:
  // φ_emc − φ_true against the position inside a 9° counter is an S-curve.
  const Sample s = simulate(cleanOptions(Process::GammaGamma), AlignmentParameters{}, 20000);
  constexpr int kBins = 9;
  std::vector<double> sum(kBins, 0.0);
  std::vector<int> n(kBins, 0);
  for (std::size_t i = 0; i < s.rows.size(); ++i) {
    const auto& t = s.truth[i];
    if (!s.rows[i].hasCluster() || t.pdg != pdg::Photon || t.theta < 50 * deg || t.theta > 130 * deg) continue;
    const double inCell = std::fmod(t.phi / deg, 9.0) / 9.0;  // 0..1 across the counter
    const int b = std::min(kBins - 1, static_cast<int>(inCell * kBins));
    sum[b] += std::remainder(s.rows[i].phiEmc - t.phi, 2 * std::numbers::pi) / deg;
    n[b] += 1;
  }
  std::vector<double> profile(kBins);
  for (int b = 0; b < kBins; ++b) {
    ASSERT_GT(n[b], 500);
    profile[b] = sum[b] / n[b];
  }
  const double amplitude =
      0.5 * (*std::max_element(profile.begin(), profile.end()) - *std::min_element(profile.begin(), profile.end()));
  EXPECT_GT(amplitude, 0.1);
  EXPECT_GT(profile[1], 0.05);           // left of the centre: pulled up
  EXPECT_LT(profile[kBins - 2], -0.05);  // right of the centre: pulled down
  EXPECT_NEAR(profile[kBins / 2], 0.0, 0.1);
}

// The docs/contract.md §7 selection, written here in a few lines so that the simulation can be tested
// before (and independently of) the calibration module.
double meanSinDeltaPhi(const Sample& s) {
  const geometry::ShowerDepth depth = geometry::ShowerDepth::of(calorimeter().description());
  double sum = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < s.rows.size();) {
    std::size_t j = i;
    while (j < s.rows.size() && s.rows[j].event == s.rows[i].event) ++j;
    const bool twoCharged = j - i == 2 && s.rows[i].charged == 1 && s.rows[i + 1].charged == 1;
    if (twoCharged && s.rows[i].muonVeto == 0) {
      bool ok = true;
      for (std::size_t k = i; k < j; ++k) {
        const auto& r = s.rows[k];
        ok = ok && r.hasCluster() && std::abs(r.z0) < 10 && std::abs(r.rho) < 1 && r.energy > 0.8 * r.beamEnergy &&
             r.energy < 1.1 * r.beamEnergy;
      }
      const double acol = std::abs(180.0 - std::abs(s.rows[i].phiTs - s.rows[i + 1].phiTs) / deg);
      if (ok && acol < 10.0) {
        for (std::size_t k = i; k < j; ++k) {
          const auto& r = s.rows[k];
          const auto y =
              geometry::measuredResidual({r.z0, r.rho, r.phiTs, r.thetaTs}, r.energy, r.phiEmc, r.thetaEmc, depth);
          if (y && r.thetaEmc > 45 * deg && r.thetaEmc < 135 * deg) {
            sum += y->phi;
            ++n;
          }
        }
      }
    }
    i = j;
  }
  EXPECT_GT(n, 1000);
  return sum / n;
}

TEST(Simulation, PureAlphaShowsUpInTheAzimuthalResidual) {
  SimulationOptions o;  // full realism, only the generated range limited to the barrel
  o.generator.thetaMin = 40.0 * deg;
  o.generator.thetaMax = 140.0 * deg;
  AlignmentParameters zero;
  EXPECT_NEAR(std::asin(meanSinDeltaPhi(simulate(o, zero, 6000))) / deg, 0.0, 0.05);
  AlignmentParameters alpha;
  alpha[Param::Alpha] = 3.0 * deg;
  EXPECT_NEAR(std::asin(meanSinDeltaPhi(simulate(o, alpha, 6000))) / deg, 3.0, 0.1);
}

TEST(Simulation, SameSeedSameEventsAndIdealisedLimitIsClean) {
  SimulationOptions o;
  o.seed = 42;
  const Sample a = simulate(o, AlignmentParameters{}, 300);
  const Sample b = simulate(o, AlignmentParameters{}, 300);
  ASSERT_EQ(a.rows.size(), b.rows.size());
  for (std::size_t i = 0; i < a.rows.size(); ++i) {
    EXPECT_EQ(a.rows[i].event, b.rows[i].event);
    EXPECT_TRUE(a.rows[i].energy == b.rows[i].energy || (std::isnan(a.rows[i].energy) && std::isnan(b.rows[i].energy)));
  }
  // In the idealised limit every barrel ee event is two tracks with their clusters and no
  // photon, and the clusters point where the deposit is.
  SimulationOptions ideal;
  ideal.setIdealised();
  ideal.generator.thetaMin = 40.0 * deg;
  ideal.generator.thetaMax = 140.0 * deg;
  const Sample c = simulate(ideal, AlignmentParameters{}, 500);
  ASSERT_EQ(c.rows.size(), 1000u);
  for (std::size_t i = 0; i < c.rows.size(); ++i) {
    EXPECT_EQ(c.rows[i].charged, 1);
    ASSERT_TRUE(c.rows[i].hasCluster());
    EXPECT_NEAR(c.rows[i].energy, c.truth[i].energy, 1e-6 * c.truth[i].energy);
    // Seen from the origin, the deposit is where the cluster points, up to the 1.5° smearing.
    EXPECT_NEAR(c.rows[i].thetaEmc, geometry::polar(c.truth[i].showerCentre), 7.5 * deg);
  }
}

}  // namespace
}  // namespace emcalign::sim

namespace emcalign::sim {
namespace {

// Every cluster row keeps its counters, and the one reconstruction function gives, from
// them and the nominal centres, the row's direction to the last bit (what correct --method
// hits relies on).
TEST(Reconstruction, ClusterRowsKeepTheirCountersAndTheirDirection) {
  SimulationOptions o;
  o.generator.process = Process::ThreePion;
  o.generator.beamEnergy = defaultBeamEnergy(Process::ThreePion);
  auto sim = Simulation::create(calorimeter(), AlignmentParameters{}, o);
  ASSERT_TRUE(sim.ok());
  EventScratch scratch(calorimeter().size());
  std::vector<ParticleRow> rows;
  std::vector<TruthRow> truth;
  std::vector<Hit> hits;
  for (std::int64_t i = 0; i < 300; ++i) sim->simulateEvent(i, scratch, rows, truth, &hits);
  const auto nominal = geometry::CounterGeometry::nominal(calorimeter());
  std::size_t at = 0, clusters = 0;
  for (const ParticleRow& r : rows) {
    const std::span<const Hit> own(hits.data() + at, static_cast<std::size_t>(r.hitCount));
    at += own.size();
    if (std::isnan(r.energy)) {
      EXPECT_EQ(r.hitCount, 0);
      continue;
    }
    ++clusters;
    ASSERT_GT(r.hitCount, 0);
    double sum = 0.0;
    for (const Hit& h : own) {
      ASSERT_GE(h.counter, 0);
      ASSERT_LT(h.counter, calorimeter().size());
      sum += h.energy;
    }
    EXPECT_EQ(sum / o.reconstruction.containment, r.energy);
    const auto d = clusterDirection(own, nominal, o.reconstruction.logWeightW0);
    ASSERT_TRUE(d);
    EXPECT_EQ(d->first, r.thetaEmc);
    EXPECT_EQ(d->second, r.phiEmc);
  }
  EXPECT_EQ(at, hits.size());
  EXPECT_GT(clusters, 600u);
}

}  // namespace
}  // namespace emcalign::sim
