#pragma once
// Small strict CSV helpers shared by every CSV reader: splitting a line into fields and
// parsing a number that must be finite and must use the whole field.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/core/result.hpp"

namespace emcalign::io {

/// Splits on commas (no quoting: emcalign's CSV files hold numbers and plain names), trims
/// spaces and a trailing '\r'.
std::vector<std::string_view> splitCsvLine(std::string_view line);

/// A finite double spelled by the whole field, or none.
std::optional<double> parseFiniteDouble(std::string_view field);

/// The strict reading of an option's value (checked on the text, before it is converted):
/// the whole text spells one number ("nan", "inf", "1e3x", "-1" for an unsigned are refused)
/// inside [lo, hi]; the error says why, the text quoted ("'7' is outside [0, 5]").
Result<double> parseFiniteIn(std::string_view text, double lo, double hi);
/// An integer, an optional '+' or '-' before its digits.
Result<std::int64_t> parseIntegerIn(std::string_view text, std::int64_t lo, std::int64_t hi);
/// 0 to 2^64 − 1, no sign (a seed).
Result<std::uint64_t> parseUnsigned64(std::string_view text);
/// A decimal integer as typed, its leading zeros dropped: "010" is "10", "-007" is "-7";
/// "0x28", "1e3" and "" are refused (a converter of base 0 would read 010 as 8).
Result<std::string> decimalInteger(std::string_view text);

/// A line to skip: empty (after trimming) or a comment starting with '#'.
bool isBlankOrComment(std::string_view line);

/// Text from an input, quoted for a message and cut when long: 'abc', or
/// '0.12345678901234567890…' (10485760 characters) — a message never echoes megabytes. (Not
/// named `quoted`: argument-dependent lookup would pick std::quoted for a std::string wherever
/// <iomanip> is included.)
std::string quotedText(std::string_view text, std::size_t keep = 32);

}  // namespace emcalign::io
