#pragma once
// Numbers and counts in the words of a message: "1 group" but "2 groups", and a value that
// rounds to zero printed as 0.000, never -0.000 (a negative zero, or -1e-12 of a
// conversion, is not a negative value to a reader); words for the shell.

#include <concepts>
#include <string>
#include <string_view>
#include <utility>

#include <fmt/format.h>

namespace emcalign {

/// The noun for `n` things: `singular` for exactly one, else `plural` (by default the
/// singular with an "s": "group" → "groups"; "beam energy" needs "beam energies").
template <std::integral N>
std::string nounFor(N n, std::string_view singular, std::string_view plural = {}) {
  if (std::cmp_equal(n, 1)) return std::string(singular);
  return plural.empty() ? std::string(singular) + "s" : std::string(plural);
}

/// "1 group", "0 groups", "3 beam energies".
template <std::integral N>
std::string counted(N n, std::string_view singular, std::string_view plural = {}) {
  return fmt::format("{} {}", n, nounFor(n, singular, plural));
}

/// `v` with `decimals` decimals ("+" before a positive value when `sign`), as fmt's {:.Nf}
/// writes it, but a value that rounds to zero has no sign: "0.000000", never "-0.000000".
inline std::string fixed(double v, int decimals, bool sign = false) {
  std::string s = sign ? fmt::format("{:+.{}f}", v, decimals) : fmt::format("{:.{}f}", v, decimals);
  if ((s.starts_with('-') || s.starts_with('+')) && s.find_first_not_of("+-0.") == std::string::npos) s.erase(0, 1);
  return s;
}

/// A word for the shell, single-quoted (a single quote as '\''): for scripts.
inline std::string shellWord(std::string_view s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

/// A word for a command line shown to a user: as it is when the shell takes it so, quoted
/// otherwise (a path with a space).
inline std::string shellArgument(std::string_view s) {
  const bool plain = !s.empty() && s.find_first_not_of(
                                       "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                                       "0123456789_./-+:=,@%") == std::string_view::npos;
  return plain ? std::string(s) : shellWord(s);
}

}  // namespace emcalign
