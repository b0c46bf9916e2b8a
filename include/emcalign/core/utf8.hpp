#pragma once
// Whether text is valid UTF-8. Paths and names end up in JSON (result files, attributes),
// which must be UTF-8: the front ends refuse arguments that are not, rather than fail
// deep inside a writer.

#include <algorithm>
#include <cstddef>
#include <string>
#include <string_view>

namespace emcalign {

/// RFC 3629: no overlong forms, no surrogates, nothing above U+10FFFF.
inline bool isValidUtf8(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    std::size_t n = 0;
    unsigned lo = 0x80, hi = 0xBF;  // the range of the second byte
    if (c < 0x80) {
      ++i;
      continue;
    } else if (c >= 0xC2 && c <= 0xDF) {
      n = 1;
    } else if (c >= 0xE0 && c <= 0xEF) {
      n = 2;
      if (c == 0xE0) lo = 0xA0;
      if (c == 0xED) hi = 0x9F;
    } else if (c >= 0xF0 && c <= 0xF4) {
      n = 3;
      if (c == 0xF0) lo = 0x90;
      if (c == 0xF4) hi = 0x8F;
    } else {
      return false;
    }
    if (i + n >= s.size()) return false;  // the sequence is cut short
    for (std::size_t k = 1; k <= n; ++k) {
      const auto b = static_cast<unsigned char>(s[i + k]);
      if (k == 1 ? (b < lo || b > hi) : (b < 0x80 || b > 0xBF)) return false;
    }
    i += n + 1;
  }
  return true;
}

/// The length of the valid UTF-8 sequence at s[i] (1 to 4), or 0 when the byte there does not
/// start one.
inline std::size_t utf8SequenceAt(std::string_view s, std::size_t i) {
  for (std::size_t n = 1; n <= 4 && i + n <= s.size(); ++n) {
    const std::string_view piece = s.substr(i, n);
    if (isValidUtf8(piece)) return n;
  }
  return 0;
}

/// Text read from a file or a database, made safe to print on a terminal and to write into
/// JSON: control characters (C0, DEL and C1: ESC sequences, a bell, a carriage return that
/// rewrites the line) as \xNN or \uNNNN, bytes that are not UTF-8 as \xNN; the rest as it is.
inline std::string printable(std::string_view s) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(s.size());
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    const std::size_t n = utf8SequenceAt(s, i);
    if (n == 0 || c < 0x20 || c == 0x7f) {
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 15];
      ++i;
      continue;
    }
    if (n == 2 && c == 0xC2 && static_cast<unsigned char>(s[i + 1]) < 0xA0) {  // U+0080 to U+009F
      const auto low = static_cast<unsigned char>(s[i + 1]);
      out += "\\u00";
      out += kHex[low >> 4];
      out += kHex[low & 15];
      i += 2;
      continue;
    }
    out.append(s.substr(i, n));
    i += n;
  }
  return out;
}

/// Why the command-line argument at `position` is refused ("" when it is not): a control
/// character (a newline would let a name forge a line of a message or a batch script), or
/// text that is not UTF-8 (names and values are recorded in JSON, which is).
inline std::string argumentRefusal(std::string_view argument, int position) {
  const bool control = std::any_of(argument.begin(), argument.end(),
                                   [](char c) { return (c >= 0 && c < 0x20 && c != '\t') || c == 0x7f; });
  if (control) {
    return "argument " + std::to_string(position) +
           " holds a control character (a newline?): a name would forge a line of a message or a batch script; "
           "rename it";
  }
  if (!isValidUtf8(argument)) {
    return "argument " + std::to_string(position) +
           " is not valid UTF-8 (file names and values are recorded in JSON, which must be: rename the file)";
  }
  return {};
}

}  // namespace emcalign
