#pragma once
// `emcalign derive-corrections` as its command line gives it, made into the derivation's
// options here, the settings a corrections file records (a rerun into a grid keeps a point
// derived with the same), and its report in words (docs/fit.md, "Deriving the corrections").

#include <cstdint>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/derive_corrections.hpp"

namespace emcalign::validation {

/// A derivation as given. The defaults are the library's (DerivationOptions), but for the
/// polar range: the generator's covers the whole calorimeter, the derivation samples only the
/// profiles'.
struct DerivationGiven {
  std::int64_t events = DerivationOptions{}.events;
  std::uint64_t seed = DerivationOptions{}.seed;
  int threads = DerivationOptions{}.threads;
  std::vector<double> beamEnergiesMev = {};  ///< several: a grid; none: the simulation's default
  double thetaMinDeg = 40.0, thetaMaxDeg = 140.0;
  double shiftCm = DerivationOptions{}.shift / units::cm;
  double gapCm = DerivationOptions{}.gap / units::cm;
  int responseSamples = DerivationOptions{}.responseSamples;
  std::int64_t responseEvents = DerivationOptions{}.responseEvents;
  bool ideal = false;
  std::vector<std::string> off = {};
  std::string detector = {};
};

/// The derivation of `given`: its options, and its beam energies sorted (a grid when more than
/// one); an energy given twice, or a polar range upside down, is refused naming the option.
struct Derivation {
  DerivationOptions options;
  std::vector<double> energies;  ///< MeV·units, sorted
  [[nodiscard]] bool grid() const { return energies.size() > 1; }
};
Result<Derivation> derivationOf(const DerivationGiven& given);

/// What a corrections file records under derived_from.settings for the point at `beamEnergy`.
io::Json derivationSettings(const DerivationGiven& given, double beamEnergy);
/// The settings of each point, in their order.
std::vector<io::Json> derivationSettings(const DerivationGiven& given, const std::vector<GridPoint>& points);
/// The files a derivation reads (the detector description), absolute: for its tasks' logs.
std::vector<std::string> derivationInputs(const DerivationGiven& given);

/// The derivation's report: the selected events, the depth offset, the parting-plane response
/// per φ column, the fit's response and the statistical errors the file gives, the closure.
std::string derivationReportText(const DerivationReport& report);

/// What `derive-corrections` says at its end: a grid's energies and the points `derived` in
/// `seconds` (`grid`), or how to use the one file `output`.
std::string derivationDoneText(const std::string& output, const std::vector<double>& energies, bool grid,
                               std::size_t derived, double seconds);

}  // namespace emcalign::validation
