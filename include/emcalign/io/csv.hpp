#pragma once
// Small strict CSV helpers shared by every CSV reader: splitting a line into fields and
// parsing a number that must be finite and must use the whole field.

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace emcalign::io {

/// Splits on commas (no quoting: emcalign's CSV files hold numbers and plain names), trims
/// spaces and a trailing '\r'.
std::vector<std::string_view> splitCsvLine(std::string_view line);

/// A finite double spelled by the whole field, or none.
std::optional<double> parseFiniteDouble(std::string_view field);

/// A line to skip: empty (after trimming) or a comment starting with '#'.
bool isBlankOrComment(std::string_view line);

/// Text from an input, quoted for a message and cut when long: 'abc', or
/// '0.12345678901234567890…' (10485760 characters) — a message never echoes megabytes. (Not
/// named `quoted`: argument-dependent lookup would pick std::quoted for a std::string wherever
/// <iomanip> is included.)
std::string quotedText(std::string_view text, std::size_t keep = 32);

}  // namespace emcalign::io
