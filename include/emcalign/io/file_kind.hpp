#pragma once
// What a file is, by its content: a reader given a file of another kind names it
// ("ev.h5: this is an HDF5 file (an event file?), not a profile CSV") instead of echoing
// its bytes or listing the columns it expected.

#include <string>
#include <string_view>

namespace emcalign::io {

/// What a text that is not JSON is, by its first bytes: "an HDF5 file (an event file?)", "an
/// SQLite database (a conditions database?)", "a PNG image", "an XML file (GDML placements?)",
/// or one of emcalign's CSV files by its header line (comment lines skipped): "a CSV event
/// file", "a profile CSV (fit --profile-out)", "a conditions export (emcalign conditions
/// export)", "a counters CSV (geometry --counters)". Empty when unknown (and for JSON).
std::string describeNonJson(std::string_view text);

/// As describeNonJson, and a JSON text by its "format": "a parameter file (its format:
/// emcalign-alignment/1)", "a JSON file (its format: other/2)", "a JSON file". Empty when
/// unknown.
std::string describeContent(std::string_view text);

/// describeContent of the file at `path` (its first 64 KiB; a JSON file whole, up to the
/// largest JSON file emcalign reads). Empty when unknown or unreadable: only a message uses it.
std::string describeFileAt(const std::string& path);

/// The kinds describeNonJson gives a CSV event file and a profile (whose readers say what
/// else is wrong with one).
inline constexpr std::string_view kCsvEventFileKind = "a CSV event file";
inline constexpr std::string_view kProfileCsvKind = "a profile CSV (fit --profile-out)";
inline constexpr std::string_view kRandomTriggerCsvKind = "a random-trigger CSV (simulate --process random-trigger)";

}  // namespace emcalign::io
