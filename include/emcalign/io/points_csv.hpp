#pragma once
// A CSV of points, as `emcalign transform` and `geometry --where` read them on standard input
// (docs/conventions.md): the header x_cm,y_cm,z_cm, then one point per row; blank and `#`
// lines skipped.

#include <istream>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/core/types.hpp"

namespace emcalign::io {

/// At most this many points (all are read before any is used: an endless input is refused
/// before it takes the memory) and this many bytes on a line.
inline constexpr std::size_t kMaxPoints = 1'000'000;
inline constexpr std::size_t kMaxPointLine = std::size_t{1} << 20;

/// The points of `in`, in native units (cm → cm); `name` ("stdin") names the input in errors,
/// with the line and the column.
Result<std::vector<Vec3>> readPointsCsv(std::istream& in, const std::string& name);

}  // namespace emcalign::io
