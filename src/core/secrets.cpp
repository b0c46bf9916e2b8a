#include "emcalign/core/secrets.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <mutex>

namespace emcalign::core {

namespace {

// Shorter ones are searched only with what stands before them (a bare "ab" is in many words).
constexpr std::size_t kMinBareSecret = 4;

std::mutex gMutex;
std::vector<std::string> gPasswords;  // and user:password forms

bool schemeCharacter(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '+' || c == '-' || c == '.';
}

void add(std::vector<std::string>& out, std::string_view s) {
  if (s.empty()) return;
  out.emplace_back(s);
  if (std::string d = percentDecoded(s); d != s) out.push_back(std::move(d));
}

}  // namespace

namespace {
int hexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

std::string percentDecoded(std::string_view s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && hexValue(s[i + 1]) >= 0 && hexValue(s[i + 2]) >= 0) {
      out += static_cast<char>(hexValue(s[i + 1]) * 16 + hexValue(s[i + 2]));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

std::vector<std::string> passwordsIn(std::string_view text, bool withinText) {
  std::vector<std::string> out;
  // scheme://user:password@host…: the userinfo up to the last '@' of the argument (a password
  // with an '@' or a space not percent-encoded is a password all the same). The scheme starts
  // at its first letter ("-opostgresql://", "--postgresql://", "%20postgresql://").
  for (auto at = text.find("://"); at != std::string_view::npos; at = text.find("://", at + 3)) {
    std::size_t begin = at;
    while (begin > 0 && schemeCharacter(text[begin - 1])) --begin;
    while (begin < at && std::isalpha(static_cast<unsigned char>(text[begin])) == 0) ++begin;
    if (begin == at) continue;
    const std::size_t from = at + 3;
    // (To the end of the argument; in a text, of its line or its quoted string.)
    const std::size_t end = std::min(text.size(), text.find_first_of(withinText ? "\n\"" : "\n", from));
    const std::string_view rest = text.substr(from, end - from);
    const auto lastAt = rest.rfind('@');
    if (lastAt == std::string_view::npos) continue;
    const std::string_view userinfo = rest.substr(0, lastAt);
    const auto colon = userinfo.find(':');
    if (colon == std::string_view::npos || colon + 1 == userinfo.size()) continue;
    add(out, userinfo.substr(colon + 1));
  }
  // password=…, sslpassword=…: a URI's parameter (its name percent-encoded or not: pass%77ord=,
  // password%3D…) or a libpq keyword string (white space around its '=' allowed).
  const auto parameters = [&](std::string_view source) {
    std::string lower(source);
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
    for (auto at = lower.find("password"); at != std::string::npos; at = lower.find("password", at + 8)) {
      std::size_t from = at + 8;
      while (from < source.size() && (source[from] == ' ' || source[from] == '\t')) ++from;
      if (from >= source.size() || source[from] != '=') continue;
      ++from;
      while (from < source.size() && (source[from] == ' ' || source[from] == '\t')) ++from;
      // The value as libpq reads it: quoted ('…') or up to white space or '&', a backslash
      // escaping the next character; kept as written and as read.
      const std::string_view rest = source.substr(from);
      const bool quoted = !rest.empty() && (rest.front() == '\'' || rest.front() == '"');
      std::string read;
      std::size_t i = quoted ? 1 : 0;
      for (; i < rest.size(); ++i) {
        const char c = rest[i];
        if (c == '\\' && i + 1 < rest.size()) {
          read += rest[++i];
          continue;
        }
        if (quoted ? c == rest.front() : (c == ' ' || c == '\t' || c == '\n' || c == '&')) break;
        read += c;
      }
      add(out, rest.substr(quoted ? 1 : 0, i - (quoted ? 1 : 0)));
      if (read != rest.substr(quoted ? 1 : 0, i - (quoted ? 1 : 0))) add(out, read);
    }
  };
  parameters(text);
  if (const std::string decoded = percentDecoded(text); decoded != text) parameters(decoded);
  return out;
}

void rememberPasswordsOf(std::string_view text) {
  auto found = passwordsIn(text);
  if (found.empty()) return;
  // Also as a JSON string and HTML text write it (a report's title, a plan's arguments): the
  // escaped form is what lands in the file.
  for (std::size_t n = found.size(), k = 0; k < n; ++k) {
    std::string json, html;
    for (char c : found[k]) {
      json += c == '"' ? std::string("\\\"") : c == '\\' ? std::string("\\\\") : std::string(1, c);
      html += c == '<'    ? std::string("&lt;")
              : c == '>'  ? std::string("&gt;")
              : c == '&'  ? std::string("&amp;")
              : c == '"'  ? std::string("&quot;")
              : c == '\'' ? std::string("&#39;")
                          : std::string(1, c);
    }
    if (json != found[k]) found.push_back(json);
    if (html != found[k]) found.push_back(html);
  }
  const std::lock_guard lock(gMutex);
  for (auto& p : found) {
    if (std::find(gPasswords.begin(), gPasswords.end(), p) == gPasswords.end()) gPasswords.push_back(std::move(p));
  }
  std::sort(gPasswords.begin(), gPasswords.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
}

bool passwordsRemembered() {
  const std::lock_guard lock(gMutex);
  return !gPasswords.empty();
}

std::string withoutAnyPassword(std::string text) {
  text = withoutPasswords(std::move(text));
  auto found = passwordsIn(text);
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
  for (const std::string& p : found) {
    for (auto at = text.find(p); at != std::string::npos; at = text.find(p, at + 3)) text.replace(at, p.size(), "***");
  }
  return text;
}

bool holdsPassword(std::string_view text, bool withinText) { return !passwordsIn(text, withinText).empty(); }

std::string withoutPasswords(std::string text) {
  const std::lock_guard lock(gMutex);
  if (gPasswords.empty()) return text;
  for (const std::string& p : gPasswords) {
    const bool bare = p.size() >= kMinBareSecret || p.find(':') != std::string::npos;
    for (auto at = text.find(p); at != std::string::npos; at = text.find(p, at)) {
      const bool preceded = at > 0 && (text[at - 1] == ':' || text[at - 1] == '=');
      if (!bare && !preceded) {
        at += p.size();
        continue;
      }
      text.replace(at, p.size(), "***");
      at += 3;
    }
  }
  // A password cut short where a message shortens a value ("hunter2sec…"): its beginning, from
  // 4 characters on (or after a ':' or '='), followed by the ellipsis.
  static constexpr std::string_view kEllipsis = "…";
  for (auto at = text.find(kEllipsis); at != std::string::npos; at = text.find(kEllipsis, at + 1)) {
    for (const std::string& p : gPasswords) {
      std::size_t k = std::min(p.size(), at);
      for (; k > 0; --k) {
        if (text.compare(at - k, k, p, 0, k) != 0) continue;
        const bool preceded = at - k > 0 && (text[at - k - 1] == ':' || text[at - k - 1] == '=');
        if (k >= kMinBareSecret || preceded) break;
      }
      if (k == 0) continue;
      text.replace(at - k, k, "***");
      at = at - k + 3;
      break;
    }
  }
  return text;
}

namespace {
ssize_t writeRedacted(void* cookie, const char* data, std::size_t size) {
  auto* real = static_cast<std::FILE*>(cookie);
  std::string text;
  try {
    text = withoutPasswords(std::string(data, size));
  } catch (...) {
    errno = ENOMEM;
    return -1;
  }
  if (std::fwrite(text.data(), 1, text.size(), real) != text.size() || std::fflush(real) != 0) return -1;
  return static_cast<ssize_t>(size);
}
}  // namespace

std::FILE* redactingStream(std::FILE* real) {
  const cookie_io_functions_t io{nullptr, writeRedacted, nullptr, nullptr};
  std::FILE* redacted = fopencookie(real, "w", io);
  if (redacted == nullptr) return nullptr;
  // Static storage without a destructor: the stream is flushed at exit, after destructors ran.
  static std::array<char, std::size_t{1} << 20> buffer;
  std::setvbuf(redacted, buffer.data(), _IOLBF, buffer.size());
  return redacted;
}

}  // namespace emcalign::core
