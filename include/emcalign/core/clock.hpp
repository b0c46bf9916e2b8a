#pragma once
// The wall-clock time as records give it (conditions tags, a plan's task records), and the
// times of the conditions database's changes: ISO 8601, UTC.

#include <chrono>
#include <cstdint>
#include <ctime>
#include <optional>
#include <string>
#include <string_view>

#include "emcalign/core/result.hpp"

namespace emcalign {

/// The current time, UTC, ISO 8601 to the second ("2026-12-02T13:39:02Z").
inline std::string utcNow() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  ::gmtime_r(&now, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

/// Microseconds since 1970-01-01T00:00:00Z.
using UtcMicros = std::int64_t;

/// The current time in microseconds.
UtcMicros utcNowMicros();

/// A time as the conditions database keeps it: "2026-12-05T04:45:30.123456Z" (always 27
/// characters, so that text order is time order).
std::string utcMicrosText(UtcMicros t);

/// A time given by a person or a record: "YYYY-MM-DDTHH:MM:SS", with a fraction of any number
/// of digits or none, then "Z", "+00:00" or nothing (UTC is meant either way); 'T' may be a
/// space. A fraction finer than a microsecond is cut (what is at or before the time given is
/// at or before its microsecond). The error says what is expected.
Result<UtcMicros> parseUtcTime(std::string_view text);

/// parseUtcTime of a text the database wrote; none when it is not one.
std::optional<UtcMicros> utcMicrosOf(std::string_view text);

}  // namespace emcalign
