#pragma once
// The detector simulation: generated e+e- collisions → misaligned detector → reconstructed
// particles in the docs/contract.md §6 record, with truth.
//
// Event i is simulated from its own random stream Rng(seed, i), so the output depends only
// on (options, truth parameters, seed), never on the number of threads or on the order in
// which events are made. `run` makes events in parallel (oneTBB) and hands them to the sink
// in event order.

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/core/event_record.hpp"
#include "emcalign/core/random.hpp"
#include "emcalign/core/random_trigger.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/sim/calorimeter_response.hpp"
#include "emcalign/sim/generators.hpp"
#include "emcalign/sim/reconstruction.hpp"
#include "emcalign/sim/tracking.hpp"

namespace emcalign::sim {

/// Limits of counting arguments: more events than a machine makes in days, more threads
/// than any machine has, are typing mistakes.
inline constexpr std::int64_t kMaxEvents = 10'000'000'000;
inline constexpr int kMaxThreads = 1024;

struct SimulationOptions {
  GeneratorOptions generator;
  TrackingOptions tracking;
  EmcOptions emc;
  ReconstructionOptions reconstruction;
  double cosmicFraction = 0.01;      ///< events replaced by a cosmic muon (assumed)
  double muonVetoEfficiency = 0.99;  ///< for cosmic muons (assumed); collisions never fire it
  std::int32_t run = 1;
  std::uint64_t seed = 1;
  /// Recorded beam background: each event gets one of these random-trigger events merged
  /// into its counters before clustering (CalorimeterResponse::mergeRecorded) instead of the
  /// Poisson model; in an order drawn from the seed (a permutation), reused cyclically when
  /// there are fewer than events. None: the Poisson model (EmcOptions). `--off background`
  /// switches either off.
  std::shared_ptr<const RandomTriggerEvents> recordedBackground;

  /// Switches every realism effect off: no radiation, background, dead counters, noise,
  /// energy smearing, shower fluctuations, layer-3 offset, cosmics, multiple scattering;
  /// point showers at R(E, θ) and cluster directions from the deposit itself, unsmeared (a
  /// smeared direction near x = 0 lands in the other hemisphere's bin, where the model
  /// gives it the wrong sign of the relative terms). In this limit the docs/contract.md §5 model is
  /// exact up to the track resolution.
  void setIdealised();

  /// Switches one realism effect off by its name (docs/simulation.md): radiation,
  /// background, dead-counters, noise, energy-resolution, shower-fluctuations,
  /// layer3-offset, cosmics, multiple-scattering, counter-directions.
  Status switchOff(std::string_view effect);
  static const std::vector<std::string>& effectNames();
  /// `--ideal` (setIdealised) when `ideal`, then every effect of `off` switched off; the
  /// error names an unknown effect (the caller names its option).
  Status applyRealism(bool ideal, const std::vector<std::string>& off);

  Status validate(int counters) const;
};

/// Per-thread working memory of the simulation.
class EventScratch {
 public:
  explicit EventScratch(int counters) : hits(counters) {}
  CounterHits hits;
  ClusterScratch clusters;
  std::vector<Cluster> clusterList;
  std::vector<geometry::TrackLine> tracks;
  std::vector<int> trackSource;
  GeneratedEvent event;
  /// The first event the generator could not make (Collision::made() false), or −1.
  std::int64_t failedEvent = -1;
};

class Simulation {
 public:
  /// The calorimeter must outlive the simulation.
  static Result<Simulation> create(const geometry::Calorimeter& calorimeter, const geometry::AlignmentParameters& truth,
                                   SimulationOptions options);

  [[nodiscard]] const SimulationOptions& options() const { return options_; }
  [[nodiscard]] const geometry::Calorimeter& calorimeter() const { return *calo_; }
  [[nodiscard]] const CalorimeterResponse& response() const { return *response_; }
  [[nodiscard]] const TrackingSystem& tracking() const { return tracking_; }

  /// Appends the reconstructed rows of event `index` (and their truth, and — when `hits` is
  /// given — each cluster row's counters, ParticleRow::hitCount of them). An event the
  /// generator could not make appends nothing and is noted in `scratch.failedEvent`.
  void simulateEvent(std::int64_t index, EventScratch& scratch, std::vector<ParticleRow>& rows,
                     std::vector<TruthRow>& truth, std::vector<Hit>* hits = nullptr) const;

  /// Rows of consecutive events, handed to the sink in event order, with their truth and
  /// their hits (in row order).
  using Sink = std::function<Status(std::span<const ParticleRow>, std::span<const TruthRow>, std::span<const Hit>)>;
  /// Called after each block with the number of events done.
  using Progress = std::function<void(std::int64_t done)>;

  /// Simulates events [0, events) on `threads` threads (0: all cores).
  Status run(std::int64_t events, int threads, const Sink& sink, const Progress& progress = {}) const;

  /// The recorded event that event `index` gets (SimulationOptions::recordedBackground), or
  /// −1 when there is none.
  [[nodiscard]] std::int64_t recordedEventOf(std::int64_t index) const;

  /// What a random trigger records in event `index`: the counters the beam background (the
  /// Poisson model of EmcOptions) and the noise fire above the counter threshold, as `hits`
  /// (cleared first; none is a quiet event). The same Rng(seed, index) stream as events.
  void randomTriggerEvent(std::int64_t index, EventScratch& scratch, std::vector<Hit>& hits) const;
  /// Random-trigger events [0, events) on `threads` threads, run and event numbers of the
  /// options; the same on any thread count.
  [[nodiscard]] Result<RandomTriggerEvents> randomTrigger(std::int64_t events, int threads,
                                                          const Progress& progress = {}) const;

 private:
  Simulation() = default;
  void cosmic(Rng& rng, GeneratedEvent& event) const;

  const geometry::Calorimeter* calo_ = nullptr;
  SimulationOptions options_;
  std::shared_ptr<const CalorimeterResponse> response_;
  std::shared_ptr<const CounterNeighbours> neighbours_;
  std::shared_ptr<const geometry::CounterGeometry> nominal_;  ///< what the reconstruction knows
  TrackingSystem tracking_{TrackingOptions{}};
  std::vector<std::uint32_t> backgroundOrder_;  ///< the recorded events in the order they are used
};

}  // namespace emcalign::sim
