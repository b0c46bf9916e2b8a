#pragma once
// JSON files of emcalign: the detector description and the alignment-parameter file
// (SPEC §3). Readers are strict: unknown keys, duplicate keys, missing parameters, wrong
// types and non-finite numbers are errors whose message names the file and the key.
// Values are converted from file units (deg, cm) to native units (rad, cm) here, and only
// here.
//
// Alignment file (read and written by every command):
//   {"format": "emcalign-alignment/1", "units": {"angle": "deg", "length": "cm"},
//    "parameters": {"alpha": …, "beta1": …, …, "beta_rel": …}}
// An input may give "physical" {alpha, beta, psi, dx, dy, dz, mu, tau, dx_rel, dy_rel,
// dz_rel, beta_rel} instead of "parameters"; when a file gives both (as `params show --json`
// writes), they must agree. A fit result adds errors, covariance, … (SPEC §3): those keys
// are accepted and ignored by the parameter reader.
//
// Detector description: see docs/conventions.md; every key but "format" is optional and
// defaults to the SND-like description of SPEC §2.

#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/detector.hpp"

namespace emcalign::io {

/// JSON with keys kept in insertion order, so files list parameters in SPEC order.
using Json = nlohmann::ordered_json;

inline constexpr std::string_view kAlignmentFormat = "emcalign-alignment/1";
inline constexpr std::string_view kDetectorFormat = "emcalign-detector/1";

/// Parses JSON text, rejecting duplicate keys; `source` names the input in messages.
Result<Json> parseJson(std::string_view text, std::string_view source);

/// Reads a whole file; the error names the path and the system's reason.
Result<std::string> readTextFile(const std::string& path);

/// Writes a file through a temporary in the same directory and a rename, so that a reader
/// (or a crash) never sees half a file.
Status writeTextFileAtomically(const std::string& path, std::string_view content);

Result<geometry::DetectorDescription> parseDetectorDescription(const Json& j,
                                                               std::string_view source);
Result<geometry::DetectorDescription> readDetectorDescription(const std::string& path);
Json toJson(const geometry::DetectorDescription& d);

/// Reads the fit set from an alignment file's JSON (either form). `r1` converts physical
/// input to gaps.
Result<geometry::AlignmentParameters> parseAlignment(const Json& j, double r1,
                                                     std::string_view source);
Result<geometry::AlignmentParameters> readAlignment(const std::string& path, double r1);

/// {"format", "units", "parameters"} in file units.
Json alignmentToJson(const geometry::AlignmentParameters& eta);
/// The same plus "physical" (fails when η is not a rigid placement).
Result<Json> alignmentToJsonWithPhysical(const geometry::AlignmentParameters& eta,
                                                   double r1);

}  // namespace emcalign::io
