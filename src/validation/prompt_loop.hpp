#pragma once
// The prompt loop (validation/prompt.hpp) inside validation: its state directory's lock and the
// loop itself, whose steps live in prompt.cpp (start, database, alerts), prompt_files.cpp (the
// watched directory) and prompt_groups.cpp (the groups of runs and their decisions).

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/types.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "emcalign/validation/prompt.hpp"
#include "prompt_internal.hpp"

namespace emcalign::validation::prompt {

using io::Json;

/// A run's fill in STATE_DIR/runs.
inline std::string runFillName(std::int32_t run) { return fmt::format("run-{:09}.json", run); }

/// What stat says of a file: enough to see that it changed.
struct Seen {
  bool regular = false;
  bool dangling = false;  // a symbolic link to nothing
  std::int64_t size = 0, mtimeNs = 0;
  std::uint64_t inode = 0;
  bool operator==(const Seen& o) const {
    return regular == o.regular && dangling == o.dangling && size == o.size && mtimeNs == o.mtimeNs && inode == o.inode;
  }
  // A file as seen, for the sets of what was said of it once.
  [[nodiscard]] std::string key(const std::string& name) const {
    return fmt::format("{} {} {} {}", name, size, mtimeNs, inode);
  }
};

/// One closed group of the runs taken.
struct ClosedGroup {
  std::vector<TakenRun> runs;
  double beamEnergy = kNaN;
  std::int64_t selected = 0;
};

/// STATE_DIR's lock: held while the loop lives (a kill releases it); the file names the holder.
class StateLock {
 public:
  static Result<std::unique_ptr<StateLock>> take(const std::string& dir);
  ~StateLock();
  StateLock() = default;
  StateLock(const StateLock&) = delete;
  StateLock& operator=(const StateLock&) = delete;

 private:
  int fd_ = -1;
};

class Loop {
 public:
  Loop(const PromptOptions& o, Thresholds thresholds, CampaignModel model)
      : o_(o), thresholds_(std::move(thresholds)), model_(std::move(model)) {}

  Status start();

  // The database as the state directory names it: an SQLite file by its absolute path, a
  // server by its address without password.
  [[nodiscard]] std::string databaseIdentity() const;

  // What a run's fill depends on: the corrections (the depth, the parting plane) and the detector,
  // by content. Not σ_sys: it acts on the fit only.
  [[nodiscard]] Json modelIdentity() const;

  // One step; problems (the database away, a full disk) go to `summary` and the step ends.
  void step(PromptSummary& summary);

 private:
  using RunRange = std::pair<std::int64_t, std::int64_t>;

  [[nodiscard]] std::string watchDir() const {
    return std::filesystem::absolute(o_.watchDir).lexically_normal().string();
  }
  [[nodiscard]] std::string statePath() const { return (std::filesystem::path(o_.stateDir) / "state.json").string(); }
  [[nodiscard]] std::string fillPath(std::int32_t run) const {
    return (std::filesystem::path(o_.stateDir) / "runs" / runFillName(run)).string();
  }
  void say(const std::string& line) const {
    if (o_.say) o_.say(line);
  }
  void problem(PromptSummary& summary, const std::string& what) {
    summary.problems.push_back(what);
    db_.reset();  // a connection that failed is opened again
  }

  // ---- the database and the state directory (prompt.cpp)
  // The SQLite file it is open on, to see it removed or replaced while the loop runs.
  [[nodiscard]] std::optional<std::uint64_t> sqliteInode() const;

  Status connect();

  // This loop as the database records it: its host, process, the process's start and its state
  // directory.
  [[nodiscard]] Json thisLoop() const;

  // Whether the loop a record names still runs: on this host, its process with its start time;
  // in this state directory (whose lock this loop holds), no; elsewhere, it may.
  static bool stillRuns(const std::string& text, const Json& me);

  // The start time of a process (/proc/PID/stat, field 22), "" when there is none.
  static std::string startOf(std::int64_t pid);

  static std::string bootId();

  Status saveState();

  // The database is the record of what was decided: the runs of decided groups leave the
  // open ones, decisions.jsonl and quarantine.json are brought up to date.
  Status catchUp(PromptSummary&);

  // The SHA-256 of the decisions as decisions.jsonl holds them.
  [[nodiscard]] std::string decisionsDigest() const;

  Status writeDecisions();

  Status writeStatus();

  // Vetoes, quarantined files and rewritten files, each sent once acknowledged (at least once).
  Status sendAlerts(PromptSummary& summary);

  [[nodiscard]] bool pending(const std::string& key) const;

  // ---- the watched directory (prompt_files.cpp)
  // A file of the watched directory read whole, to be taken.
  struct Read {
    std::string name;
    Seen seen;
    std::string sha;
    std::map<std::int32_t, calib::ProfileFill> runs;
  };
  Status writeQuarantine();

  void quarantine(const std::string& name, const Seen& s, const std::string& sha, const std::string& reason,
                  PromptSummary& summary);

