#pragma once
// Printing to standard error that never throws nor kills: a message or a progress line that
// cannot be shown (stderr closed, redirected to a full disk, a pipe whose reader is gone) must
// not end a command that otherwise succeeds, nor turn its refusal into an abort. (A closed
// pipe on standard output still ends the command with SIGPIPE, as `| head` expects.)

#include <pthread.h>
#include <signal.h>

#include <cerrno>
#include <cstdio>
#include <ctime>
#include <string>
#include <utility>

#include <fmt/format.h>

#include "emcalign/core/secrets.hpp"
#include "emcalign/core/utf8.hpp"

namespace emcalign::app {

/// `text` safe for a terminal: every control character that input files or a database could
/// have put into a message (an ESC sequence, a bell, a carriage return that rewrites the line)
/// shown as \xNN (core/utf8.hpp's printable), except the line's own newlines and tabs and a
/// carriage return that starts it (a progress line).
inline std::string terminalSafe(const std::string& text) {
  std::string out;
  std::size_t from = 0;
  for (std::size_t i = 0; i <= text.size(); ++i) {
    const bool end = i == text.size();
    if (!end && text[i] != '\n' && text[i] != '\t' && !(text[i] == '\r' && i == 0)) continue;
    out += printable(std::string_view(text).substr(from, i - from));
    if (!end) out += text[i];
    from = i + 1;
  }
  return out;
}

/// Writes `text` to stderr, without the command line's passwords (core/secrets.hpp) and terminal-safe; a SIGPIPE this
/// raises (the reader of a pipe gone) is taken back.
inline void writeToStderr(const std::string& given) noexcept {
  std::string text;
  try {
    text = terminalSafe(core::passwordsRemembered() ? core::withoutPasswords(given) : given);
  } catch (...) {  // out of memory: the line is not shown rather than shown with a password
    return;
  }
  sigset_t pipe, old;
  sigemptyset(&pipe);
  sigaddset(&pipe, SIGPIPE);
  pthread_sigmask(SIG_BLOCK, &pipe, &old);
  const std::size_t written = std::fwrite(text.data(), 1, text.size(), stderr);
  if (written < text.size() || std::fflush(stderr) != 0) {
    const timespec none{0, 0};
    while (sigtimedwait(&pipe, nullptr, &none) > 0) {  // the SIGPIPE of this write, pending: taken
    }
    std::clearerr(stderr);
  }
  pthread_sigmask(SIG_SETMASK, &old, nullptr);
}

template <typename... T>
void eprint(fmt::format_string<T...> format, T&&... args) noexcept {
  try {
    writeToStderr(fmt::format(format, std::forward<T>(args)...));
  } catch (...) {  // out of memory formatting a message: nothing more can be said
  }
}

}  // namespace emcalign::app
