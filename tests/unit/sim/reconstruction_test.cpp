// The cluster reconstruction of the simulation (sim/reconstruction.hpp) on hand-placed
// counter energies: clusters are the connected groups of fired counters, their energy the
// sum over the containment, their direction the log-weighted mean of the counter centres;
// light clusters are dropped; tracks take the nearest cluster within the match radius.

#include "emcalign/sim/reconstruction.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "test_support.hpp"

#include "emcalign/core/units.hpp"

namespace emcalign::sim {
namespace {

using geometry::Calorimeter;
using geometry::CounterGeometry;
using geometry::DetectorDescription;
using geometry::TrackLine;
using units::deg;

const Calorimeter& calorimeter() { return geometry::testing::sndCalorimeter(); }

const CounterGeometry& nominal() {
  static const CounterGeometry g = CounterGeometry::nominal(calorimeter());
  return g;
}

const CounterNeighbours& neighbours() {
  static const CounterNeighbours n(calorimeter());
  return n;
}

// Layer 1..3, ring 0..15 from θ = 18°, iphi from φ = 0 (ring 8: θ 90°–99°, 40 cells of 9°).
int counter(int layer, int ring, int iphi) {
  const int c = calorimeter().counterIndex(layer, ring, iphi);
  EXPECT_GE(c, 0) << layer << " " << ring << " " << iphi;
  return c;
}

// Angles (θ, φ) of a point as docs/contract.md §1 defines them, written out.
std::pair<double, double> anglesOf(const Vec3& p) {
  double phi = std::atan2(p.y(), p.x());
  if (phi < 0.0) phi += 2.0 * std::numbers::pi;
  return {std::acos(p.z() / p.norm()), phi};
}

// Counter energies placed by hand, digitised without noise (threshold 2 MeV), clustered.
class ClusterFinding : public ::testing::Test {
 protected:
  ClusterFinding() : hits_(calorimeter().size()) { digitization_.noise = false; }

  // `energy` MeV in a counter, at its centre.
  void deposit(int c, double energy, int source = 0) {
    const Vec3& centre = nominal().centre(c);
    hits_.add(c, source, energy, centre, centre);
  }
  const std::vector<Cluster>& reconstruct() {
    hits_.digitize(digitization_, {}, rng_);
    findClusters(hits_, nominal(), neighbours(), options_, scratch_, rng_, clusters_);
    return clusters_;
  }
  // The counters of a found cluster, sorted by index.
  std::vector<int> countersOf(const Cluster& cl) const {
    std::vector<int> out;
    for (int k = 0; k < cl.counters; ++k)
      out.push_back(scratch_.hits[static_cast<std::size_t>(cl.firstHit + k)].counter);
    std::sort(out.begin(), out.end());
    return out;
  }
  // The cluster direction of the contract-like log weights, computed here from the counter centres:
  // Σ w_i·c_i with w_i = max(0, W0 + ln(E_i/E)).
  std::pair<double, double> logWeighted(const std::vector<std::pair<int, double>>& deposits) const {
    double sum = 0.0;
    for (const auto& [c, e] : deposits) sum += e;
    Vec3 centre = Vec3::Zero();
    for (const auto& [c, e] : deposits)
      centre += std::max(0.0, options_.logWeightW0 + std::log(e / sum)) * nominal().centre(c);
    return anglesOf(centre);
  }