  // The settled files of the watched directory, taken in the order of their runs.
  Status takeFiles(PromptSummary& summary);

  // The names in the watched directory, sorted, without the temporaries of a writer.
  [[nodiscard]] Result<std::vector<std::string>> watchedNames() const;

  // One name of the watched directory looked at: quarantined (`changed`), or — settled, and new
  // or rewritten — read into `read`.
  void look(const std::string& rawName, std::vector<Read>& read, bool& changed, PromptSummary& summary);

  // A taken file seen changed: the same content (touched, copied back) is known again as it is
  // now; another is said once (quarantined, alerted) and never taken. Whether the state changed.
  bool retaken(const std::string& name, FileEntry& known, const Seen& now, const std::string& path);

  // Unchanged for --settle seconds: by its modification time, or — one in the future (a clock
  // ahead on the DAQ's machine) — since this loop first saw it as it is.
  bool settled(const std::string& name, const Seen& s);

  // One file read: refused (quarantined) when it repeats what was taken, holds a run older than
  // what is decided or two energies in a run; else its runs' fills are kept and its runs taken.
  Status take(const std::string& name, const Seen& seenAs, const std::string& sha,
              std::map<std::int32_t, calib::ProfileFill>& runs, PromptSummary& summary);

  // ---- the groups and their decisions (prompt_groups.cpp)
  Status decideClosed(PromptSummary& summary);

  // The calibration in force for a group's first run: the tag's latest IOV starting at or before
  // it (a running tag's IOVs are only appended: its last one, unless a promotion appended IOVs
  // since); none for an empty tag. And the last run of the tag's IOVs.
  struct InForce {
    std::optional<conddb::Iov> iov;
    std::optional<std::int64_t> lastRun;
  };
  Result<InForce> inForce(std::int64_t first);

  Status decide(const ClosedGroup& g, PromptSummary& summary);

  // The group's fit (when it has selected events and a fit), or in `outcome` why there is none;
  // an error when its fill cannot be had (the step's problem, tried again).
  Status fitForDecision(const ClosedGroup& g, std::int64_t group, GroupOutcome& outcome, std::optional<GroupFit>& fit);

  // The decision as the database and decisions.jsonl keep it.
  Json decisionJson(const ClosedGroup& g, std::int64_t group, const DecisionResult& d, const conddb::Payload* payload,
                    const std::optional<RunRange>& iov, const std::optional<GroupFit>& fit);

  // The decision stored in the database: the loop's state after it (a kill before finds it there,
  // catchUp), the fills of its runs removed, decisions.jsonl and the status page written.
  Status recordDecided(const ClosedGroup& g, std::int64_t group, const DecisionResult& d,
                       const conddb::Database::PromptRecord& record, const Json& j, const std::optional<RunRange>& iov,
                       PromptSummary& summary);

  // The merged fill of a group's runs, in run order: each run's kept fill, or — lost (removed,
  // damaged) — its file read again when it still has the content taken.
  Result<calib::ProfileFill> groupFill(const ClosedGroup& g, const calib::ProfileOptions& profile);

  Result<GroupFit> fitOf(const ClosedGroup& g, std::int64_t group, const std::vector<std::string>& files,
                         const CampaignModel& gm, const calib::ProfileFill& fill);

  const PromptOptions& o_;
  const std::string cwd_ = std::filesystem::current_path().string();  // where --on-alert runs: the loop's own
  Thresholds thresholds_;
  CampaignModel model_;
  std::unique_ptr<StateLock> lock_;
  std::unique_ptr<conddb::Database> db_;
  std::optional<std::uint64_t> dbInode_;
  State state_;
  std::vector<std::string> records_;
  std::map<std::string, std::string> decidedFiles_;  // file → SHA-256, of the decided groups
  std::int64_t lastDecidedRun_ = std::numeric_limits<std::int64_t>::min();
  std::int64_t lastIovRun_ = std::numeric_limits<std::int64_t>::min();
  std::vector<std::pair<std::string, Json>> pendingAlerts_;
  std::set<std::string> rewrittenSeen_;             // taken files rewritten, as seen when said
  std::map<std::string, std::int64_t> futureSeen_;  // files modified in the future: when first seen
  std::chrono::steady_clock::time_point nextAlertTry_{};
  double alertBackoff_ = 60.0;

 public:
  /// Set when the loop cannot go on (another loop writes the tag): not retried.
  std::string fatal_;
};

/// What stat says of `path` now (nullopt: it vanished).
std::optional<Seen> seen(const std::string& path);

/// docs/contract.md §13's grouping of the runs taken after the last decided group (by run): a
/// group closes when it reaches minEvents, or when the next run has another beam energy. The rest
/// is open.
std::vector<ClosedGroup> closedGroups(const std::vector<TakenRun>& runs, std::int64_t minEvents);

}  // namespace emcalign::validation::prompt
