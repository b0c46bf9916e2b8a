#pragma once
// Event reconstruction as SND does it, on the simulated counter energies:
// * clusters = connected groups of fired counters (neighbours in θ, φ and depth);
// * energy = sum of the counters divided by the mean containment (a leakage correction);
// * direction = angles of the log-weighted mean of the counter centres,
//   w_i = max(0, W0 + ln(E_i/E)), seen from the origin (`clusterDirection`). The simulation
//   reconstructs with the *nominal* centres (it does not know the misalignment); building
//   the direction from counter centres is what makes the reconstructed angle non-uniform
//   inside a counter (the paper's σ_sys). `emcalign correct --method hits` calls the same
//   function with the *aligned* centres (geometry/counter_geometry.hpp): with a zero
//   alignment it gives the simulation's direction to the last bit.
// * tracks and clusters are matched by angle; clusters left over are photons.

#include <optional>
#include <span>
#include <utility>
#include <vector>

#include "emcalign/core/event_record.hpp"
#include "emcalign/core/types.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/counter_geometry.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/geometry/track.hpp"
#include "emcalign/sim/calorimeter_response.hpp"

namespace emcalign::sim {

struct ReconstructionOptions {
  double clusterThreshold = 10.0;          ///< MeV: lighter clusters are dropped (assumed)
  double logWeightW0 = 3.5;                ///< W0 of the logarithmic weights (tuned: σ_θ ≈ 1.5°)
  double containment = 0.958;              ///< median E_sum/E of 600 MeV e± and γ (measured, docs/simulation.md)
  double matchRadius = 15.0 * units::deg;  ///< rad, track–cluster angle
  double matchSphereRadius = 45.0;         ///< cm, where the track direction is taken for matching
  bool directionFromCounters = true;       ///< false: the exact nominal-frame direction of the
                                           ///< deposited energy, smeared (the idealised limit)
  double idealDirectionSigma = 1.5 * units::deg;  ///< rad, smearing per angle then
  Status validate() const;
};

struct Cluster {
  double energy = 0.0;  ///< MeV, leakage-corrected
  double theta = 0.0;   ///< rad, nominal EMC frame
  double phi = 0.0;     ///< rad
  int mainSource = -1;  ///< source (generated particle or background) with most energy
  int counters = 0;
  int firstHit = 0;  ///< its counters: ClusterScratch::hits[firstHit, firstHit + counters)
};

/// The direction (θ, φ) of a cluster from its counters (index, energy), in their order:
/// the angles of Σ w_i·c_i with w_i = max(0, W0 + ln(E_i/E)), E = Σ E_i, c_i the counter
/// centres of `geometry` (nominal or aligned). None when no weight is positive.
std::optional<std::pair<double, double>> clusterDirection(std::span<const Hit> hits,
                                                          const geometry::CounterGeometry& geometry, double w0);

/// Neighbours of every counter, computed once per calorimeter.
class CounterNeighbours {
 public:
  explicit CounterNeighbours(const geometry::Calorimeter& calo);
  [[nodiscard]] std::span<const int> of(int counter) const {
    const auto c = static_cast<std::size_t>(counter);
    return {all_.data() + first_[c], all_.data() + first_[c + 1]};
  }

 private:
  // Every counter's neighbours one after the other (counter c's are all_[first_[c],
  // first_[c + 1])): the clustering walks them for every fired counter.
  std::vector<int> all_;
  std::vector<std::size_t> first_;
};

/// Scratch space of the clustering, reused across events.
struct ClusterScratch {
  std::vector<int> label;  ///< per counter: cluster id, -1 unassigned (reset after use)
  std::vector<int> stack;
  std::vector<int> members;
  std::vector<Hit> hits;  ///< the counters of the clusters found, cluster by cluster
};

/// Clusters of the fired counters, directions from the centres of `geometry` (the nominal
/// one in the simulation); each keeps its counters in `scratch.hits` (`rng` smears the
/// idealised directions only).
void findClusters(const CounterHits& hits, const geometry::CounterGeometry& geometry,
                  const CounterNeighbours& neighbours, const ReconstructionOptions& options, ClusterScratch& scratch,
                  Rng& rng, std::vector<Cluster>& clusters);

/// Matches tracks to clusters by the smallest angle within the match radius; returns, for
/// each track, the index of its cluster or -1.
std::vector<int> matchTracks(const std::vector<geometry::TrackLine>& tracks, const std::vector<Cluster>& clusters,
                             const ReconstructionOptions& options);

}  // namespace emcalign::sim
