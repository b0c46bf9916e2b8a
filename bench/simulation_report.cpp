// Measures the numbers docs/simulation.md quotes, from the simulation itself:
//   build/bin/emcalign_simulation_report
// Tracking resolution, EMC energy and angular resolution of 600 MeV e± and γ, the
// non-uniformity of the reconstructed angle inside a counter, the share of shower energy in
// layers 1–2, and single-thread throughput per process.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "emcalign/core/units.hpp"
#include "emcalign/sim/simulation.hpp"

namespace {

using namespace emcalign;
using units::deg;

double robustSigma(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const auto at = [&](double q) { return v[static_cast<std::size_t>(q * (v.size() - 1))]; };
  return 0.5 * (at(0.8415) - at(0.1585));
}
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

const geometry::Calorimeter& calo() {
  static const auto c = *geometry::Calorimeter::create(geometry::DetectorDescription::sndDefault());
  return c;
}

void tracking() {
  for (bool ms : {false, true}) {
    sim::TrackingOptions o;
    o.multipleScattering = ms;
    sim::TrackingSystem ts(o);
    Rng rng(1, 0);
    std::vector<double> dPhi, dTheta;
    for (int i = 0; i < 50000; ++i) {
      const double phi = rng.uniform(0.0, 2 * std::numbers::pi);
      const Vec3 d = geometry::pointAt(1.0, 90.0 * deg, phi);
      const auto path = ts.scatter(Vec3::Zero(), d, 612.5, 1.0, rng);
      const auto t = ts.measure(path, rng);
      dPhi.push_back(std::remainder(t->phi - phi, 2 * std::numbers::pi));
      dTheta.push_back(t->theta - 90.0 * deg);
    }
    std::printf(
        "tracking, radial 612.5 MeV e at 90 deg, %s multiple scattering: sigma_phi %.3f deg, sigma_theta %.3f deg\n",
        ms ? "with" : "without", robustSigma(dPhi) / deg, robustSigma(dTheta) / deg);
  }
}

void emc() {
  for (auto p : {sim::Process::Bhabha, sim::Process::GammaGamma}) {
    sim::SimulationOptions o;
    o.generator.process = p;
    o.generator.beamEnergy = 600.0;
    o.generator.radiation = false;
    o.generator.vertexSigma = Vec3::Zero();
    o.generator.beamEnergySpread = 0.0;
    o.generator.thetaMin = 40.0 * deg;
    o.generator.thetaMax = 140.0 * deg;
    o.cosmicFraction = 0.0;
    o.emc.beamBackground = false;
    o.emc.deadCountersOn = false;
    const auto s = *sim::Simulation::create(calo(), geometry::AlignmentParameters{}, o);
    sim::EventScratch scratch(calo().size());
    std::vector<ParticleRow> rows;
    std::vector<TruthRow> truth;
    for (int i = 0; i < 20000; ++i) s.simulateEvent(i, scratch, rows, truth);
    std::vector<double> ratio, dTheta, dPhi;
    double sum[9] = {}, n[9] = {};
    int splitOffs = 0, particles = 0;
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const auto& t = truth[k];
      if (!rows[k].hasCluster() || t.pdg == 0 || t.theta < 45 * deg || t.theta > 135 * deg) continue;
      if (rows[k].energy < 0.3 * t.energy) {
        ++splitOffs;
        continue;
      }
      ++particles;
      ratio.push_back(rows[k].energy / t.energy);
      dTheta.push_back(rows[k].thetaEmc - t.theta);
      const double dp = std::remainder(rows[k].phiEmc - t.phi, 2 * std::numbers::pi);
      dPhi.push_back(dp * std::sin(t.theta));
      const int b = std::min(8, static_cast<int>(std::fmod(t.phi / deg, 9.0)));
      sum[b] += dp / deg;
      n[b] += 1;
    }
    double lo = 1e9, hi = -1e9;
    for (int b = 0; b < 9; ++b) {
      lo = std::min(lo, sum[b] / n[b]);
      hi = std::max(hi, sum[b] / n[b]);
    }
    std::printf(
        "EMC, 600 MeV %s, theta 45-135 deg: E/E_true median %.4f, sigma_E/E %.4f (4.2%%/E^1/4 = %.4f); "
        "sigma_theta %.2f deg, sigma_phi*sin(theta) %.2f deg; phi_emc - phi_true across a 9 deg counter "
        "spans +-%.2f deg; split-off clusters %.2f%% of particles\n",
        p == sim::Process::Bhabha ? "e+-" : "photons", median(ratio), robustSigma(ratio), 0.042 / std::pow(0.6, 0.25),
        robustSigma(dTheta) / deg, robustSigma(dPhi) / deg, 0.5 * (hi - lo), 100.0 * splitOffs / particles);
  }
  // Longitudinal containment: the share of deposited energy in layers 1–2.
  sim::EmcOptions o;
  o.deadCountersOn = false;
  o.energyResolution = false;
  const auto truth = *geometry::AlignmentTransform::create({}, geometry::AlignmentRadii::of(calo().description()));
  sim::CalorimeterResponse response(calo(), truth, o);
  sim::CounterHits hits(calo().size());
  Rng rng(2, 0);
  using Showering = sim::CalorimeterResponse::Showering;
  for (Showering particle : {Showering::Electron, Showering::Photon}) {
    double l12 = 0.0, all = 0.0;
    for (int i = 0; i < 5000; ++i) {
      hits.clear();
      response.shower(hits, 0, 600.0, particle, Vec3::Zero(),
                      geometry::pointAt(1.0, rng.uniform(50.0, 130.0) * deg, rng.uniform(0.0, 6.28)), rng);
      for (int c = 0; c < calo().size(); ++c) {
        all += hits.energy(c);
        if (calo().counter(c).layer <= 2) l12 += hits.energy(c);
      }
    }
    std::printf("showers of 600 MeV %s: %.1f%% of the energy deposited in counters, %.1f%% of that in layers 1-2\n",
                particle == Showering::Photon ? "photons" : "electrons", 100.0 * all / (5000 * 600.0),
                100.0 * l12 / all);
  }
}

void throughput() {
  for (auto p : {sim::Process::Bhabha, sim::Process::GammaGamma, sim::Process::ThreePion}) {
    for (bool barrel : {false, true}) {
      if (barrel && p == sim::Process::ThreePion) continue;
      sim::SimulationOptions o;
      o.generator.process = p;
      o.generator.beamEnergy = sim::defaultBeamEnergy(p);
      if (barrel) {
        o.generator.thetaMin = 40.0 * deg;
        o.generator.thetaMax = 140.0 * deg;
      }
      const auto s = *sim::Simulation::create(calo(), geometry::AlignmentParameters{}, o);
      sim::EventScratch scratch(calo().size());
      std::vector<ParticleRow> rows;
      std::vector<TruthRow> truth;
      constexpr int kEvents = 100000;
      const auto t0 = std::chrono::steady_clock::now();
      for (int i = 0; i < kEvents; ++i) {
        if (rows.size() > 100000) {
          rows.clear();
          truth.clear();
        }
        s.simulateEvent(i, scratch, rows, truth);
      }
      const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::printf("throughput, one thread, %s%s, full realism: %.0f events/s\n", std::string(sim::name(p)).c_str(),
                  barrel ? " (theta 40-140 deg)" : " (theta 10-170 deg)", kEvents / dt);
    }
  }
}

}  // namespace

int main() {
  tracking();
  emc();
  throughput();
  return 0;
}
