// Recorded beam background: random-trigger events merged into the simulated events before
// clustering reproduce the Poisson model they were recorded from, go where their counters
// are, skip dead counters, and come in a permutation drawn from the seed.

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.hpp"

#include "emcalign/core/units.hpp"
#include "emcalign/sim/simulation.hpp"

namespace emcalign::sim {
namespace {

using geometry::AlignmentParameters;
using geometry::Calorimeter;
using geometry::DetectorDescription;
using units::deg;

const Calorimeter& calorimeter() { return geometry::testing::sndCalorimeter(); }

struct BackgroundPhotons {
  double count = 0.0;      // photon rows made by the background alone (truth pdg 0)
  double energySum = 0.0;  // MeV
  double energySquares = 0.0;
};

BackgroundPhotons simulate(const SimulationOptions& o, std::int64_t events) {
  auto sim = Simulation::create(calorimeter(), AlignmentParameters{}, o);
  EXPECT_TRUE(sim.ok()) << sim.error().message;
  BackgroundPhotons b;
  EventScratch scratch(calorimeter().size());
  std::vector<ParticleRow> rows;
  std::vector<TruthRow> truth;
  for (std::int64_t i = 0; i < events; ++i) {
    rows.clear();
    truth.clear();
    sim->simulateEvent(i, scratch, rows, truth);
    for (std::size_t k = 0; k < rows.size(); ++k) {
      if (rows[k].charged == 0 && truth[k].pdg == 0) {
        b.count += 1.0;
        b.energySum += rows[k].energy;
        b.energySquares += rows[k].energy * rows[k].energy;
      }
    }
  }
  return b;
}

SimulationOptions barrel() {
  SimulationOptions o;
  o.generator.thetaMin = 40.0 * deg;
  o.generator.thetaMax = 140.0 * deg;
  return o;
}

// Random triggers recorded with the Poisson model (another seed), merged instead of it: the
// background photons are as many and as energetic as the model's, within their statistical
// errors; a background three times as energetic is not.
TEST(RecordedBackground, ClosesOnThePoissonModelItWasRecordedFrom) {
  SimulationOptions recorder = barrel();
  recorder.seed = 99;
  auto rtSim = Simulation::create(calorimeter(), AlignmentParameters{}, recorder);
  ASSERT_TRUE(rtSim.ok());
  auto recorded = rtSim->randomTrigger(60000, 0);
  ASSERT_TRUE(recorded.ok());
  // Above the counter threshold: 0.3 hits per event, e^(−2/6) of them above 2 MeV.
  EXPECT_NEAR(static_cast<double>(recorded->allHits().size()) / 60000.0, 0.3 * std::exp(-2.0 / 6.0), 0.01);

  constexpr std::int64_t kEvents = 30000;
  const BackgroundPhotons poisson = simulate(barrel(), kEvents);
  SimulationOptions merged = barrel();
  merged.recordedBackground = std::make_shared<const RandomTriggerEvents>(*recorded);
  const BackgroundPhotons fromRecord = simulate(merged, kEvents);
  ASSERT_GT(poisson.count, 500.0);
  EXPECT_LT(std::abs(fromRecord.count - poisson.count), 4.0 * std::sqrt(fromRecord.count + poisson.count));
  const auto meanAndError = [](const BackgroundPhotons& b) {
    const double mean = b.energySum / b.count;
    const double variance = b.energySquares / b.count - mean * mean;
    return std::pair{mean, std::sqrt(variance / b.count)};
  };
  const auto [m1, e1] = meanAndError(poisson);
  const auto [m2, e2] = meanAndError(fromRecord);
  EXPECT_LT(std::abs(m1 - m2), 4.0 * std::hypot(e1, e2)) << m1 << " vs " << m2;

  RandomTriggerEvents hotter;
  for (std::size_t i = 0; i < recorded->size(); ++i) {
    std::vector<Hit> hits(recorded->hits(i).begin(), recorded->hits(i).end());
    for (Hit& h : hits) h.energy *= 3.0;
    hotter.append(recorded->run(i), recorded->event(i), hits);
  }
  SimulationOptions hot = barrel();
  hot.recordedBackground = std::make_shared<const RandomTriggerEvents>(std::move(hotter));
  const BackgroundPhotons fromHot = simulate(hot, kEvents);
  EXPECT_GT(fromHot.count - poisson.count, 6.0 * std::sqrt(fromHot.count + poisson.count));
}

// One recorded event with 50 MeV in a counter, in a simulation with nothing else in the
// background: every event has a photon there, at the counter's direction; a hit in a dead
// counter is dropped; `--off background` drops them all.
TEST(RecordedBackground, IsMergedIntoItsCounterBeforeClusteringAndSkipsDeadCounters) {
  const int counter = 700;
  const Vec3 centre = calorimeter().counter(counter).centre();
  SimulationOptions o = barrel();
  o.setIdealised();
  o.generator.thetaMin = 40.0 * deg;
  o.generator.thetaMax = 140.0 * deg;
  o.emc.beamBackground = true;
  o.emc.deadCountersOn = true;
  o.emc.deadCounters = {51};
  RandomTriggerEvents one;
  one.append(1, 0, std::vector<Hit>{{counter, 50.0}, {51, 80.0}});
  o.recordedBackground = std::make_shared<const RandomTriggerEvents>(one);
  auto sim = Simulation::create(calorimeter(), AlignmentParameters{}, o);
  ASSERT_TRUE(sim.ok()) << sim.error().message;
  EventScratch scratch(calorimeter().size());
  int found = 0, events = 200, other = 0;
  for (int i = 0; i < events; ++i) {
    std::vector<ParticleRow> rows;
    std::vector<TruthRow> truth;
    sim->simulateEvent(i, scratch, rows, truth);
    for (std::size_t k = 0; k < rows.size(); ++k) {
      if (rows[k].charged != 0 || truth[k].pdg != 0) continue;
      if (std::abs(rows[k].energy - 50.0) < 1e-9 && std::abs(rows[k].thetaEmc - geometry::polar(centre)) < 1e-9 &&
          std::abs(rows[k].phiEmc - geometry::azimuth(centre)) < 1e-9) {
        ++found;
      } else {
        ++other;
      }
    }
  }
  // A shower may overlap the counter now and then: nearly every event has the photon alone.
  EXPECT_GT(found, events * 9 / 10);
  EXPECT_EQ(other, 0) << "the dead counter's 80 MeV made a photon";

  o.emc.beamBackground = false;  // --off background
  auto quiet = Simulation::create(calorimeter(), AlignmentParameters{}, o);
  ASSERT_TRUE(quiet.ok());
  std::vector<ParticleRow> rows;
  std::vector<TruthRow> truth;
  for (int i = 0; i < 50; ++i) quiet->simulateEvent(i, scratch, rows, truth);
  EXPECT_EQ(std::count_if(truth.begin(), truth.end(), [](const TruthRow& t) { return t.pdg == 0; }), 0);
}

TEST(RecordedBackground, EventsComeInAPermutationDrawnFromTheSeedReusedCyclically) {
  RandomTriggerEvents events;
  for (int i = 0; i < 97; ++i) events.append(1, i, std::vector<Hit>{});
  SimulationOptions o;
  o.recordedBackground = std::make_shared<const RandomTriggerEvents>(events);
  const auto orderOf = [&](std::uint64_t seed) {
    o.seed = seed;
    auto sim = Simulation::create(calorimeter(), AlignmentParameters{}, o);
    EXPECT_TRUE(sim.ok());
    std::vector<std::int64_t> order;
    for (std::int64_t i = 0; i < 2 * 97; ++i) order.push_back(sim->recordedEventOf(i));
    return order;
  };
  const auto a = orderOf(5);
  std::vector<std::int64_t> first(a.begin(), a.begin() + 97);
  std::vector<std::int64_t> sorted = first;
  std::sort(sorted.begin(), sorted.end());
  std::vector<std::int64_t> all(97);
  std::iota(all.begin(), all.end(), 0);
  EXPECT_EQ(sorted, all) << "each recorded event once per cycle";
  EXPECT_TRUE(std::equal(first.begin(), first.end(), a.begin() + 97)) << "the second cycle repeats the first";
  EXPECT_NE(first, std::vector<std::int64_t>(all)) << "not the file's order";
  EXPECT_EQ(orderOf(5), a);
  EXPECT_NE(orderOf(6), a);

  // A recorded hit outside the detector is refused when the simulation is made.
  RandomTriggerEvents bad;
  bad.append(1, 0, std::vector<Hit>{{calorimeter().size(), 5.0}});
  o.recordedBackground = std::make_shared<const RandomTriggerEvents>(bad);
  EXPECT_FALSE(Simulation::create(calorimeter(), AlignmentParameters{}, o).ok());
}

}  // namespace
}  // namespace emcalign::sim
