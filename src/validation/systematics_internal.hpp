#pragma once
// The part of a systematic study (validation/systematics.hpp) in a file of its own.

#include <string>

#include "emcalign/core/result.hpp"
#include "emcalign/validation/systematics.hpp"

namespace emcalign::validation {

/// DIR/systematics.json, DIR/systematics.md and the figure (systematics_output.cpp).
Status writeSystematics(const SystematicsTable& t, const std::string& dir);

}  // namespace emcalign::validation
