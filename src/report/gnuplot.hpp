#pragma once
// Internal to the report module (src/report/): what every figure needs to be drawn by
// gnuplot — the terminal header of a script, text safe in a gnuplot string, writing the data
// files and scripts, and running gnuplot with its messages turned into errors.

#include <filesystem>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"

namespace emcalign::report::detail {

inline constexpr const char* kInstallHint = "install it with `apt-get install gnuplot-nox` (scripts/install-deps does)";

/// Text a user gave (a sample's name, a tag, a file), shown literally inside a double-quoted
/// gnuplot string in enhanced mode: `mc_nominal` stays mc_nominal, never mc with a
/// subscript n; quotes and backslashes stay themselves; control characters become spaces.
std::string literalText(const std::string& s);
/// Text for a `#` comment line of a script or data file: control characters become spaces.
std::string commentText(const std::string& s);
/// Enhanced-text label of a quantity: a leading Greek letter's name becomes the letter, and
/// trailing digits and a "_suffix" a subscript ("beta1" → β_{1}, "dx_rel" → dx_{rel}).
std::string quantityLabel(const std::string& name);
/// Terminal and output of a script drawing NAME.png (pngcairo, UTF-8).
std::string terminalHeader(const std::string& pngName, int width, int height);
/// Writes dir/name (io/output_file.hpp rules).
Status writeFile(const std::filesystem::path& dir, const std::string& name, const std::string& content);
/// Draws dir/NAME.png with gnuplot from `script` (dir/NAME.gp's text, run from memory);
/// gnuplot's messages go into the error.
Status runGnuplot(const std::filesystem::path& dir, const std::string& name, std::string script);
Status createPlotDirectory(const std::filesystem::path& dir);

struct Figure {
  std::string name, script;
};
/// Writes each figure's script and runs it; the paths of the PNGs, in order.
Result<std::vector<std::string>> drawFigures(const std::filesystem::path& out, const std::vector<Figure>& figures);

}  // namespace emcalign::report::detail
