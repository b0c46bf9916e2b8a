#pragma once
// Prompt calibration (docs/prompt.md, docs/contract.md §13): a loop beside the data taking. Event files
// arriving in a watched directory are taken once settled, their runs grouped per beam energy
// to --min-events selected events, each closed group fitted and decided — update, no-update or
// veto (validation/prompt_decision.hpp) — against the calibration in force, and stored as the
// next IOV of a running tag with its decision record.
//
// Nothing is lost and nothing decided twice, whatever kills the process (kill -9 included):
//   - a run taken is first kept as its profile fill in STATE_DIR/runs/RUN.json, then named in
//     STATE_DIR/state.json (replaced whole, through a temporary): a kill in between takes the
//     file again, giving the same fill;
//   - a group is a pure function of the runs taken after the last decided one, so a group
//     interrupted before it was stored is formed again the same;
//   - a decision is stored with its IOV in one transaction of the conditions database, which is
//     the record of what was decided: decisions.jsonl is brought up to it at every start, and
//     an alert not yet acknowledged is sent again (at least once).
// The payloads and decision records hold no time, so that a season interrupted by kills ends
// with the same tag and decisions as one run through.

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "emcalign/calib/sigma_sys.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/prompt_decision.hpp"

namespace emcalign::validation {

inline constexpr std::string_view kPromptStateFormat = "emcalign-prompt-state/1";

struct PromptOptions {
  std::string watchDir;     ///< the directory the event files arrive in
  std::string conditions;   ///< the database URI
  std::string tag;          ///< the running tag
  std::string thresholds;   ///< the thresholds file
  std::string stateDir;     ///< -o
  std::string corrections;  ///< a corrections file or grid (empty: the paper's model)
  std::string detector;     ///< a detector description (empty: the embedded one)
  std::int64_t minEvents = 50000;
  calib::SigmaSysChoice sigmaSys;
  double settleSeconds = 30.0;
  double pollSeconds = 10.0;
  bool once = false;
  std::string onAlert;  ///< a /bin/sh command; empty: none
  /// Checked between steps (and during the waits): the loop ends when it is set (SIGTERM).
  const std::atomic<bool>* stop = nullptr;
  /// Each line of what the loop does (taken files, decisions, alerts, waits).
  std::function<void(const std::string&)> say;
};

/// What a run of the loop (or of --once) did.
struct PromptSummary {
  int filesTaken = 0, quarantined = 0, decided = 0, alertsSent = 0;
  std::vector<std::string> problems;  ///< what could not be done (the database away, STATE_DIR full): --once exits 1
};

/// Checks the options (the thresholds read, the directories, the database reachable and the
/// tag running or made so), takes STATE_DIR's lock, then runs steps until `stop` (or one with
/// `once`). A step: catch up with the database, take the settled files, decide every closed
/// group. An error is returned for what prevents starting (another loop holds STATE_DIR, a tag
/// in another state, bad thresholds); trouble while running (the database away, a full disk)
/// is said and retried with back-off, or ends --once with `problems`.
Result<PromptSummary> runPrompt(const PromptOptions& options);

/// The prompt loop's state directory as HTML (its decisions against run with the thresholds,
/// the last decisions, the alerts): the "Prompt calibration" section of `emcalign report
/// --prompt STATE_DIR`. Fails naming the file when one of STATE_DIR's is missing or not the loop's.
Result<std::string> promptReportHtml(const std::string& stateDir);

/// Whether a file name is a temporary that is never taken (docs/contract.md §13: a leading '.', ".tmp",
/// ".part" at the end, ".tmp-" inside).
bool isPromptTemporary(std::string_view name);

}  // namespace emcalign::validation
