#pragma once
// The wall-clock time as records give it (conditions tags, a plan's task records).

#include <chrono>
#include <ctime>
#include <string>

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

}  // namespace emcalign