  EmcOptions digitization_;
  ReconstructionOptions options_;
  CounterHits hits_;
  ClusterScratch scratch_;
  Rng rng_{201, 0};
  std::vector<Cluster> clusters_;
};

TEST_F(ClusterFinding, SingleCounterGivesOneClusterAtItsCentre) {
  const int c = counter(1, 8, 5);
  deposit(c, 300.0, 3);
  const auto& cl = reconstruct();
  ASSERT_EQ(cl.size(), 1u);
  EXPECT_DOUBLE_EQ(cl[0].energy, 300.0 / options_.containment);
  EXPECT_EQ(cl[0].counters, 1);
  EXPECT_EQ(cl[0].mainSource, 3);
  EXPECT_THAT(countersOf(cl[0]), ::testing::ElementsAre(c));
  const auto [theta, phi] = anglesOf(nominal().centre(c));
  EXPECT_NEAR(cl[0].theta, theta, 1e-12);
  EXPECT_NEAR(cl[0].phi, phi, 1e-12);
  // The counter's own mid-angles: ring 8 starts at 90°, iphi 5 at 45°.
  EXPECT_NEAR(cl[0].theta, 94.5 * deg, 1e-12);
  EXPECT_NEAR(cl[0].phi, 49.5 * deg, 1e-12);
}

TEST_F(ClusterFinding, DirectionIsTheLogWeightedMeanOfTheCounterCentres) {
  // A shower shared by two φ neighbours and the counter behind the main one.
  const int main = counter(1, 8, 5), side = counter(1, 8, 6), behind = counter(2, 8, 5);
  const std::vector<std::pair<int, double>> deposits = {{main, 250.0}, {side, 90.0}, {behind, 60.0}};
  for (const auto& [c, e] : deposits) deposit(c, e);
  const auto& cl = reconstruct();
  ASSERT_EQ(cl.size(), 1u);
  EXPECT_DOUBLE_EQ(cl[0].energy, 400.0 / options_.containment);
  EXPECT_THAT(countersOf(cl[0]), ::testing::ElementsAre(main, side, behind));
  const auto [theta, phi] = logWeighted(deposits);
  EXPECT_NEAR(cl[0].theta, theta, 1e-12);
  EXPECT_NEAR(cl[0].phi, phi, 1e-12);
  // Between the two φ centres (49.5° and 58.5°), nearer the main counter.
  EXPECT_GT(cl[0].phi, 49.5 * deg);
  EXPECT_LT(cl[0].phi, 54.0 * deg);
  // The same answer from the function the correction uses, on the cluster's own counters.
  const std::span<const Hit> own(scratch_.hits.data() + cl[0].firstHit, static_cast<std::size_t>(cl[0].counters));
  const auto d = clusterDirection(own, nominal(), options_.logWeightW0);
  ASSERT_TRUE(d);
  EXPECT_EQ(d->first, cl[0].theta);
  EXPECT_EQ(d->second, cl[0].phi);
}

TEST_F(ClusterFinding, CountersBelowEToTheMinusW0OfTheSumAddEnergyButNoWeight) {
  // e^−3.5 = 3.0% of 400 MeV is 12 MeV: a 5 MeV neighbour has weight 0.
  const int main = counter(1, 8, 5), side = counter(1, 8, 6), faint = counter(1, 8, 4);
  deposit(main, 300.0);
  deposit(side, 95.0);
  deposit(faint, 5.0);
  const auto& cl = reconstruct();
  ASSERT_EQ(cl.size(), 1u);
  EXPECT_EQ(cl[0].counters, 3);
  EXPECT_DOUBLE_EQ(cl[0].energy, 400.0 / options_.containment);
  const auto [theta, phi] = logWeighted({{main, 300.0}, {side, 95.0}, {faint, 5.0}});
  EXPECT_NEAR(cl[0].phi, phi, 1e-12);
  EXPECT_NEAR(cl[0].theta, theta, 1e-12);
  // Had the faint counter kept its negative weight W0 + ln(5/400) = −0.88, the direction
  // would be pushed away from it by about 2.5°: the clamp is what the comparison above sees.
  Vec3 unclamped = Vec3::Zero();
  for (const auto& [c, e] : {std::pair{main, 300.0}, std::pair{side, 95.0}, std::pair{faint, 5.0}}) {
    unclamped += (options_.logWeightW0 + std::log(e / 400.0)) * nominal().centre(c);
  }
  EXPECT_GT(std::abs(anglesOf(unclamped).second - cl[0].phi), 1.0 * deg);
}

TEST_F(ClusterFinding, TwoFarDepositsGiveTwoClusters) {
  const int a = counter(1, 8, 5), b = counter(1, 7, 25);  // φ 49.5° and 229.5°: opposite
  deposit(a, 500.0, 1);
  deposit(b, 200.0, 2);
  const auto& cl = reconstruct();
  ASSERT_EQ(cl.size(), 2u);
  const Cluster& first = cl[0].mainSource == 1 ? cl[0] : cl[1];
  const Cluster& second = cl[0].mainSource == 1 ? cl[1] : cl[0];
  EXPECT_EQ(first.mainSource, 1);
  EXPECT_EQ(second.mainSource, 2);
  EXPECT_DOUBLE_EQ(first.energy, 500.0 / options_.containment);
  EXPECT_DOUBLE_EQ(second.energy, 200.0 / options_.containment);
  EXPECT_THAT(countersOf(first), ::testing::ElementsAre(a));
  EXPECT_THAT(countersOf(second), ::testing::ElementsAre(b));
  EXPECT_NEAR(second.phi, 229.5 * deg, 1e-12);
  EXPECT_NEAR(second.theta, 85.5 * deg, 1e-12);
}

// Neighbours merge in φ, in θ, in depth and across a corner, across φ = 0 and across the
// 36° ring where 22.5° cells meet 9° cells; one empty counter between them keeps two apart.
TEST_F(ClusterFinding, TouchingCountersMergeAndSeparatedOnesDoNot) {
  struct Pair {
    const char* what;
    int a, b;
    std::size_t clusters;
  };
  const Pair pairs[] = {
      {"φ neighbours", counter(1, 8, 5), counter(1, 8, 6), 1},
      {"θ neighbours", counter(1, 8, 5), counter(1, 9, 5), 1},
      {"layer 1 and layer 2", counter(1, 8, 5), counter(2, 8, 5), 1},
      {"layer 2 and layer 3", counter(2, 8, 5), counter(3, 8, 5), 1},
      {"corner", counter(1, 8, 5), counter(2, 9, 6), 1},
      {"across φ = 0", counter(1, 8, 0), counter(1, 8, 39), 1},
      // φ 22.5°–45° and 36°–45° across θ = 36°, and the other way round across θ = 144°.
      {"22.5° cell next to a 9° cell", counter(1, 1, 1), counter(1, 2, 4), 1},
      {"9° cell next to a 22.5° cell", counter(1, 13, 4), counter(1, 14, 1), 1},
      {"one counter apart in φ", counter(1, 8, 5), counter(1, 8, 7), 2},
      {"one ring apart", counter(1, 8, 5), counter(1, 10, 5), 2},
      {"layer 1 and layer 3", counter(1, 8, 5), counter(3, 8, 5), 2},
  };
  for (const Pair& p : pairs) {
    SCOPED_TRACE(p.what);
    hits_.clear();
    deposit(p.a, 200.0);
    deposit(p.b, 100.0);
    const auto& cl = reconstruct();
    ASSERT_EQ(cl.size(), p.clusters);
    double total = 0.0;
    for (const Cluster& c : cl) total += c.energy;
    EXPECT_DOUBLE_EQ(total, 300.0 / options_.containment);
    if (p.clusters == 1) {
      EXPECT_THAT(countersOf(cl[0]), ::testing::UnorderedElementsAre(p.a, p.b));
    }
  }
}

TEST_F(ClusterFinding, MainSourceIsTheOneWithMostEnergy) {
  deposit(counter(1, 8, 5), 150.0, 4);
  deposit(counter(1, 8, 6), 120.0, 6);
  deposit(counter(1, 8, 5), 20.0, 6);  // 140 MeV of source 6 in all: still less than 150
  const auto& cl = reconstruct();
  ASSERT_EQ(cl.size(), 1u);
  EXPECT_EQ(cl[0].mainSource, 4);
  EXPECT_DOUBLE_EQ(cl[0].energy, 290.0 / options_.containment);
}

// Counters fire from 2 MeV (digitisation); clusters are kept from 10 MeV after the
// containment correction, i.e. from 9.58 MeV deposited.
TEST_F(ClusterFinding, CounterAndClusterThresholds) {
  const int main = counter(1, 8, 5), faint = counter(1, 8, 6);
  deposit(main, 100.0);
  deposit(faint, 1.5);  // below the counter threshold: not fired, not in the cluster
  auto cl = reconstruct();
  ASSERT_EQ(cl.size(), 1u);
  EXPECT_THAT(countersOf(cl[0]), ::testing::ElementsAre(main));
  EXPECT_DOUBLE_EQ(cl[0].energy, 100.0 / options_.containment);

  ASSERT_DOUBLE_EQ(options_.clusterThreshold, 10.0);
  for (const double e : {9.5, 9.65}) {
    SCOPED_TRACE(e);
    hits_.clear();
    deposit(main, e);
    cl = reconstruct();
    const bool kept = e / options_.containment >= options_.clusterThreshold;
    EXPECT_EQ(kept, e > 9.58);
    ASSERT_EQ(cl.size(), kept ? 1u : 0u);
    if (!kept) {
      EXPECT_TRUE(scratch_.hits.empty());  // a dropped cluster leaves no counters
    }
  }
  // A light cluster in the same event as a heavy one is dropped alone.
  hits_.clear();
  deposit(main, 100.0);
  deposit(counter(1, 2, 30), 6.0);
  cl = reconstruct();
  ASSERT_EQ(cl.size(), 1u);
  EXPECT_THAT(countersOf(cl[0]), ::testing::ElementsAre(main));
  options_.clusterThreshold = 0.0;
  hits_.clear();
  deposit(main, 100.0);
  deposit(counter(1, 2, 30), 6.0);
  EXPECT_EQ(reconstruct().size(), 2u);
}

// With W0 small enough that no counter of a two-counter cluster has a positive weight, the
// direction does not exist: clusterDirection says so and the cluster is not made.
TEST_F(ClusterFinding, NoPositiveWeightMeansNoDirectionAndNoCluster) {
  const int a = counter(1, 8, 5), b = counter(1, 8, 6);
  const std::vector<Hit> equal = {{a, 100.0}, {b, 100.0}};
  EXPECT_FALSE(clusterDirection(equal, nominal(), 0.5));  // 0.5 + ln(1/2) < 0
  EXPECT_TRUE(clusterDirection(equal, nominal(), 0.8));   // 0.8 + ln(1/2) > 0
  options_.logWeightW0 = 0.5;
  deposit(a, 100.0);
  deposit(b, 100.0);
  deposit(counter(1, 8, 25), 100.0);  // alone: weight 0.5, kept
  const auto& cl = reconstruct();
  ASSERT_EQ(cl.size(), 1u);
  EXPECT_THAT(countersOf(cl[0]), ::testing::ElementsAre(counter(1, 8, 25)));
  EXPECT_EQ(scratch_.hits.size(), 1u);
}

// The idealised limit: the direction of the deposited energy itself, here unsmeared.
TEST_F(ClusterFinding, IdealisedDirectionIsThatOfTheDepositedEnergy) {
  options_.directionFromCounters = false;
  options_.idealDirectionSigma = 0.0;
  const int a = counter(1, 8, 5), b = counter(1, 8, 6);
  const Vec3 pa = geometry::pointAt(36.0, 91.0 * deg, 46.0 * deg);  // off the counter centres
  const Vec3 pb = geometry::pointAt(38.0, 97.0 * deg, 55.0 * deg);
  hits_.add(a, 0, 300.0, pa, pa);
  hits_.add(b, 0, 100.0, pb, pb);
  const auto& cl = reconstruct();
  ASSERT_EQ(cl.size(), 1u);
  const auto [theta, phi] = anglesOf(300.0 * pa + 100.0 * pb);
  EXPECT_NEAR(cl[0].theta, theta, 1e-12);
  EXPECT_NEAR(cl[0].phi, phi, 1e-12);
  EXPECT_DOUBLE_EQ(cl[0].energy, 400.0 / options_.containment);
}

// matchTracks: each track takes the cluster nearest in angle to its point on the sphere of
// matchSphereRadius, within matchRadius (15°), a cluster once, the closest pairs first.
TEST(TrackMatching, NearestClusterWithinTheRadiusEachClusterOnce) {
  const ReconstructionOptions o;
  auto clusterAt = [](double thetaDeg, double phiDeg) {
    Cluster c;
    c.theta = thetaDeg * deg;
    c.phi = phiDeg * deg;
    c.energy = 500.0;
    return c;
  };
  const std::vector<Cluster> clusters = {clusterAt(90.0, 100.0), clusterAt(90.0, 40.0), clusterAt(90.0, 46.0),
                                         clusterAt(60.0, 250.0)};
  const std::vector<TrackLine> tracks = {
      {0.0, 0.0, 42.0 * deg, 90.0 * deg},   // 2° from cluster 1, 4° from cluster 2
      {0.0, 0.0, 45.0 * deg, 90.0 * deg},   // 1° from cluster 2, 5° from cluster 1
      {0.0, 0.0, 112.0 * deg, 90.0 * deg},  // 12° from cluster 0: inside 15°
      {0.0, 0.0, 250.0 * deg, 80.0 * deg},  // 20° from cluster 3: outside
  };
  EXPECT_THAT(matchTracks(tracks, clusters, o), ::testing::ElementsAre(1, 2, 0, -1));

  // Two tracks, one cluster: the nearer track takes it.
  EXPECT_THAT(matchTracks({tracks[1], tracks[0]}, {clusters[1]}, o), ::testing::ElementsAre(-1, 0));
  // A wider radius reaches cluster 3.
  ReconstructionOptions wide = o;
  wide.matchRadius = 25.0 * deg;
  EXPECT_EQ(matchTracks(tracks, clusters, wide)[3], 3);
  // No clusters: nothing matched.
  EXPECT_THAT(matchTracks(tracks, {}, o), ::testing::Each(-1));
}

TEST(TrackMatching, UsesTheTrackPointOnTheMatchSphere) {
  // z0 = 6 cm at θ = 90°: at 45 cm the track is seen at θ = acos(6/45) = 82.3°, not at 90°.
  const ReconstructionOptions o;
  ASSERT_DOUBLE_EQ(o.matchSphereRadius, 45.0);
  const double seen = std::acos(6.0 / 45.0);
  Cluster atNinety, atSeen;
  atNinety.theta = 89.0 * deg;  // 1° from the direction, 6.7° from the point
  atSeen.theta = seen;
  atNinety.phi = atSeen.phi = 30.0 * deg;
  const std::vector<TrackLine> track = {{6.0, 0.0, 30.0 * deg, 90.0 * deg}};
  EXPECT_THAT(matchTracks(track, {atNinety, atSeen}, o), ::testing::ElementsAre(1));
  // A track that never reaches the sphere (rho > 45 cm) matches nothing.
  const std::vector<TrackLine> far = {{0.0, 50.0, 30.0 * deg, 90.0 * deg}};
  EXPECT_THAT(matchTracks(far, {atNinety, atSeen}, o), ::testing::ElementsAre(-1));
}

}  // namespace
}  // namespace emcalign::sim
