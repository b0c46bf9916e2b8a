#include "emcalign/core/clock.hpp"

#include <charconv>

#include <fmt/format.h>

namespace emcalign {

namespace {

// Days since 1970-01-01 of a civil date (proleptic Gregorian; H. Hinnant's algorithm).
std::int64_t daysFromCivil(std::int64_t y, unsigned m, unsigned d) {
  y -= m <= 2 ? 1 : 0;
  const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
  const auto yoe = static_cast<unsigned>(y - era * 400);
  const unsigned doy = (153 * (m > 2 ? m - 3 : m + 9) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + static_cast<std::int64_t>(doe) - 719468;
}

bool digits(std::string_view s, std::size_t at, std::size_t n, int& out) {
  if (at + n > s.size()) return false;
  for (std::size_t i = at; i < at + n; ++i) {
    if (s[i] < '0' || s[i] > '9') return false;
  }
  return std::from_chars(s.data() + at, s.data() + at + n, out).ec == std::errc();
}

}  // namespace

UtcMicros utcNowMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string utcMicrosText(UtcMicros t) {
  const std::int64_t micros = ((t % 1000000) + 1000000) % 1000000;
  const std::time_t seconds = static_cast<std::time_t>((t - micros) / 1000000);
  std::tm tm{};
  ::gmtime_r(&seconds, &tm);
  return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:06}Z", tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday,
                     tm.tm_hour, tm.tm_min, tm.tm_sec, micros);
}

Result<UtcMicros> parseUtcTime(std::string_view s) {
  const auto bad = [&] {
    return Error{fmt::format(
        "'{}' is not a UTC time: expected ISO 8601, e.g. 2026-12-05T14:03:27Z or 2026-12-05T14:03:27.123456Z",
        std::string(s.substr(0, 64)))};
  };
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, sec = 0;
  if (!digits(s, 0, 4, y) || s.size() < 19 || s[4] != '-' || !digits(s, 5, 2, mo) || s[7] != '-' ||
      !digits(s, 8, 2, d) || (s[10] != 'T' && s[10] != 't' && s[10] != ' ') || !digits(s, 11, 2, h) || s[13] != ':' ||
      !digits(s, 14, 2, mi) || s[16] != ':' || !digits(s, 17, 2, sec)) {
    return bad();
  }
  static constexpr int kDays[] = {31, 29, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  const bool leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
  if (mo < 1 || mo > 12 || d < 1 || d > kDays[mo - 1] || (mo == 2 && d == 29 && !leap) || h > 23 || mi > 59 ||
      sec > 59) {
    return bad();
  }
  std::size_t at = 19;
  std::int64_t micros = 0;
  if (at < s.size() && s[at] == '.') {
    ++at;
    std::size_t n = 0;
    while (at < s.size() && s[at] >= '0' && s[at] <= '9') {
      if (n < 6) micros = micros * 10 + (s[at] - '0');
      ++n;
      ++at;
    }
    if (n == 0) return bad();
    for (std::size_t k = n; k < 6; ++k) micros *= 10;
  }
  // The zone: Z, an offset from UTC (+01:00, -0500), or none: UTC, as every time here is.
  const std::string_view zone = s.substr(at);
  int offsetMinutes = 0;
  if (!zone.empty() && zone != "Z" && zone != "z") {
    int oh = 0, om = 0;
    const bool colon = zone.size() == 6 && zone[3] == ':';
    if ((zone.size() != 5 && !colon) || (zone[0] != '+' && zone[0] != '-') || !digits(zone, 1, 2, oh) ||
        !digits(zone, colon ? 4 : 3, 2, om) || oh > 23 || om > 59) {
      return bad();
    }
    offsetMinutes = (zone[0] == '-' ? -1 : 1) * (oh * 60 + om);
  }
  const std::int64_t days = daysFromCivil(y, static_cast<unsigned>(mo), static_cast<unsigned>(d));
  return ((days * 24 + h) * 60 + mi - offsetMinutes) * 60 * std::int64_t{1000000} + sec * std::int64_t{1000000} +
         micros;
}

std::optional<UtcMicros> utcMicrosOf(std::string_view text) {
  auto t = parseUtcTime(text);
  if (!t) return std::nullopt;
  return *t;
}

}  // namespace emcalign
