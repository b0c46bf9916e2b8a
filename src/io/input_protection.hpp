#pragma once
// What outputs (output_file.cpp) take from the protected inputs (input_protection.cpp).

#include <string>

#include "emcalign/io/output_file.hpp"

namespace emcalign::io {

/// An input as the messages name it: its option, then its path.
std::string describe(const NamedPath& input);

}  // namespace emcalign::io
