#include "emcalign/io/csv.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

#include <fmt/format.h>

#include "emcalign/core/secrets.hpp"

namespace emcalign::io {

namespace {
std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}
}  // namespace

std::vector<std::string_view> splitCsvLine(std::string_view line) {
  std::vector<std::string_view> fields;
  line = trim(line);
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    if (comma == std::string_view::npos) {
      fields.push_back(trim(line.substr(start)));
      break;
    }
    fields.push_back(trim(line.substr(start, comma - start)));
    start = comma + 1;
  }
  return fields;
}

std::optional<double> parseFiniteDouble(std::string_view field) {
  if (!field.empty() && field.front() == '+') field.remove_prefix(1);
  if (field.empty()) return std::nullopt;
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (ec != std::errc() || ptr != field.data() + field.size() || !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

Result<double> parseFiniteIn(std::string_view text, double lo, double hi) {
  const auto x = parseFiniteDouble(text);
  if (!x) return Error{fmt::format("{} is not a finite number", quotedText(text))};
  if (*x < lo || *x > hi) return Error{fmt::format("{} is outside [{}, {}]", quotedText(text), lo, hi)};
  return *x;
}

Result<std::int64_t> parseIntegerIn(std::string_view text, std::int64_t lo, std::int64_t hi) {
  std::string_view digits = text;
  if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);
  std::int64_t x = 0;
  const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), x);
  if (digits.empty() || ec == std::errc::invalid_argument || ptr != digits.data() + digits.size()) {
    return Error{fmt::format("{} is not an integer", quotedText(text))};
  }
  if (ec == std::errc::result_out_of_range || x < lo || x > hi) {
    return Error{fmt::format("{} is outside [{}, {}]", quotedText(text), lo, hi)};
  }
  return x;
}

Result<std::uint64_t> parseUnsigned64(std::string_view text) {
  std::uint64_t x = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), x);
  if (text.empty() || ec == std::errc::invalid_argument || ptr != text.data() + text.size()) {
    return Error{fmt::format("{} is not an unsigned integer (0 to 2^64 - 1)", quotedText(text))};
  }
  if (ec == std::errc::result_out_of_range) return Error{fmt::format("{} is larger than 2^64 - 1", quotedText(text))};
  return x;
}

Result<std::string> decimalInteger(std::string_view text) {
  std::string_view digits = text;
  const bool negative = !digits.empty() && digits.front() == '-';
  if (!digits.empty() && (digits.front() == '+' || negative)) digits.remove_prefix(1);
  if (digits.empty() || !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    return Error{fmt::format("{} is not a decimal integer", quotedText(text))};
  }
  while (digits.size() > 1 && digits.front() == '0') digits.remove_prefix(1);
  std::string number(negative ? "-" : "");
  number.append(digits);
  return number;
}

std::string quotedText(std::string_view given, std::size_t keep) {
  // Passwords out before the cut: a password cut in two is not found again.
  const std::string redacted = core::withoutPasswords(std::string(given));
  const std::string_view text = redacted;
  if (text.size() <= keep + 8) return fmt::format("'{}'", text);
  // Cut on a UTF-8 character boundary.
  std::size_t cut = keep;
  while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) --cut;
  return fmt::format("'{}…' ({} characters)", text.substr(0, cut), text.size());
}

bool isBlankOrComment(std::string_view line) {
  line = trim(line);
  return line.empty() || line.front() == '#';
}

}  // namespace emcalign::io
