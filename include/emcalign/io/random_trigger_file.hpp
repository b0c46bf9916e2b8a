#pragma once
// Random-trigger files: recorded beam background for the simulation (core/random_trigger.hpp),
// written by `emcalign simulate --process random-trigger` and converted by users from their
// experiment's random-trigger runs (docs/simulation.md, "Recorded beam background"). The
// format is chosen by the name, as for event files: ".csv" (and "-", standard output) is CSV,
// anything else HDF5.
//
// HDF5 (root attribute "format" = "emcalign-random-trigger/1", a variable-length string;
// other string attributes are kept as metadata; datasets 1-D, any layout and filter HDF5 reads):
//   /random_trigger/run int32, event int64, hit_offset int64, hit_count int32   one per event
//   /hits/counter int32, energy_mev double                                       flat, event order
// Event i's hits are /hits[hit_offset[i], hit_offset[i] + hit_count[i]): the offsets follow
// each other from 0 without holes, to the length of /hits. An event may have no hit.
//
// CSV (the header line `run,event,counter,energy_mev`, '#' lines are comments; the first
// '# format: emcalign-random-trigger/1' is written, not required):
//   one row per hit; an event without hits is one row with counter and energy empty
//   ("7,12,,"); the rows of an event are contiguous.
//
// What every file must satisfy (the reader refuses it naming the file, the event and the
// field): an event (run, event) appears once; a counter is in [0, counters) of the detector
// and appears at most once in an event; an energy is in [0, kMaxRandomTriggerEnergyMev]; at most
// kMaxRandomTriggerEvents events and kMaxRandomTriggerHits hits (the whole file is held in memory). HDF5 is read in a
// child process as event files are (io/event_file.hpp).

#include <string>
#include <utility>
#include <vector>

#include "emcalign/core/random_trigger.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::io {

inline constexpr const char* kRandomTriggerFormat = "emcalign-random-trigger/1";
inline constexpr const char* kRandomTriggerCsvHeader = "run,event,counter,energy_mev";

/// Writes `events` to `path` (io/output_file.hpp: a temporary renamed into place, nothing
/// left on failure); `attributes` (key, value) are stored beside "format" (HDF5 attributes,
/// CSV '# key: value' lines; values without line breaks).
Status writeRandomTriggerFile(const std::string& path, const RandomTriggerEvents& events,
                              const std::vector<std::pair<std::string, std::string>>& attributes = {},
                              Placement placement = Placement::Named);

/// Reads a whole random-trigger file for a detector of `counters` counters, checked by the
/// rules above.
Result<RandomTriggerEvents> readRandomTriggerFile(const std::string& path, int counters,
                                                  double hdf5TimeoutSeconds = 60.0);

}  // namespace emcalign::io
