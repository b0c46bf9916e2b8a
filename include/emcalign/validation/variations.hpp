#pragma once
// Plausible variations of the simulation, for the systematic uncertainty of what was derived
// from it (docs/systematics.md, issue 18).
//
// The model corrections (calib/corrections.hpp) are measured in this simulation; on SND data
// the shower depth, the lateral profile, the counters' response, the dead channels, the
// background and the tracker differ from it by amounts nobody knows exactly. Each variation
// below changes one of them by about its uncertainty (each says why that much), in both
// directions where both are plausible; a campaign simulated with it and fitted with the
// shipped corrections (`emcalign validate --variation NAME`) shows how far each parameter's
// bias moves. Variations of one quantity form a pair; its shift is the larger of the two.
// The counter gains and the extra dead counters are patterns, drawn anew in every sample.
//
// A variation changes the simulation only: the fit keeps the detector's description (its
// R(E, θ), its x_pre), as a fit of data would.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/sim/simulation.hpp"

namespace emcalign::validation {

struct Variation {
  std::string name;      ///< e.g. "tmax-up": what --variation takes
  std::string quantity;  ///< the quantity it varies, shared by a pair (e.g. "t_max")
  std::string change;    ///< what it sets, e.g. "t_max + 0.5 X0"
  std::string why;       ///< why that much
  void (*apply)(sim::SimulationOptions&) = nullptr;
  /// For a variation that is one draw of a pattern (counter gains, dead counters): draws the
  /// pattern of one sample from its seed, the detector having `counters` counters. A study
  /// then averages over patterns, and the pattern's effect on data — one draw of unknown
  /// sign — is the root mean square of the samples' shifts. None: the same change everywhere.
  void (*pattern)(sim::SimulationOptions&, std::uint64_t seed, int counters) = nullptr;
};

/// Every variation, in the order of docs/systematics.md.
const std::vector<Variation>& variations();
/// Their names, in that order (what --variation takes).
std::vector<std::string> variationNames();
/// The variation of that name, or nullptr.
const Variation* findVariation(std::string_view name);

}  // namespace emcalign::validation
