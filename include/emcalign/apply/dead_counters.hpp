#pragma once
// Dead counters from data: the counters that never fire in a sample while their neighbours
// do, for the simulation to mask the same ones (`emcalign dead-counters`, `simulate
// --dead-counters @FILE`).
//
// A counter's occupancy is the number of times it appears among the counters of a cluster
// (the hits of the event files). What it would have without failing is estimated from its
// neighbours in the same layer (the clustering's neighbours, sim/reconstruction.hpp): their
// mean occupancy μ. A counter with no hit is
//   - dead when μ ≥ minExpected (default 15: a live counter shows no hit with probability
//     e^−15 = 3e-7, so among 1632 counters one is wrongly called dead once in ~2000 samples);
//   - undecided when μ is smaller (the edge of the acceptance, a small sample): listed apart,
//     never called dead.

#include <cstdint>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/geometry/detector.hpp"

namespace emcalign::apply {

struct CounterOccupancy {
  std::vector<std::int64_t> hits;  ///< per counter
  std::int64_t events = 0;         ///< events read
  std::int64_t clusterRows = 0;    ///< rows with a cluster (and their hits)
};

/// The occupancy of every counter of `calo` in the event files `paths`, which must have hits;
/// a hit outside the detector is an error naming the file.
Result<CounterOccupancy> countCounterHits(const std::vector<std::string>& paths, const geometry::Calorimeter& calo);

struct DeadCounterOptions {
  double minExpected = 15.0;  ///< μ a counter without hits needs to be called dead
};

struct DeadCounters {
  std::vector<int> dead;         ///< never fired, μ ≥ minExpected
  std::vector<int> undecided;    ///< never fired, μ below it
  std::vector<double> expected;  ///< μ per counter
  double medianOccupancy = 0.0;  ///< of the counters that fired
};

DeadCounters findDeadCounters(const CounterOccupancy& occupancy, const geometry::Calorimeter& calo,
                              const DeadCounterOptions& options = {});

/// The file `dead-counters -o` writes: comment lines (what it was found from, the rule, the
/// undecided counters), then the dead counters, comma-separated, on one line (none: an empty
/// line). `sources` names the inputs.
std::string deadCountersText(const DeadCounters& found, const CounterOccupancy& occupancy,
                             const DeadCounterOptions& options, const std::string& sources);

/// The counters of a dead-counter list: comma-, space- or newline-separated indices, '#'
/// comment lines and the rest of a line after '#' skipped (what deadCountersText writes, or a
/// hand-written list), in ascending order, each once. `source` names the input in messages.
Result<std::vector<int>> parseCounterList(const std::string& text, const std::string& source);

/// The inputs as deadCountersText names them: the one file, or "FIRST and N more".
std::string deadCounterSources(const std::vector<std::string>& files);
/// The line `dead-counters` prints: the events read, the dead counters (or none), those never
/// fired where too few hits are expected to tell, and `output`, where the list went.
std::string deadCountersSummary(const DeadCounters& found, const CounterOccupancy& occupancy,
                                const std::string& output);

}  // namespace emcalign::apply
