#include "emcalign/sim/reconstruction.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <tuple>

namespace emcalign::sim {

Status ReconstructionOptions::validate() const {
  if (!(clusterThreshold >= 0.0) || !(logWeightW0 > 0.0) || !(containment > 0.0 && containment <= 1.5) ||
      !(matchRadius > 0.0) || !(matchSphereRadius > 0.0)) {
    return Error{"reconstruction: thresholds, W0, containment and matching must be positive"};
  }
  return {};
}

CounterNeighbours::CounterNeighbours(const geometry::Calorimeter& calo) {
  // Two counters are neighbours when their layers, rings differ by at most one and their
  // φ ranges overlap or touch (9° and 22.5° cells meet at 36° and 144°).
  constexpr double kTol = 1e-9;
  const double twoPi = 2.0 * std::numbers::pi;
  auto touches = [&](const geometry::Counter& a, const geometry::Counter& b) {
    for (double shift : {-twoPi, 0.0, twoPi}) {
      if (a.phiMin <= b.phiMax + shift + kTol && b.phiMin + shift <= a.phiMax + kTol) return true;
    }
    return false;
  };
  const int rings = calo.description().ringCount();
  const auto counters = calo.counters();
  std::vector<int> candidates;
  first_.push_back(0);
  for (const auto& a : counters) {
    for (int layer = std::max(1, a.layer - 1); layer <= std::min(3, a.layer + 1); ++layer) {
      for (int ring = std::max(0, a.ring - 1); ring <= std::min(rings - 1, a.ring + 1); ++ring) {
        const int first = calo.counterIndex(layer, ring, 0);
        const int n = calo.description().countersPerRing[static_cast<std::size_t>(ring)];
        // Only the cells of this ring around a's φ range can touch it (one cell of margin
        // each side), taken in index order as a scan of the whole ring would find them.
        const double width = twoPi / n;
        const int lo = static_cast<int>(std::floor(a.phiMin / width)) - 1;
        const int hi = static_cast<int>(std::floor(a.phiMax / width)) + 1;
        candidates.clear();
        if (hi - lo + 1 >= n) {
          for (int i = 0; i < n; ++i) candidates.push_back(i);
        } else {
          for (int i = lo; i <= hi; ++i) candidates.push_back(((i % n) + n) % n);
          std::sort(candidates.begin(), candidates.end());
        }
        for (int iphi : candidates) {
          const auto& b = counters[static_cast<std::size_t>(first + iphi)];
          if (a.index != b.index && touches(a, b)) all_.push_back(b.index);
        }
      }
    }
    first_.push_back(all_.size());
  }
}

std::optional<std::pair<double, double>> clusterDirection(std::span<const Hit> hits,
                                                          const geometry::CounterGeometry& geometry, double w0) {
  double sum = 0.0;
  for (const Hit& h : hits) sum += h.energy;
  Vec3 centre = Vec3::Zero();
  double weights = 0.0;
  // A counter below e^(−w0) of the sum has weight 0: no logarithm taken for it.
  const double least = sum * std::exp(-w0);
  for (const Hit& h : hits) {
    if (!(h.energy > least)) continue;
    const double w = std::max(0.0, w0 + std::log(std::max(h.energy, 1e-9) / sum));
    centre += w * geometry.centre(h.counter);
    weights += w;
  }
  if (!(weights > 0.0)) return std::nullopt;
  return std::pair{geometry::polar(centre), geometry::azimuth(centre)};
}

void findClusters(const CounterHits& hits, const geometry::CounterGeometry& geometry,
                  const CounterNeighbours& neighbours, const ReconstructionOptions& options, ClusterScratch& scratch,
                  Rng& rng, std::vector<Cluster>& clusters) {
  const geometry::Calorimeter& calo = geometry.calorimeter();
  clusters.clear();
  scratch.hits.clear();
  if (scratch.label.size() != static_cast<std::size_t>(calo.size())) {
    scratch.label.assign(static_cast<std::size_t>(calo.size()), -1);
  }
  // Only fired counters may join: mark them, then flood-fill.
  constexpr int kFired = -2;
  for (int c : hits.fired()) scratch.label[static_cast<std::size_t>(c)] = kFired;
  std::vector<int>& members = scratch.members;
  int* const label = scratch.label.data();  // not resized below: kept out of the pushes' aliasing
  for (int seed : hits.fired()) {
    if (label[seed] != kFired) continue;
    members.clear();
    scratch.stack.assign(1, seed);
    label[seed] = 0;
    while (!scratch.stack.empty()) {
      const int c = scratch.stack.back();
      scratch.stack.pop_back();
      members.push_back(c);
      for (int n : neighbours.of(c)) {
        if (label[n] == kFired) {
          label[n] = 0;
          scratch.stack.push_back(n);
        }
      }
    }
    double sum = 0.0;
    std::array<double, CounterHits::kMaxSources> bySource{};
    for (int c : members) {
      sum += hits.energy(c);
      const auto& contrib = hits.contributions(c);
      for (std::size_t k = 0; k < bySource.size(); ++k) bySource[k] += contrib[k];
    }
    if (sum <= 0.0 || sum / options.containment < options.clusterThreshold) continue;
    Cluster cl;
    cl.energy = sum / options.containment;
    cl.firstHit = static_cast<int>(scratch.hits.size());
    for (int c : members) scratch.hits.push_back({c, hits.energy(c)});
    const std::span<const Hit> own(scratch.hits.data() + cl.firstHit, members.size());
    if (options.directionFromCounters) {
      const auto direction = clusterDirection(own, geometry, options.logWeightW0);
      if (!direction) {
        scratch.hits.resize(static_cast<std::size_t>(cl.firstHit));
        continue;
      }
      std::tie(cl.theta, cl.phi) = *direction;
    } else {
      Vec3 centre = Vec3::Zero();
      for (int c : members) centre += hits.nominalMoment(c);
      cl.theta =
          std::clamp(geometry::polar(centre) + options.idealDirectionSigma * rng.normal(), 0.0, std::numbers::pi);
      cl.phi =
          std::fmod(geometry::azimuth(centre) + options.idealDirectionSigma * rng.normal() + 2.0 * std::numbers::pi,
                    2.0 * std::numbers::pi);
    }
    cl.mainSource = static_cast<int>(std::max_element(bySource.begin(), bySource.end()) - bySource.begin());
    cl.counters = static_cast<int>(members.size());
    clusters.push_back(cl);
  }
  for (int c : hits.fired()) scratch.label[static_cast<std::size_t>(c)] = -1;
}

std::vector<int> matchTracks(const std::vector<geometry::TrackLine>& tracks, const std::vector<Cluster>& clusters,
                             const ReconstructionOptions& options) {
  struct Pair {
    double angle;
    int track, cluster;
  };
  std::vector<Pair> pairs;
  std::vector<Vec3> directions;
  directions.reserve(clusters.size());
  for (const Cluster& c : clusters) directions.push_back(geometry::pointAt(1.0, c.theta, c.phi));
  // Pairs clearly wider than the match radius are passed over by their cosine, before the
  // accurate angle is taken (the margin keeps every pair the angle would accept).
  const double widest = options.matchRadius < 3.0 ? std::cos(options.matchRadius) - 1e-9 : -2.0;
  for (std::size_t t = 0; t < tracks.size(); ++t) {
    const auto p = tracks[t].sphereIntersection(options.matchSphereRadius);
    if (!p) continue;
    const Vec3 u = p->normalized();
    for (std::size_t c = 0; c < clusters.size(); ++c) {
      const Vec3& v = directions[c];
      if (u.dot(v) < widest) continue;
      const double angle = std::atan2(u.cross(v).norm(), u.dot(v));
      if (angle < options.matchRadius) pairs.push_back({angle, static_cast<int>(t), static_cast<int>(c)});
    }
  }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
    return a.angle != b.angle ? a.angle < b.angle : (a.track != b.track ? a.track < b.track : a.cluster < b.cluster);
  });
  std::vector<int> match(tracks.size(), -1);
  std::vector<char> used(clusters.size(), 0);
  for (const auto& p : pairs) {
    if (match[static_cast<std::size_t>(p.track)] >= 0 || used[static_cast<std::size_t>(p.cluster)]) continue;
    match[static_cast<std::size_t>(p.track)] = p.cluster;
    used[static_cast<std::size_t>(p.cluster)] = 1;
  }
  return match;
}

}  // namespace emcalign::sim
