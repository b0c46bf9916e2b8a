#pragma once
// Where a path lies, for the checks that keep outputs off inputs and plans off their data.

#include <string>

namespace emcalign::io {

/// Whether `path` is `dir` or lies inside it: both made absolute and normal, links resolved as
/// far as the paths exist ("d/" and "d" are one directory). False when either cannot be resolved.
bool isWithin(const std::string& path, const std::string& dir);

}  // namespace emcalign::io
