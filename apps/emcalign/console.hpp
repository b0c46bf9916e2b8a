#pragma once
// Printing to standard error that never throws: a message or a progress line that cannot be
// shown (stderr closed, redirected to a full disk) must not end a command that otherwise
// succeeds, nor turn its refusal into an abort.

#include <cstdio>
#include <string>
#include <utility>

#include <fmt/format.h>

namespace emcalign::app {

template <typename... T>
void eprint(fmt::format_string<T...> format, T&&... args) noexcept {
  try {
    const std::string text = fmt::format(format, std::forward<T>(args)...);
    [[maybe_unused]] const std::size_t written = std::fwrite(text.data(), 1, text.size(), stderr);
  } catch (...) {  // out of memory formatting a message: nothing more can be said
  }
}

}  // namespace emcalign::app
