#pragma once
// The prompt loop's state in STATE_DIR/state.json (validation/prompt.hpp), inside validation.

#include <cmath>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/report/html.hpp"

namespace emcalign::validation::prompt {

/// A beam energy in a record: null for none (NaN).
inline io::Json energyJson(double e) { return std::isnan(e) ? io::Json(nullptr) : io::Json(e); }

/// A file of the watched directory as it was when taken or quarantined.
struct FileEntry {
  std::int64_t size = 0, mtimeNs = 0;
  std::uint64_t inode = 0;
  std::string sha256;              ///< of its content ("" when it could not be read)
  std::string status;              ///< "taken" or "quarantined"
  std::vector<std::int32_t> runs;  ///< taken: its runs
  std::string reason;              ///< quarantined: why
};

/// A run taken and not yet decided.
struct TakenRun {
  std::int32_t run = 0;
  std::string file;   ///< its file's name in the watched directory
  double beamEnergy;  ///< MeV; NaN: no selected event
  std::int64_t selected = 0;
};

struct State {
  std::string watchDir, tag;
  std::string conditions;                  ///< the database (its address without password) the decisions are in
  std::int64_t decided = 0;                ///< the groups that database held decided when last seen
  std::string decidedSha256;               ///< of those decisions as decisions.jsonl holds them
  io::Json model = io::Json::object();     ///< what the open runs' fills were made with
  std::map<std::string, FileEntry> files;  ///< by name
  std::vector<TakenRun> open;              ///< by run
  std::set<std::string> alerted;           ///< the alerts acknowledged by --on-alert (or with none)
  /// Alerts of what is kept nowhere else (a taken file rewritten), by key, until acknowledged.
  std::map<std::string, io::Json> pending;
  [[nodiscard]] io::Json toJson() const;
  static Result<State> parse(const io::Json& j, const std::string& source);
};

/// What STATE_DIR/status.html shows (prompt_status.cpp).
struct StatusInput {
  const State& state;
  const std::vector<std::string>& records;  ///< the decisions, as stored
  std::string tag, conditions;              ///< conditions: the address without password
  std::int64_t minEvents = 0;
  io::Json thresholds;  ///< {"sha256", "json"}
  std::string written;  ///< UTC
};
std::string statusPage(const StatusInput& in);
/// Its sections (the report's "Prompt calibration" too).
std::vector<report::html::Section> statusSections(const StatusInput& in);

}  // namespace emcalign::validation::prompt
