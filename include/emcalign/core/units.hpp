#pragma once
// Native units of emcalign: centimetre, MeV, radian (docs/contract.md §1).
//
// Every quantity inside the library is in these units. A value read from or written to a
// human-facing place (parameter files, tables, CSV in degrees) is converted exactly once,
// at that boundary, by multiplying or dividing by one of these constants. A variable that
// holds anything else says so in its name (`alphaDeg`).

#include <numbers>

namespace emcalign::units {

inline constexpr double cm = 1.0;
inline constexpr double mm = 0.1 * cm;
inline constexpr double m = 100.0 * cm;

inline constexpr double MeV = 1.0;
inline constexpr double GeV = 1000.0 * MeV;

inline constexpr double rad = 1.0;
inline constexpr double deg = std::numbers::pi / 180.0 * rad;

}  // namespace emcalign::units
