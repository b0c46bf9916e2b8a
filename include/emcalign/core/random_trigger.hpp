#pragma once
// Events of the random trigger: what the calorimeter's counters read when no collision was
// asked for (beam background and noise above the readout threshold). The simulation merges
// one of them into each simulated event instead of its Poisson model of the background
// (sim/simulation.hpp); the files are io/random_trigger_file.hpp's.

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "emcalign/core/event_record.hpp"

namespace emcalign {

/// The most events and hits a set of random-trigger events holds (it is held in memory whole).
inline constexpr std::size_t kMaxRandomTriggerEvents = 10'000'000;
inline constexpr std::size_t kMaxRandomTriggerHits = 40'000'000;
/// The largest energy one counter of a random trigger may read, MeV (twice the largest beam
/// energy: beyond, a unit mistake, which would overflow the clustering's sums).
inline constexpr double kMaxRandomTriggerEnergyMev = 10'000.0;

/// Recorded events in order, each with its run and event number and its fired counters
/// (an event may have none: a quiet trigger is an event too).
class RandomTriggerEvents {
 public:
  [[nodiscard]] std::size_t size() const { return run_.size(); }
  [[nodiscard]] bool empty() const { return run_.empty(); }
  [[nodiscard]] std::int32_t run(std::size_t i) const { return run_[i]; }
  [[nodiscard]] std::int64_t event(std::size_t i) const { return event_[i]; }
  /// The counters of event i, with the energies they read (MeV).
  [[nodiscard]] std::span<const Hit> hits(std::size_t i) const {
    return std::span<const Hit>(hits_).subspan(static_cast<std::size_t>(first_[i]),
                                               static_cast<std::size_t>(first_[i + 1] - first_[i]));
  }
  /// Every hit of every event, in event order.
  [[nodiscard]] std::span<const Hit> allHits() const { return hits_; }

  void append(std::int32_t run, std::int64_t event, std::span<const Hit> hits) {
    run_.push_back(run);
    event_.push_back(event);
    hits_.insert(hits_.end(), hits.begin(), hits.end());
    first_.push_back(static_cast<std::int64_t>(hits_.size()));
  }
  void reserve(std::size_t events, std::size_t hits) {
    run_.reserve(events);
    event_.reserve(events);
    first_.reserve(events + 1);
    hits_.reserve(hits);
  }

 private:
  std::vector<std::int32_t> run_;
  std::vector<std::int64_t> event_;
  std::vector<std::int64_t> first_ = {0};  ///< event i's hits are [first_[i], first_[i + 1])
  std::vector<Hit> hits_;
};

}  // namespace emcalign
