#pragma once
// A directory whose files a command reads as data: a campaign's event files, a corrections
// grid. One rule for all of them: its hidden files and emcalign's temporaries are not data; an
// entry with a data name that cannot be read (a link to a tape not mounted, a FIFO) is an
// error, never left out silently (its runs would be calibrated without it); and, while the
// command runs, no output creates a new data file there (it would be read next time).

#include <string>
#include <string_view>
#include <vector>

#include "emcalign/core/result.hpp"

namespace emcalign::io {

/// The data files of `dir` (names ending in one of `extensions`), sorted; `what` says what they
/// are in a message ("an event file", "a corrections file"). The directory becomes a protected
/// input directory (io/output_file.hpp) with `option` as its name.
Result<std::vector<std::string>> dataFilesIn(const std::string& dir, const std::vector<std::string>& extensions,
                                             std::string_view what, const std::string& option = {});

}  // namespace emcalign::io
