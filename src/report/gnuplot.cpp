#include "gnuplot.hpp"

#include <sys/wait.h>

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string_view>
#include <system_error>
#include <utility>

#include <fmt/format.h>

#include "emcalign/core/regular_file.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::report::detail {

namespace fs = std::filesystem;

std::string shellQuote(const std::string& s) {
  std::string out = "'";
  for (char c : s) {
    if (c == '\'')
      out += "'\\''";
    else
      out += c;
  }
  return out + "'";
}

// Keeps text that is safe inside a double-quoted gnuplot string in enhanced mode.
std::string plainText(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (std::isalnum(static_cast<unsigned char>(c)) || c == ' ' || c == '.' || c == ',' || c == '-') out += c;
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
  return io::writeOutputFile((dir / name).string(), content);
}

// Runs `gnuplot -d NAME.gp` in `dir`; gnuplot's messages go into the error. gnuplot does not
// write NAME.png itself (it would follow a link planted there, and leave half a figure when
// killed): it draws into the temporary of that output (io/output_file.hpp), which is renamed
// into place when gnuplot succeeds. The script it runs is NAME.gp with that output, kept in a
// temporary beside it; NAME.gp as written still draws NAME.png when a user runs it.
Status runGnuplot(const fs::path& dir, const std::string& name) {
  const std::string script = name + ".gp";
  const std::string png = (dir / (name + ".png")).string();
  auto text = RegularFile::open((dir / script).string());
  if (!text) return text.error();
  auto content = text->readAll(io::kMaxInputFileBytes);
  if (!content) return content.error();
  auto output = io::OutputFile::reserve(png);
  if (!output) return output.error();
  const std::string setOutput = fmt::format("set output '{}.png'\n", name);
  const auto at = content->find(setOutput);
  if (at == std::string::npos) return Error{fmt::format("{}: no line {}", (dir / script).string(), setOutput)};
  std::string target = fs::absolute((*output)->writtenPath()).string();
  std::string quotedTarget;
  for (char c : target) quotedTarget += c == '\'' ? std::string("''") : std::string(1, c);
  content->replace(at, setOutput.size(), fmt::format("set output '{}'\n", quotedTarget));
  auto run = io::OutputFile::open((dir / ("." + script)).string());  // never committed: removed afterwards
  if (!run) return run.error();
  if (std::fwrite(content->data(), 1, content->size(), (*run)->stream()) != content->size() ||
      std::fflush((*run)->stream()) != 0) {
    return Error{fmt::format("{}: write failed: {}", (*run)->writtenPath(), std::strerror(errno))};
  }
  const std::string command = fmt::format("cd {} && gnuplot -d {} 2>&1", shellQuote(dir.string()),
                                          shellQuote(fs::path((*run)->writtenPath()).filename().string()));
  std::FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr)
    return Error{fmt::format("{}: cannot start gnuplot: {}", (dir / script).string(), std::strerror(errno))};
  std::string said;
  char buffer[4096];
  std::size_t got = 0;
  while ((got = std::fread(buffer, 1, sizeof buffer, pipe)) > 0) said.append(buffer, got);
  const int status = pclose(pipe);
  while (!said.empty() && (said.back() == '\n' || said.back() == ' ')) said.pop_back();
  if (said.size() > 2000) said = said.substr(0, 2000) + " …";
  if (status == -1)
    return Error{fmt::format("{}: running gnuplot failed: {}", (dir / script).string(), std::strerror(errno))};
  if (WIFEXITED(status) && WEXITSTATUS(status) == 127)
    return Error{
        fmt::format("gnuplot was not found (needed to draw {}): {}; the shell said: {}", png, kInstallHint, said)};
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    return Error{fmt::format(
        "gnuplot failed on {} ({}): {}\n(gnuplot with the pngcairo terminal is needed; {})", (dir / script).string(),
        WIFEXITED(status) ? fmt::format("exit status {}", WEXITSTATUS(status)) : std::string("killed by a signal"),
        said, kInstallHint)};
  }
  std::error_code ec;
  const auto size = fs::file_size((*output)->writtenPath(), ec);
  if (ec || size == 0)
    return Error{fmt::format("gnuplot ran {} but drew no {}.png{}", (dir / script).string(), name,
                             said.empty() ? "" : ": " + said)};
  return (*output)->commit();
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
    if (auto st = runGnuplot(out, f.name); !st) return st.error();
    written.push_back((out / (f.name + ".png")).string());
  }
  return written;
}

}  // namespace emcalign::report::detail
