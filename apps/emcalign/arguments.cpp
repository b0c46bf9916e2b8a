#include "arguments.hpp"

#include <algorithm>
#include <cctype>
#include <string_view>
#include <vector>

#include <fmt/format.h>

namespace emcalign::app {

// Levenshtein distance with a swap of two neighbouring letters as one edit (the optimal
// string alignment distance): "lsit" is 1 from "list", 2 from "init".
std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    }
  }
  return d[a.size()][b.size()];
}

namespace {

// The nearest of `names` to `typed`: a name it begins or ends, else the least edit distance
// within a third of the longer one (at least 2).
std::optional<std::string> nearest(const std::string& typed, const std::vector<std::string>& names) {
  std::optional<std::string> best;
  std::size_t bestDistance = std::string::npos;
  for (const auto& n : names) {
    std::size_t d = editDistance(typed, n);
    const std::size_t limit = std::max<std::size_t>(2, std::max(typed.size(), n.size()) / 3);
    const bool affix = typed.size() >= 3 && (n.starts_with(typed) || typed.starts_with(n));
    if (affix) d = std::min<std::size_t>(d, 1);
    if (d <= limit && d < bestDistance) {
      best = n;
      bestDistance = d;
    }
  }
  return best;
}

// "emcalign conditions", or "emcalign" for the root (whose name is empty).
std::string path(const CLI::App& app) {
  std::string p = "emcalign";
  std::vector<std::string> names;
  for (const CLI::App* a = &app; a != nullptr; a = a->get_parent()) {
    if (!a->get_name().empty()) names.push_back(a->get_name());
  }
  for (auto it = names.rbegin(); it != names.rend(); ++it) p += " " + *it;
  return p;
}

std::vector<std::string> optionNames(const CLI::App& app, bool longNames) {
  std::vector<std::string> out;
  for (const CLI::Option* o : app.get_options()) {
    for (const auto& n : longNames ? o->get_lnames() : o->get_snames()) out.push_back((longNames ? "--" : "-") + n);
  }
  return out;
}

std::vector<std::string> commandNames(CLI::App& app) {
  std::vector<std::string> out;
  for (const CLI::App* s : app.get_subcommands([](CLI::App*) { return true; })) {
    if (!s->get_name().empty()) out.push_back(s->get_name());
  }
  return out;
}

bool looksLikeNumber(std::string_view t) {
  return t.size() > 1 && t[0] == '-' && (std::isdigit(static_cast<unsigned char>(t[1])) != 0 || t[1] == '.');
}

}  // namespace

std::optional<std::string> mistypedArgument(CLI::App& root, int argc, char** argv) {
  CLI::App* app = &root;
  for (int i = 1; i < argc; ++i) {
    const std::string token = argv[i];
    if (token == "--") return std::nullopt;
    if (token.starts_with("--")) {
      const std::string name = token.substr(0, token.find('='));
      if (app->get_option_no_throw(name) != nullptr) continue;
      const auto guess = nearest(name, optionNames(*app, true));
      return fmt::format("unknown option {} for {}{}", name, path(*app),
                         guess ? fmt::format(" (did you mean {}?)", *guess) : std::string());
    }
    if (token.size() >= 2 && token[0] == '-' && !looksLikeNumber(token)) {
      const std::string name = token.substr(0, 2);
      if (app->get_option_no_throw(name) != nullptr) continue;
      return fmt::format("unknown option {} for {}", name, path(*app));
    }
    const auto names = commandNames(*app);
    if (names.empty()) continue;  // a leaf command: its values and positional arguments
    if (std::find(names.begin(), names.end(), token) != names.end()) {
      app = app->get_subcommand(token);
      continue;
    }
    // A word where a command is expected (its options take their values with them: a value
    // of one of them is never a command here, none of the commands with subcommands has
    // options with values).
    if (app->get_options([](const CLI::Option* o) { return o->get_positional(); }).empty()) {
      const auto guess = nearest(token, names);
      return fmt::format("unknown command '{}' for {}{}; the commands are: {}", token, path(*app),
                         guess ? fmt::format(" (did you mean {}?)", *guess) : std::string(), fmt::join(names, ", "));
    }
  }
  return std::nullopt;
}

}  // namespace emcalign::app
