#include "emcalign/io/file_kind.hpp"

#include <array>
#include <utility>

#include <fmt/format.h>

#include "emcalign/core/regular_file.hpp"
#include "emcalign/io/csv.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::io {

namespace {

// emcalign's CSV files by the start of their header line.
constexpr std::array<std::pair<std::string_view, std::string_view>, 5> kCsvHeaders{{
    {"run,event,beam_energy_mev,", kCsvEventFileKind},
    {"i_phi,i_theta,n,", kProfileCsvKind},
    {"first_run,last_run,payload,", "a conditions export (emcalign conditions export)"},
    {"index,layer,ring,iphi,", "a counters CSV (geometry --counters)"},
    {"run,event,counter,energy_mev,", kRandomTriggerCsvKind},
}};

// The first line that is neither blank nor a comment, within the text given.
std::string_view firstDataLine(std::string_view text) {
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);  // UTF-8 BOM
  while (!text.empty()) {
    const std::size_t end = text.find('\n');
    const std::string_view line = text.substr(0, end);
    if (!isBlankOrComment(line)) return line;
    if (end == std::string_view::npos) break;
    text.remove_prefix(end + 1);
  }
  return {};
}

std::string_view csvKind(std::string_view text) {
  if (text.starts_with("# emcalign conditions export")) return kCsvHeaders[2].second;
  if (text.starts_with("# format: emcalign-random-trigger/")) return kRandomTriggerCsvKind;
  // The attribute comments a simulated event file starts with (its header may lie beyond the text given).
  if (text.starts_with("# truth_parameters:") || text.starts_with("# simulation:")) return kCsvEventFileKind;
  std::string header;  // its fields trimmed, each followed by a comma; the start is enough
  for (auto field : splitCsvLine(firstDataLine(text).substr(0, 256))) header += std::string(field) + ",";
  for (const auto& [start, kind] : kCsvHeaders) {
    if (header.starts_with(start)) return kind;
  }
  return {};
}

bool looksLikeJson(std::string_view text) {
  const std::size_t first = text.find_first_not_of(" \t\r\n");
  return first != std::string_view::npos && (text[first] == '{' || text[first] == '[');
}

}  // namespace

std::string describeNonJson(std::string_view text) {
  if (looksLikeJson(text)) return {};
  if (text.starts_with("\x89HDF\r\n\x1a\n")) return "an HDF5 file (an event file?)";
  if (text.starts_with("\x89PNG")) return "a PNG image";
  if (text.starts_with("SQLite format 3")) return "an SQLite database (a conditions database?)";
  if (text.starts_with("<?xml") || text.starts_with("<gdml")) return "an XML file (GDML placements?)";
  return std::string(csvKind(text));
}

std::string describeContent(std::string_view text) {
  if (!looksLikeJson(text)) return describeNonJson(text);
  auto j = parseJson(text, "");
  if (!j) return {};
  const bool hasFormat = j->is_object() && j->contains("format") && (*j)["format"].is_string();
  if (!hasFormat) return "a JSON file";
  const std::string format = (*j)["format"].get<std::string>();
  std::string kind = describeFile(*j);
  if (kind.empty()) return fmt::format("a JSON file (its format: {})", format);
  // "a corrections file (derive-corrections)" → "a corrections file (derive-corrections; its format: …)"
  if (kind.ends_with(')')) {
    kind.pop_back();
    return fmt::format("{}; its format: {})", kind, format);
  }
  return fmt::format("{} (its format: {})", kind, format);
}

std::string describeFileAt(const std::string& path) {
  auto file = RegularFile::open(path);
  if (!file) return {};
  std::string text(std::size_t{64} << 10, '\0');
  auto got = file->read(text.data(), text.size());
  if (!got) return {};
  text.resize(*got);
  if (looksLikeJson(text) && *got == (std::size_t{64} << 10)) {
    auto rest = file->readAll(kMaxInputFileBytes - text.size());
    if (!rest) return {};
    text += *rest;
  }
  return describeContent(text);
}

}  // namespace emcalign::io
