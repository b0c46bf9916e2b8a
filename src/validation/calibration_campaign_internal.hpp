#pragma once
// What the parts of a calibration campaign (validation/calibration_campaign.hpp) share: the
// check that every event is in one file only.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/io/event_numbers.hpp"

namespace emcalign::validation {

// Every event in one file only, as one reader of all the files demands (io/event_file.hpp):
// a copy of a file is named by its digest, another file holding the same events (a corrected
// copy, another version) by the first event the two share.
Status eachEventOnce(const std::vector<std::string>& files, const std::vector<std::string>& digests,
                     const std::vector<std::map<std::int32_t, io::EventNumbers>>& eventsOf);

}  // namespace emcalign::validation
