#pragma once
// JSON files of emcalign: the detector description and the alignment-parameter file
// (docs/contract.md §3). Readers are strict: unknown keys, duplicate keys, missing parameters, wrong
// types and non-finite numbers are errors whose message names the file and the key.
// Values are converted from file units (deg, cm) to native units (rad, cm) here, and only
// here.
//
// Alignment file (read and written by every command):
//   {"format": "emcalign-alignment/1", "units": {"angle": "deg", "length": "cm"},
//    "parameters": {"alpha": …, "beta1": …, …, "beta_rel": …}}
// An input may give "physical" {alpha, beta, psi, dx, dy, dz, mu, tau, dx_rel, dy_rel,
// dz_rel, beta_rel} instead of "parameters"; when a file gives both (as `params show --json`
// writes), they must agree. A fit result adds errors, covariance, … (docs/contract.md §3): those keys
// are accepted and ignored by the parameter reader.
//
// Detector description: see docs/conventions.md; every key but "format" is optional and
// defaults to the SND-like description of docs/contract.md §2.

#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "emcalign/core/fit_status.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::io {

/// JSON with keys kept in insertion order, so files list parameters in the contract's order.
using Json = nlohmann::ordered_json;

inline constexpr std::string_view kAlignmentFormat = "emcalign-alignment/1";
inline constexpr std::string_view kDetectorFormat = "emcalign-detector/1";

/// The largest JSON file (and whole text file) emcalign reads.
inline constexpr std::size_t kMaxInputFileBytes = std::size_t{64} << 20;

/// Parses JSON text, rejecting duplicate keys, nesting deeper than 64 levels and texts
/// above 64 MiB; `source` names the input in messages.
Result<Json> parseJson(std::string_view text, std::string_view source);
/// The string at `key` of a JSON object (none: not an object, no such key, or not a string):
/// how a reader tells what a document is before reading it, and how lenient readers read.
inline std::optional<std::string> stringAt(const Json& j, std::string_view key) {
  if (!j.is_object()) return std::nullopt;
  const auto it = j.find(key);
  if (it == j.end() || !it->is_string()) return std::nullopt;
  return it->get<std::string>();
}
/// A document's "format" ("" when it has none).
inline std::string formatOf(const Json& j) { return stringAt(j, "format").value_or(""); }

/// What an emcalign JSON file is, by its "format": "a fit result", "a corrections file
/// (derive-corrections)", …; empty when it has no emcalign format.
std::string describeFile(const Json& j);
/// Fails, naming what the file is, when `j` is an emcalign file of another format than
/// `format` ("c.json: this is a fit result (format …), not a corrections file"). A file
/// without an emcalign format passes: the reader's own checks name what is wrong.
Status expectFormat(const Json& j, std::string_view format, std::string_view expected, std::string_view source);

/// An integer of a JSON document within [lo, hi] (never wrapped or truncated: 1e10, 2^32 + 16,
/// 16.0 and "16" are errors naming the source and the key).
Result<std::int64_t> integerIn(const Json& value, std::int64_t lo, std::int64_t hi, std::string_view source,
                               std::string_view key);

/// A number, or null when it is not finite (JSON has no NaN or infinity).
inline Json numberOrNull(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

/// Reads a whole regular file of at most `maxBytes` (a FIFO, a device or a larger file is
/// refused: core/regular_file.hpp); the error names the path and the system's reason. The
/// file becomes a protected input of the command (io/output_file.hpp).
Result<std::string> readTextFile(const std::string& path, std::size_t maxBytes = kMaxInputFileBytes);
/// Reads a file the running command wrote on an earlier run and may write again (the state of
/// a resumed job, its finished parts): as readTextFile, but it does not become a protected input.
Result<std::string> readOwnOutput(const std::string& path, std::size_t maxBytes = kMaxInputFileBytes);

Result<geometry::DetectorDescription> parseDetectorDescription(const Json& j, std::string_view source);
Result<geometry::DetectorDescription> readDetectorDescription(const std::string& path);
/// The calorimeter of a description file (`--detector FILE`), or the embedded SND-like one
/// when the path is empty; a description the calorimeter refuses is named by its path.
Result<geometry::Calorimeter> loadCalorimeter(const std::string& path);
/// How files and settings name the detector: a description's path, or this for the embedded one.
inline constexpr std::string_view kEmbeddedDetector = "embedded default";
/// The name recorded for `path` (empty: the embedded detector), and the path of a recorded name.
inline std::string detectorName(const std::string& path) {
  return path.empty() ? std::string(kEmbeddedDetector) : path;
}
inline std::string detectorPath(const std::string& name) { return name == kEmbeddedDetector ? std::string() : name; }
Json toJson(const geometry::DetectorDescription& d);

/// How strictly an alignment is read.
enum class AlignmentUse {
  /// A file a user gives a command: a fit result must be usable (status "converged", or
  /// "poor fit" with a warning; "not converged" and "covariance singular" are refused), and
  /// the values plausible (geometry::checkPlausible).
  Input,
  /// emcalign's own records read back (a campaign's samples): any rigid placement, any status.
  Record,
};

struct AlignmentFile {
  geometry::AlignmentParameters parameters;
  std::optional<FitStatus> status;    ///< when the file is a fit result
  std::vector<std::string> warnings;  ///< negative gaps, a poor fit: for the caller to print
};

/// Reads the fit set from an alignment file's JSON (either form). `r1` converts physical
/// input to gaps.
Result<AlignmentFile> parseAlignmentFile(const Json& j, double r1, std::string_view source,
                                         AlignmentUse use = AlignmentUse::Input);
Result<AlignmentFile> readAlignmentFile(const std::string& path, double r1);
/// The same, parameters only (the warnings dropped).
Result<geometry::AlignmentParameters> parseAlignment(const Json& j, double r1, std::string_view source,
                                                     AlignmentUse use = AlignmentUse::Input);
Result<geometry::AlignmentParameters> readAlignment(const std::string& path, double r1);

/// {"format", "units", "parameters"} in file units.
Json alignmentToJson(const geometry::AlignmentParameters& eta);
/// The same plus "physical" (fails when η is not a rigid placement).
Result<Json> alignmentToJsonWithPhysical(const geometry::AlignmentParameters& eta, double r1);

}  // namespace emcalign::io
