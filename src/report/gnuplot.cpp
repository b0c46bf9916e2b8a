#include "gnuplot.hpp"

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "emcalign/core/subprocess.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::report::detail {

namespace fs = std::filesystem;

std::string commentText(const std::string& s) {
  std::string out;
  for (char c : s) out += static_cast<unsigned char>(c) < 0x20 || c == '\x7f' ? ' ' : c;
  return out;
}

std::string literalText(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (static_cast<unsigned char>(c) < 0x20 || c == '\x7f') {
      out += ' ';
    } else if (c == '"') {
      out += "\\\"";
    } else if (c == '\\') {
      out += "\\\\\\\\";  // a backslash for enhanced text, each doubled for the string
    } else if (std::string_view("_^@&~{}").find(c) != std::string_view::npos) {
      out += "\\\\";  // enhanced text's escape, doubled for the double-quoted string
      out += c;
    } else {
      out += c;
    }
  }
  return out;
}

// Enhanced-text label of a quantity: a leading Greek letter's name becomes the letter, and
// trailing digits and a "_suffix" a subscript ("beta1" → β_{1}, "dx_rel" → dx_{rel},
// "beta_rel" → β_{rel}). Only letters and digits of the name are kept, so the label is
// safe in a double-quoted enhanced-mode string.
std::string quantityLabel(const std::string& name) {
  static constexpr std::pair<std::string_view, std::string_view> kGreek[] = {
      {"alpha", "α"}, {"beta", "β"}, {"gamma", "γ"}, {"delta", "δ"}, {"eta", "η"},
      {"theta", "θ"}, {"mu", "μ"},   {"psi", "ψ"},   {"tau", "τ"},   {"phi", "φ"}};
  auto alnum = [](std::string_view s) {
    std::string out;
    for (char c : s)
      if (std::isalnum(static_cast<unsigned char>(c))) out += c;
    return out;
  };
  const auto underscore = name.find('_');
  const std::string head = alnum(std::string_view(name).substr(0, underscore));
  const std::string tail = underscore == std::string::npos ? "" : alnum(std::string_view(name).substr(underscore + 1));
  std::size_t digits = head.size();
  while (digits > 0 && std::isdigit(static_cast<unsigned char>(head[digits - 1]))) --digits;
  std::string label = head.substr(0, digits);
  for (const auto& [word, letter] : kGreek)
    if (label == word) label = letter;
  std::string sub = head.substr(digits);
  if (!tail.empty()) sub += (sub.empty() ? "" : ",") + tail;
  if (!sub.empty()) label += "_{" + sub + "}";
  return label.empty() ? std::string("?") : label;
}

// Terminal and output of a script drawing NAME.png.
std::string terminalHeader(const std::string& pngName, int width, int height) {
  return fmt::format(
      "# Written by emcalign (its report module). Restyle freely; run in this directory:\n"
      "#   gnuplot {}.gp\n"
      "set encoding utf8\n"
      "set terminal pngcairo size {},{} enhanced font 'DejaVu Sans,12' linewidth 1\n"
      "set output '{}.png'\n",
      pngName, width, height, pngName);
}

Status writeFile(const fs::path& dir, const std::string& name, const std::string& content) {
  return io::writeFileIn(dir.string(), name, content);
}

namespace {

// A figure takes gnuplot a second; a data file that never ends (a FIFO) would take for ever.
constexpr int kGnuplotSeconds = 120;

}  // namespace

// Draws DIR/NAME.png from `script` (the text of DIR/NAME.gp, as written); gnuplot's messages
// go into the error. gnuplot opens no file to write, and runs the script from memory (never
// read back from the directory, where it could have been swapped): it is given on gnuplot's
// standard input with the output set to the standard output, and the figure printed there is
// written as DIR/NAME.png by the output rules (io/output_file.hpp). gnuplot reads the data
// files of the directory; one that never ends (a FIFO swapped in) stops it after
// kGnuplotSeconds.
Status runGnuplot(const fs::path& dir, const std::string& name, std::string script) {
  const std::string source = (dir / (name + ".gp")).string();
  const std::string png = name + ".png";
  const std::string setOutput = fmt::format("set output '{}'\n", png);
  const auto at = script.find(setOutput);
  if (at == std::string::npos) return Error{fmt::format("{}: no line {}", source, setOutput)};
  script.replace(at, setOutput.size(), "set output  # the standard output, which emcalign writes to the file\n");
  const core::Ran ran = core::runCapturing({"gnuplot", "-d"}, dir.string(), script, kGnuplotSeconds);
  std::string said = ran.err;
  while (!said.empty() && (said.back() == '\n' || said.back() == ' ')) said.pop_back();
  if (said.size() > 2000) said = said.substr(0, 2000) + " …";
  if (ran.timedOut) {
    return Error{fmt::format("gnuplot did not finish {} within {} s (a data file of {} that never ends?): stopped",
                             source, kGnuplotSeconds, dir.string())};
  }
  if (ran.status == -1 && (ran.startError == ENOENT || ran.startError == EACCES)) {
    return Error{fmt::format("gnuplot was not found (needed to draw {}): {}", (dir / png).string(), kInstallHint)};
  }
  if (ran.status == -1) {
    return Error{fmt::format("{}: cannot start gnuplot: {}", source, std::strerror(ran.startError))};
  }
  if (!WIFEXITED(ran.status) || WEXITSTATUS(ran.status) != 0) {
    return Error{fmt::format("gnuplot failed on {} ({}): {}\n(gnuplot with the pngcairo terminal is needed; {})",
                             source,
                             WIFEXITED(ran.status) ? fmt::format("exit status {}", WEXITSTATUS(ran.status))
                                                   : std::string("killed by a signal"),
                             said, kInstallHint)};
  }
  static constexpr std::string_view kPngSignature = "\x89PNG\r\n\x1a\n";
  if (!std::string_view(ran.out).starts_with(kPngSignature)) {
    return Error{fmt::format("gnuplot ran {} but drew no PNG{}", source, said.empty() ? "" : ": " + said)};
  }
  return io::writeFileIn(dir.string(), png, ran.out);
}

Status createPlotDirectory(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Error{fmt::format("cannot create the plot directory '{}': {}", dir.string(), ec.message())};
  return {};
}

// Writes each figure's script and runs it; the paths of the PNGs, in order.
Result<std::vector<std::string>> drawFigures(const fs::path& out, const std::vector<Figure>& figures) {
  std::vector<std::string> written;
  for (const auto& f : figures) {
    if (auto st = writeFile(out, f.name + ".gp", f.script); !st) return st.error();
    if (auto st = runGnuplot(out, f.name, f.script); !st) return st.error();
    written.push_back((out / (f.name + ".png")).string());
  }
  return written;
}

}  // namespace emcalign::report::detail
