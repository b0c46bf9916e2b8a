// The prompt calibration loop (validation/prompt.hpp): its state, the watched directory, the
// grouping and the decisions stored.

#include "emcalign/validation/prompt.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include <fmt/format.h>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/clock.hpp"
#include "emcalign/core/secrets.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/subprocess.hpp"
#include "emcalign/core/utf8.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/io/strict_json.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "prompt_internal.hpp"

namespace emcalign::validation {

namespace fs = std::filesystem;
using io::Json;

namespace {

using prompt::FileEntry;
using prompt::State;
using prompt::TakenRun;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kAlertSeconds = 30;

bool sameEnergy(double a, double b) { return std::isnan(a) || std::isnan(b) || a == b; }

std::string runFillName(std::int32_t run) { return fmt::format("run-{:09}.json", run); }

// What stat says of a file: enough to see that it changed.
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

std::optional<Seen> seen(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    if (::lstat(path.c_str(), &st) != 0) return std::nullopt;  // vanished
    Seen link{false, true, static_cast<std::int64_t>(st.st_size),
              static_cast<std::int64_t>(st.st_mtim.tv_sec) * 1'000'000'000 + st.st_mtim.tv_nsec,
              static_cast<std::uint64_t>(st.st_ino)};
    return link;
  }
  return Seen{S_ISREG(st.st_mode), false, static_cast<std::int64_t>(st.st_size),
              static_cast<std::int64_t>(st.st_mtim.tv_sec) * 1'000'000'000 + st.st_mtim.tv_nsec,
              static_cast<std::uint64_t>(st.st_ino)};
}

std::int64_t nowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// One closed group of the runs taken.
struct ClosedGroup {
  std::vector<TakenRun> runs;
  double beamEnergy = kNaN;
  std::int64_t selected = 0;
};

// docs/contract.md §13's grouping of the runs taken after the last decided group (by run): a group closes
// when it reaches minEvents, or when the next run has another beam energy. The rest is open.
std::vector<ClosedGroup> closedGroups(const std::vector<TakenRun>& runs, std::int64_t minEvents) {
  std::vector<ClosedGroup> closed;
  ClosedGroup current;
  for (const TakenRun& r : runs) {
    if (!current.runs.empty() && !sameEnergy(current.beamEnergy, r.beamEnergy)) {
      closed.push_back(std::move(current));
      current = {};
    }
    current.runs.push_back(r);
    if (std::isnan(current.beamEnergy)) current.beamEnergy = r.beamEnergy;
    current.selected += r.selected;
    if (current.selected >= minEvents) {
      closed.push_back(std::move(current));
      current = {};
    }
  }
  return closed;
}

// STATE_DIR's lock: held while the loop lives (a kill releases it); the file names the holder.
class StateLock {
 public:
  static Result<std::unique_ptr<StateLock>> take(const std::string& dir) {
    const std::string path = (fs::path(dir) / "lock").string();
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (fd < 0) return Error{fmt::format("{}: cannot open the lock: {}", path, std::strerror(errno))};
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      char holder[512] = {};
      const ssize_t n = ::pread(fd, holder, sizeof holder - 1, 0);
      ::close(fd);
      return Error{fmt::format(
          "{}: another prompt loop holds this state directory ({}): one loop per tag and state directory; stop "
          "it first (SIGTERM)",
          dir, n > 0 ? printable(std::string_view(holder, static_cast<std::size_t>(n))) : std::string("?"))};
    }
    char host[256] = {};
    ::gethostname(host, sizeof host - 1);
    const std::string who = fmt::format("pid {} on {} since {}", ::getpid(), host, utcNow());
    if (::ftruncate(fd, 0) == 0) {
      [[maybe_unused]] const ssize_t written = ::pwrite(fd, who.data(), who.size(), 0);
    }
    auto lock = std::make_unique<StateLock>();
    lock->fd_ = fd;
    return lock;
  }
  ~StateLock() {
    if (fd_ >= 0) ::close(fd_);
  }
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

  Status start() {
    std::error_code ec;
    fs::create_directories(fs::path(o_.stateDir) / "runs", ec);
    if (ec) return Error{fmt::format("{}: cannot create the state directory: {}", o_.stateDir, ec.message())};
    auto lock = StateLock::take(o_.stateDir);
    if (!lock) return lock.error();
    lock_ = std::move(*lock);
    const std::string path = statePath();
    if (fs::exists(path, ec)) {
      auto text = io::readOwnOutput(path);
      if (!text) return text.error();
      auto j = io::parseJson(*text, path);
      if (!j) return j.error();
      auto s = State::parse(*j, path);
      if (!s) return s.error();
      if (s->watchDir != watchDir() || s->tag != o_.tag) {
        return Error{
            fmt::format("{}: this state directory is the loop's of {} into tag {}, not of {} into tag {}: "
                        "one state directory per watched directory and tag",
                        o_.stateDir, s->watchDir, s->tag, watchDir(), o_.tag)};
      }
      if (s->conditions != databaseIdentity()) {
        return Error{
            fmt::format("{}: this state directory's decisions are in {}, not {}: one state directory per "
                        "database and tag (a new database needs a new state directory)",
                        o_.stateDir, s->conditions, databaseIdentity())};
      }
      // The open runs' fills were made with one model: a group is fitted with that one.
      if (!s->open.empty() && s->model != modelIdentity()) {
        return Error{fmt::format(
            "{}: the {} runs taken and not yet decided were read with {}, not {}: start again with the same "
            "--corrections and --detector until their group is decided",
            o_.stateDir, s->open.size(), s->model.dump(), modelIdentity().dump())};
      }
      state_ = std::move(*s);
    } else {
      state_.watchDir = watchDir();
      state_.tag = o_.tag;
      state_.conditions = databaseIdentity();
    }
    state_.model = modelIdentity();
    // The thresholds of the decisions to come, beside them (the report reads them there).
    const std::string kept = (fs::path(o_.stateDir) / "thresholds.json").string();
    if (auto before = io::readOwnOutput(kept); before) {
      const Json was = Json::parse(*before, nullptr, false);
      if (was != thresholds_.json) {
        say(fmt::format("the thresholds changed (now {}…): the decisions to come name them",
                        thresholds_.sha256.substr(0, 12)));
      }
    }
    return io::writeFileIn(o_.stateDir, "thresholds.json", thresholds_.json.dump(1) + "\n");
  }

  // The database as the state directory names it: an SQLite file by its absolute path, a
  // server by its address without password.
  [[nodiscard]] std::string databaseIdentity() const {
    const std::string file = conddb::sqliteFileOf(o_.conditions);
    if (!file.empty()) return "sqlite:" + fs::absolute(file).lexically_normal().string();
    return core::withoutAnyPassword(o_.conditions);
  }

  // What a run's fill depends on: the corrections (the depth, the parting plane) and the detector,
  // by content. Not σ_sys: it acts on the fit only.
  [[nodiscard]] Json modelIdentity() const {
    std::string detector = "embedded";
    if (!o_.detector.empty()) {
      auto sha = sha256OfFile(o_.detector);
      detector = sha ? *sha : o_.detector;
    }
    return {{"corrections_sha256", model_.correctionsSha256}, {"detector_sha256", detector}};
  }

  // One step; problems (the database away, a full disk) go to `summary` and the step ends.
  void step(PromptSummary& summary) {
    if (Status s = connect(); !s) return problem(summary, s.error().message);
    if (Status s = catchUp(summary); !s) return problem(summary, s.error().message);
    if (Status s = takeFiles(summary); !s) return problem(summary, s.error().message);
    if (Status s = decideClosed(summary); !s) return problem(summary, s.error().message);
    if (Status s = sendAlerts(summary); !s) return problem(summary, s.error().message);
  }

 private:
  [[nodiscard]] std::string watchDir() const { return fs::absolute(o_.watchDir).lexically_normal().string(); }
  [[nodiscard]] std::string statePath() const { return (fs::path(o_.stateDir) / "state.json").string(); }
  [[nodiscard]] std::string fillPath(std::int32_t run) const {
    return (fs::path(o_.stateDir) / "runs" / runFillName(run)).string();
  }
  void say(const std::string& line) const {
    if (o_.say) o_.say(line);
  }
  void problem(PromptSummary& summary, const std::string& what) {
    summary.problems.push_back(what);
    db_.reset();  // a connection that failed is opened again
  }

  // The SQLite file it is open on, to see it removed or replaced while the loop runs.
  [[nodiscard]] std::optional<std::uint64_t> sqliteInode() const {
    const std::string file = conddb::sqliteFileOf(o_.conditions);
    if (file.empty()) return std::nullopt;
    struct stat st {};
    if (::stat(file.c_str(), &st) != 0) return 0;
    return static_cast<std::uint64_t>(st.st_ino);
  }

  Status connect() {
    if (db_) {
      if (sqliteInode() == dbInode_) return {};
      db_.reset();
      return Error{fmt::format("{}: the database file was removed or replaced while the loop ran", o_.conditions)};
    }
    // A database this state directory has decisions in is never made anew (it went away).
    if (state_.decided > 0 && sqliteInode() == std::optional<std::uint64_t>(0)) {
      fatal_ = fmt::format(
          "{}: the database this state directory has {} decisions in is gone: restore it (nothing "
          "was made in its place)",
          o_.conditions, state_.decided);
      return Error{fatal_};
    }
    // A short wait for another writer's lock: the step ends, is said, and is tried again.
    auto db = conddb::Database::open(o_.conditions, conddb::IfMissing::Create, 3000);
    if (!db) return db.error();
    if (Status s = (*db)->makeRunning(o_.tag, "prompt calibration (emcalign prompt)"); !s) {
      // A tag in another state is refused for good; anything else (the server went away) is tried again.
      if (auto t = (*db)->tag(o_.tag); t && t->has_value() && (*t)->state != conddb::TagState::Running) {
        fatal_ = s.error().message;
      }
      return s;
    }
    // One loop per tag, whatever its state directory: the second names the first.
    const Json me = thisLoop();
    auto other = (*db)->claimPrompt(o_.tag, me.dump(), [&](const std::string& text) { return stillRuns(text, me); });
    if (!other) return other.error();
    if (!other->empty()) {
      fatal_ = fmt::format("{}: tag {} is written by another prompt loop ({}): one loop per tag; stop it first",
                           (*db)->uri(), o_.tag, *other);
      return Error{fatal_};
    }
    db_ = std::move(*db);
    dbInode_ = sqliteInode();
    return {};
  }

  // This loop as the database records it: its host, process, the process's start and its state
  // directory.
  [[nodiscard]] Json thisLoop() const {
    char host[256] = {};
    ::gethostname(host, sizeof host - 1);
    return {{"host", host},
            {"boot", bootId()},
            {"pid", ::getpid()},
            {"start", startOf(::getpid())},
            {"state_dir", fs::absolute(o_.stateDir).lexically_normal().string()}};
  }

  // Whether the loop a record names still runs: on this host, its process with its start time;
  // in this state directory (whose lock this loop holds), no; elsewhere, it may.
  static bool stillRuns(const std::string& text, const Json& me) {
    const Json other = Json::parse(text, nullptr, false);
    if (!other.is_object()) return false;
    if (other.value("state_dir", std::string()) == me["state_dir"].get<std::string>()) return false;
    if (other.value("host", std::string()) != me["host"].get<std::string>()) return true;
    if (other.value("boot", std::string()) != me["boot"].get<std::string>()) return false;
    const auto pid = other.value("pid", std::int64_t{-1});
    return pid > 0 && startOf(pid) == other.value("start", std::string("?"));
  }

  // The start time of a process (/proc/PID/stat, field 22), "" when there is none.
  static std::string startOf(std::int64_t pid) {
    std::ifstream in(fmt::format("/proc/{}/stat", pid));
    std::string text;
    std::getline(in, text);
    const auto close = text.rfind(')');
    if (close == std::string::npos || close + 2 > text.size()) return "";
    std::istringstream fields(text.substr(close + 2));
    std::string f;
    for (int k = 3; k <= 22 && (fields >> f); ++k) {
    }
    return f;
  }

  static std::string bootId() {
    std::ifstream in("/proc/sys/kernel/random/boot_id");
    std::string id;
    std::getline(in, id);
    return id;
  }

  Status saveState() { return io::writeFileIn(o_.stateDir, "state.json", state_.toJson().dump(1) + "\n"); }

  // The database is the record of what was decided: the runs of decided groups leave the
  // open ones, decisions.jsonl and quarantine.json are brought up to date.
  Status catchUp(PromptSummary&) {
    auto records = db_->promptRecords(o_.tag);
    if (!records) return records.error();
    std::string seen;
    for (std::int64_t k = 0; k < state_.decided && k < static_cast<std::int64_t>(records->size()); ++k) {
      seen += (*records)[static_cast<std::size_t>(k)] + "\n";
    }
    if (static_cast<std::int64_t>(records->size()) >= state_.decided && !state_.decidedSha256.empty() &&
        sha256(seen) != state_.decidedSha256) {
      fatal_ = fmt::format(
          "{}: tag {}'s first {} decisions are not those this state directory saw: another database at the same "
          "place? Not going on (nothing changed)",
          db_->uri(), o_.tag, state_.decided);
      return Error{fatal_};
    }
    if (static_cast<std::int64_t>(records->size()) < state_.decided) {
      fatal_ = fmt::format(
          "{}: tag {} holds {} decided groups, this state directory has seen {}: another database, or one restored "
          "from an older copy? Not going on: the runs taken since would be lost (restore the database, or start a "
          "new tag with a new state directory)",
          db_->uri(), o_.tag, records->size(), state_.decided);
      return Error{fatal_};
    }
    records_ = std::move(*records);
    lastDecidedRun_ = std::numeric_limits<std::int64_t>::min();
    for (const std::string& r : records_) {
      const Json j = Json::parse(r, nullptr, false);
      if (j.is_object() && j.contains("runs") && j["runs"].is_array() && j["runs"].size() == 2) {
        lastDecidedRun_ = std::max(lastDecidedRun_, j["runs"][1].get<std::int64_t>());
      }
      if (j.is_object() && j.contains("files") && j["files"].is_object()) {
        for (const auto& [name, sha] : j["files"].items()) {
          if (sha.is_string()) decidedFiles_[name] = sha.get<std::string>();
        }
      }
    }
    auto iovs = db_->iovs(o_.tag);
    if (!iovs) return iovs.error();
    lastIovRun_ = iovs->empty() ? std::numeric_limits<std::int64_t>::min() : iovs->back().lastRun;
    const auto before = state_.open.size();
    std::erase_if(state_.open, [&](const TakenRun& r) { return r.run <= lastDecidedRun_; });
    if (state_.open.size() != before || state_.decided != static_cast<std::int64_t>(records_.size()) ||
        state_.decidedSha256 != decisionsDigest()) {
      state_.decided = static_cast<std::int64_t>(records_.size());
      state_.decidedSha256 = decisionsDigest();
      if (Status s = saveState(); !s) return s;
    }
    return writeDecisions();
  }

  // The SHA-256 of the decisions as decisions.jsonl holds them.
  [[nodiscard]] std::string decisionsDigest() const {
    std::string text;
    for (const std::string& r : records_) text += r + "\n";
    return sha256(text);
  }

  Status writeDecisions() {
    std::string text;
    for (const std::string& r : records_) text += r + "\n";
    const std::string path = (fs::path(o_.stateDir) / "decisions.jsonl").string();
    if (auto now = io::readOwnOutput(path); now && *now == text) return {};
    return io::writeFileIn(o_.stateDir, "decisions.jsonl", text);
  }

  Status writeQuarantine() {
    Json list = Json::array();
    for (const auto& [name, f] : state_.files) {
      if (f.status == "quarantined") list.push_back({{"file", name}, {"reason", f.reason}});
    }
    return io::writeFileIn(o_.stateDir, "quarantine.json", list.dump(1) + "\n");
  }

  void quarantine(const std::string& name, const Seen& s, const std::string& sha, const std::string& reason,
                  PromptSummary& summary) {
    FileEntry& f = state_.files[name];
    f = {s.size, s.mtimeNs, s.inode, sha, "quarantined", {}, core::withoutAnyPassword(printable(reason))};
    ++summary.quarantined;
    say(fmt::format("{}: quarantined: {}", printable(name), f.reason));
  }

  // The settled files of the watched directory, taken in the order of their runs.
  Status takeFiles(PromptSummary& summary) {
    std::error_code ec;
    std::vector<std::string> names;
    for (fs::directory_iterator it(o_.watchDir, ec), end; !ec && it != end; it.increment(ec)) {
      const std::string name = it->path().filename().string();
      if (!isPromptTemporary(name) && !io::isTemporaryName(name)) names.push_back(name);
    }
    if (ec) return Error{fmt::format("{}: cannot list the directory: {}", o_.watchDir, ec.message())};
    std::sort(names.begin(), names.end());
    struct Read {
      std::string name;
      Seen seen;
      std::string sha;
      std::map<std::int32_t, calib::ProfileFill> runs;
    };
    std::vector<Read> read;
    bool changed = false;
    for (const std::string& rawName : names) {
      if (o_.stop != nullptr && o_.stop->load()) break;  // SIGTERM: the rest at the next start
      const std::string path = (fs::path(o_.watchDir) / rawName).string();
      const auto before = seen(path);
      if (!before) continue;  // vanished
      // Named in JSON (state, decisions, quarantine): a name that is not UTF-8 is never read.
      const bool utf8 = isValidUtf8(rawName);
      const std::string name = utf8 ? rawName : printable(rawName) + " (a name that is not UTF-8)";
      const auto known = state_.files.find(name);
      if (known != state_.files.end() && known->second.size == before->size &&
          known->second.mtimeNs == before->mtimeNs && known->second.inode == before->inode) {
        continue;  // as it was taken or quarantined
      }
      if (!before->regular || !utf8) {
        if (known == state_.files.end()) {
          quarantine(name, *before, "",
                     !utf8              ? "its name is not UTF-8 text (the decisions name files in JSON): rename it"
                     : before->dangling ? "a symbolic link to nothing: never read"
                                        : "not a regular file (a directory, a FIFO, a device): never read",
                     summary);
          changed = true;
        }
        continue;
      }
      if (!settled(name, *before)) continue;
      if (rewrittenSeen_.contains(before->key(name))) {
        continue;  // a rewrite said already
      }
      if (known != state_.files.end() && known->second.status == "taken") {
        auto sha = sha256OfFile(path);
        // Taken already: the content taken is kept; a rewrite is said once (quarantined, alerted).
        if (sha && *sha == known->second.sha256) {
          known->second.size = before->size;
          known->second.mtimeNs = before->mtimeNs;
          known->second.inode = before->inode;
          changed = true;
          continue;
        }
        rewrittenSeen_.insert(before->key(name));
        const std::string rewritten = name + " rewritten";
        if (!state_.alerted.contains(rewritten + (sha ? *sha : std::string()))) {
          say(
              fmt::format("{}: rewritten after it was taken (runs {}): the content taken is kept; the new one is "
                          "not taken",
                          printable(name), fmt::join(known->second.runs, ", ")));
          // Kept in the state (saved with this step's files): sent at least once, after a kill too.
          state_.pending[rewritten + (sha ? *sha : std::string())] =
              Json{{"file", name},
                   {"reason", fmt::format("rewritten after it was taken (runs {}): the content taken is kept, the new "
                                          "one is not taken",
                                          fmt::join(known->second.runs, ", "))}};
          changed = true;
        }
        continue;
      }
      // Read first (a file that is no event file is refused at its first bytes), then its digest.
      auto runs = calib::fillProfilesByRun(path, model_.depthAtEnergy(), model_.selection, model_.profile);
      auto sha = runs ? sha256OfFile(path) : Result<std::string>(std::string());
      const auto after = seen(path);
      if (!after || !(*after == *before)) continue;  // written meanwhile: not settled
      if (!runs || !sha) {
        quarantine(name, *before, sha && !sha->empty() ? *sha : std::string(),
                   !runs ? runs.error().message : sha.error().message, summary);
        changed = true;
        continue;
      }
      read.push_back({name, *before, *sha, std::move(*runs)});
    }
    // In the order of their runs: a group is formed the same whatever batch a file came in.
    std::sort(read.begin(), read.end(), [](const Read& a, const Read& b) {
      const std::int32_t ra = a.runs.empty() ? 0 : a.runs.begin()->first;
      const std::int32_t rb = b.runs.empty() ? 0 : b.runs.begin()->first;
      return ra != rb ? ra < rb : a.name < b.name;
    });
    for (Read& r : read) {
      if (Status s = take(r.name, r.seen, r.sha, r.runs, summary); !s) return s;
      changed = true;
    }
    const std::string page = (fs::path(o_.stateDir) / "status.html").string();
    if (!changed && fs::exists(page, ec)) return {};
    if (Status s = saveState(); !s) return s;
    if (Status s = writeQuarantine(); !s) return s;
    return writeStatus();
  }

  // Unchanged for --settle seconds: by its modification time, or — one in the future (a clock
  // ahead on the DAQ's machine) — since this loop first saw it as it is.
  bool settled(const std::string& name, const Seen& s) {
    const std::int64_t now = nowNs(), settle = static_cast<std::int64_t>(o_.settleSeconds * 1e9);
    if (s.mtimeNs <= now) return now - s.mtimeNs >= settle;
    const std::string key = s.key(name);
    auto [it, fresh] = futureSeen_.try_emplace(key, now);
    if (fresh) {
      say(
          fmt::format("{}: modified in the future ({:.0f} s ahead: a clock ahead?): taken once unchanged for --settle "
                      "seconds as this loop sees it",
                      printable(name), static_cast<double>(s.mtimeNs - now) / 1e9));
    }
    return now - it->second >= settle;
  }

  // One file read: refused (quarantined) when it repeats what was taken, holds a run older than
  // what is decided or two energies in a run; else its runs' fills are kept and its runs taken.
  Status take(const std::string& name, const Seen& seenAs, const std::string& sha,
              std::map<std::int32_t, calib::ProfileFill>& runs, PromptSummary& summary) {
    // Decided already (a state directory started afresh on the tag): known, nothing to do.
    if (auto it = decidedFiles_.find(name); it != decidedFiles_.end() && it->second == sha) {
      std::vector<std::int32_t> list;
      list.reserve(runs.size());
      for (const auto& [run, fill] : runs) list.push_back(run);
      state_.files[name] = {seenAs.size, seenAs.mtimeNs, seenAs.inode, sha, "taken", list, ""};
      say(fmt::format("{}: decided already (the tag's decisions name it): not taken again", printable(name)));
      return {};
    }
    for (const auto& [other, f] : state_.files) {
      if (f.status == "taken" && f.sha256 == sha) {
        quarantine(name, seenAs, sha, fmt::format("the same content as {}, taken already", other), summary);
        return {};
      }
    }
    std::map<std::int32_t, std::string> takenFrom;
    for (const auto& [other, f] : state_.files) {
      if (f.status == "taken") {
        for (std::int32_t run : f.runs) takenFrom[run] = other;
      }
    }
    const std::int64_t covered = std::max(lastDecidedRun_, lastIovRun_);
    for (const auto& [run, fill] : runs) {
      std::string why;
      if (auto it = takenFrom.find(run); it != takenFrom.end()) {
        why = fmt::format("run {} was taken already from {}: a run is taken once", run, it->second);
      } else if (run <= covered) {
        why = fmt::format(
            "run {} is not after the runs decided already (up to run {}): it is not inserted into a decided "
            "group (its run is covered by the tag's IOV there)",
            run, covered);
      } else if (fill.beamEnergies.size() > 1) {
        why = fmt::format("run {} holds events of {} beam energies", run, fill.beamEnergies.size());
      }
      if (!why.empty()) {
        quarantine(name, seenAs, sha, why, summary);
        return {};
      }
    }
    if (runs.empty()) {
      quarantine(name, seenAs, sha, "no event", summary);
      return {};
    }
    // The fills first, then the state naming them: a kill between takes the file again.
    std::vector<std::int32_t> list;
    for (const auto& [run, fill] : runs) {
      if (Status s =
              io::writeFileIn((fs::path(o_.stateDir) / "runs").string(), runFillName(run), fill.state().dump() + "\n");
          !s) {
        return s;
      }
      list.push_back(run);
    }
    state_.files[name] = {seenAs.size, seenAs.mtimeNs, seenAs.inode, sha, "taken", list, ""};
    for (const auto& [run, fill] : runs) {
      const double energy = fill.beamEnergies.empty() ? kNaN : *fill.beamEnergies.begin();
      const std::int64_t selected = fill.cutFlow.events.back();
      state_.open.push_back({run, name, energy, selected});
      say(fmt::format("{}: run {} taken ({}, {} selected events{})", printable(name), run,
                      std::isnan(energy) ? std::string("no beam energy") : fmt::format("{:g} MeV", energy), selected,
                      selected == 0 ? fmt::format(" of {} read: covered by its group's IOV, adds nothing to its fit",
                                                  fill.cutFlow.events.front())
                                    : std::string()));
    }
    std::sort(state_.open.begin(), state_.open.end(),
              [](const TakenRun& a, const TakenRun& b) { return a.run < b.run; });
    ++summary.filesTaken;
    return {};
  }

  Status decideClosed(PromptSummary& summary) {
    for (;;) {
      const auto groups = closedGroups(state_.open, o_.minEvents);
      if (groups.empty()) return {};
      if (Status s = decide(groups.front(), summary); !s) return s;
    }
  }

  // The calibration in force for a group's first run: the tag's latest IOV starting at or before
  // it (a running tag's IOVs are only appended: its last one, unless a promotion appended IOVs
  // since); none for an empty tag. And the last run of the tag's IOVs.
  struct InForce {
    std::optional<conddb::Iov> iov;
    std::optional<std::int64_t> lastRun;
  };
  Result<InForce> inForce(std::int64_t first) {
    auto iovs = db_->iovs(o_.tag);
    if (!iovs) return iovs.error();
    InForce f;
    for (const conddb::Iov& i : *iovs) {
      if (i.firstRun <= first) f.iov = i;
    }
    if (!iovs->empty()) f.lastRun = iovs->back().lastRun;
    return f;
  }

  Status decide(const ClosedGroup& g, PromptSummary& summary) {
    const auto group = static_cast<std::int64_t>(records_.size());
    const std::int32_t first = g.runs.front().run, last = g.runs.back().run;
    auto force = inForce(first);
    if (!force) return force.error();
    std::optional<conddb::Payload> forcePayload;
    if (force->iov) {
      auto p = db_->payload(force->iov->payload);
      if (!p) return p.error();
      forcePayload = std::move(*p);
    }
    GroupOutcome outcome;
    outcome.selected = g.selected;
    outcome.minEvents = o_.minEvents;
    if (forcePayload) outcome.inForce = forcePayload->values();
    std::optional<GroupFit> fit;
    std::vector<std::string> files;
    // By name, as found in the watched directory, with their SHA-256: the same payload wherever
    // that directory is (an interrupted season against one run through elsewhere).
    for (const TakenRun& r : g.runs) {
      if (std::find(files.begin(), files.end(), r.file) == files.end()) files.push_back(r.file);
    }
    if (g.selected == 0 || std::isnan(g.beamEnergy)) {
      outcome.fitProblem = "no selected event";
    } else {
      // A fill that cannot be had is this step's problem (tried again), never the group's veto.
      auto gm = model_.at(g.beamEnergy);
      auto fill = gm ? groupFill(g, gm->profile) : Result<calib::ProfileFill>(gm.error());
      if (!fill && gm) return fill.error();
      auto f = fill ? fitOf(g, group, files, *gm, *fill) : Result<GroupFit>(fill.error());
      if (f) {
        outcome.status = f->result.status;
        outcome.pValue = f->result.pValue;
        outcome.fitted = f->payload.values();
        fit = std::move(*f);
      } else {
        outcome.fitProblem = f.error().message;
      }
    }
    const DecisionResult d = validation::decide(thresholds_, outcome);
    conddb::Database::PromptRecord record;
    record.group = group;
    record.thresholdsSha256 = thresholds_.sha256;
    record.thresholds = thresholds_.json.dump();
    const conddb::Payload* payload = d.decision == Decision::Update ? &fit->payload
                                     : forcePayload                 ? &*forcePayload
                                                                    : nullptr;
    std::optional<std::pair<std::int64_t, std::int64_t>> iov;
    // From the run after the tag's last IOV: none when a promotion covered the group's runs.
    if (payload != nullptr && (!force->lastRun || last > *force->lastRun)) {
      iov = {force->lastRun ? *force->lastRun + 1 : first, last};
      record.iov = conddb::Database::NewIov{iov->first, iov->second, *payload};
    }
    Json parameters = Json::object();
    for (const ParameterDecision& p : d.parameters) {
      parameters[std::string(name(p.parameter))] = {{"fitted", io::numberOrNull(p.fitted)},
                                                    {"error", io::numberOrNull(p.error)},
                                                    {"in_force", io::numberOrNull(p.inForce)},
                                                    {"change", io::numberOrNull(p.change)},
                                                    {"significance", io::numberOrNull(p.significance)}};
    }
    Json names = Json::object();  // the files of its runs, with their SHA-256
    for (const TakenRun& r : g.runs) names[r.file] = state_.files[r.file].sha256;
    const Json j = {{"group", group},
                    {"runs", {first, last}},
                    {"beam_energy_mev", prompt::energyJson(g.beamEnergy)},
                    {"selected_events", g.selected},
                    {"decision", name(d.decision)},
                    {"reasons", d.reasons},
                    {"parameters", parameters},
                    {"payload", payload != nullptr ? Json(payload->hash()) : Json(nullptr)},
                    {"iov", iov ? Json{iov->first, iov->second} : Json(nullptr)},
                    {"fit_status", fit ? Json(std::string(emcalign::name(fit->result.status))) : Json(nullptr)},
                    {"thresholds_sha256", thresholds_.sha256},
                    {"min_events", o_.minEvents},
                    {"files", names}};
    record.decision = j.dump();
    if (Status s = db_->appendPrompt(o_.tag, record); !s) return s;
    records_.push_back(record.decision);
    state_.decided = static_cast<std::int64_t>(records_.size());
    state_.decidedSha256 = decisionsDigest();
    lastDecidedRun_ = last;
    if (iov) lastIovRun_ = iov->second;
    ++summary.decided;
    say(fmt::format("group {} (runs {}-{}, {}, {} selected events): {} — {}", group, first, last,
                    std::isnan(g.beamEnergy) ? std::string("no beam energy") : fmt::format("{:g} MeV", g.beamEnergy),
                    g.selected, name(d.decision), fmt::join(d.reasons, "; ")));
    if (d.decision == Decision::Veto) pendingAlerts_.push_back({fmt::format("group {}", group), j});
    // The state after the database: a kill between finds the group decided there (catchUp).
    std::erase_if(state_.open, [&](const TakenRun& r) { return r.run <= last; });
    if (Status s = saveState(); !s) return s;
    for (const TakenRun& r : g.runs) {
      std::error_code ec;
      fs::remove(fillPath(r.run), ec);
    }
    if (Status s = writeDecisions(); !s) return s;
    return writeStatus();
  }

  Status writeStatus() {
    const prompt::StatusInput in{state_,       records_,
                                 o_.tag,       db_ ? db_->uri() : std::string(),
                                 o_.minEvents, Json{{"sha256", thresholds_.sha256}, {"json", thresholds_.json}},
                                 utcNow()};
    return io::writeFileIn(o_.stateDir, "status.html", prompt::statusPage(in));
  }

  // The merged fill of a group's runs, in run order: each run's kept fill, or — lost (removed,
  // damaged) — its file read again when it still has the content taken.
  Result<calib::ProfileFill> groupFill(const ClosedGroup& g, const calib::ProfileOptions& profile) {
    calib::ProfileFill fill = calib::ProfileFill::empty(profile);
    for (const TakenRun& r : g.runs) {
      auto text = io::readOwnOutput(fillPath(r.run));
      auto j = text ? io::parseJson(*text, fillPath(r.run)) : Result<Json>(text.error());
      auto f = j ? calib::ProfileFill::restore(*j, profile, fillPath(r.run)) : Result<calib::ProfileFill>(j.error());
      if (!f) {
        const std::string path = (fs::path(o_.watchDir) / r.file).string();
        auto sha = sha256OfFile(path);
        if (!sha || *sha != state_.files[r.file].sha256) {
          return Error{
              fmt::format("run {}: its kept fill is lost ({}) and its file {} no longer has the content "
                          "taken: restore either, or remove the run from {} (it is then never decided)",
                          r.run, f.error().message, r.file, statePath())};
        }
        auto again = calib::fillProfilesByRun(path, model_.depthAtEnergy(), model_.selection, profile);
        if (!again || !again->contains(r.run)) {
          return Error{fmt::format("run {}: its kept fill is lost and {} cannot be read again", r.run, r.file)};
        }
        say(fmt::format("run {}: its kept fill was lost: read again from {}", r.run, printable(r.file)));
        f = std::move(again->at(r.run));
      }
      fill.merge(*f);
    }
    return fill;
  }

  Result<GroupFit> fitOf(const ClosedGroup& g, std::int64_t group, const std::vector<std::string>& files,
                         const CampaignModel& gm, const calib::ProfileFill& fill) {
    std::map<std::string, std::string> digests;
    CampaignGroup cg;
    cg.index = static_cast<int>(group);
    cg.iovFirst = g.runs.front().run;
    cg.iovLast = g.runs.back().run;
    cg.beamEnergy = g.beamEnergy;
    cg.selected = g.selected;
    cg.isShort = g.selected < o_.minEvents;
    cg.files = files;
    for (const TakenRun& r : g.runs) {
      cg.runs.push_back(r.run);
      digests[r.file] = state_.files[r.file].sha256;
    }
    const Json origin = {{"prompt",
                          {{"group", group},
                           {"runs", cg.runs},
                           {"beam_energy_mev", g.beamEnergy},
                           {"selected_events", g.selected},
                           {"min_events", o_.minEvents},
                           {"short", cg.isShort}}}};
    return fitGroup(cg, fill, gm, digests, origin);
  }

  // Vetoes, quarantined files and rewritten files, each sent once acknowledged (at least once).
  Status sendAlerts(PromptSummary& summary) {
    // Every veto of the tag and every quarantined file not acknowledged yet (after a kill too).
    for (const std::string& r : records_) {
      const Json j = Json::parse(r, nullptr, false);
      if (j.is_object() && j.value("decision", std::string()) == "veto") {
        const std::string key = fmt::format("group {}", j.value("group", std::int64_t{-1}));
        if (!state_.alerted.contains(key) && !pending(key)) pendingAlerts_.push_back({key, j});
      }
    }
    for (const auto& [key, record] : state_.pending) {
      if (!state_.alerted.contains(key) && !pending(key)) pendingAlerts_.push_back({key, record});
    }
    for (const auto& [name, f] : state_.files) {
      const std::string key = fmt::format("{} {} {}", name, f.size, f.mtimeNs);
      if (f.status == "quarantined" && !state_.alerted.contains(key) && !pending(key)) {
        pendingAlerts_.push_back({key, Json{{"file", name}, {"reason", f.reason}}});
      }
    }
    // A command that failed is tried again later, less and less often (not at every step).
    const bool wait = !o_.once && std::chrono::steady_clock::now() < nextAlertTry_;
    std::vector<std::pair<std::string, Json>> left;
    bool failed = false;
    for (const auto& [key, record] : pendingAlerts_) {
      if (state_.alerted.contains(key)) continue;
      if (!o_.onAlert.empty()) {
        if (wait || failed || (o_.stop != nullptr && o_.stop->load())) {
          left.push_back({key, record});
          continue;
        }
        // Its output goes nowhere (a command that prints without end, or leaves a child holding it).
        const core::Ran ran = core::runCapturing({"/bin/sh", "-c", "exec >/dev/null 2>&1\n" + o_.onAlert}, cwd_,
                                                 record.dump() + "\n", kAlertSeconds, o_.stop);
        if (!ran.succeeded()) {
          failed = true;
          say(fmt::format("--on-alert for {}: {} (sent again in {:g} s, or at the next start)", key, ran.outcome(),
                          alertBackoff_));
          left.push_back({key, record});
          continue;
        }
        ++summary.alertsSent;
      }
      state_.alerted.insert(key);
    }
    if (failed) {
      nextAlertTry_ =
          std::chrono::steady_clock::now() +
          std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(alertBackoff_));
      alertBackoff_ = std::min(alertBackoff_ * 2.0, 3600.0);
    } else if (!wait) {
      alertBackoff_ = 60.0;
    }
    pendingAlerts_ = std::move(left);
    std::erase_if(state_.pending, [&](const auto& p) { return state_.alerted.contains(p.first); });
    if (Status s = saveState(); !s) return s;
    if (failed && o_.once) return Error{"--on-alert failed: the alerts not sent are sent by the next run"};
    return {};
  }

  [[nodiscard]] bool pending(const std::string& key) const {
    return std::any_of(pendingAlerts_.begin(), pendingAlerts_.end(), [&](const auto& p) { return p.first == key; });
  }

  const PromptOptions& o_;
  const std::string cwd_ = fs::current_path().string();  // where --on-alert runs: the loop's own
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

// Sleeps `seconds`, waking early when `stop` is set.
void sleepUnlessStopped(double seconds, const std::atomic<bool>* stop) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < until) {
    if (stop != nullptr && stop->load()) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

}  // namespace

Result<PromptSummary> runPrompt(const PromptOptions& o) {
  if (!(o.minEvents >= 1)) return Error{"--min-events: at least 1"};
  if (!(o.settleSeconds >= 0.0 && std::isfinite(o.settleSeconds))) return Error{"--settle: 0 or more seconds"};
  if (!(o.pollSeconds > 0.0 && std::isfinite(o.pollSeconds))) return Error{"--poll: more than 0 seconds"};
  std::error_code ec;
  if (!fs::is_directory(o.watchDir, ec)) return Error{fmt::format("{}: not a directory", o.watchDir)};
  auto thresholds = readThresholds(o.thresholds);
  if (!thresholds) return thresholds.error();
  auto calo = io::loadCalorimeter(o.detector);
  if (!calo) return calo.error();
  auto model = campaignModel(o.corrections, o.detector, *calo);
  if (!model) return model.error();
  model->setSigmaSys(o.sigmaSys);
  Loop loop(o, std::move(*thresholds), std::move(*model));
  if (Status s = loop.start(); !s) return s.error();
  PromptSummary total;
  double backoff = o.pollSeconds;
  for (;;) {
    PromptSummary step;
    loop.step(step);
    if (!loop.fatal_.empty()) return Error{loop.fatal_};
    total.filesTaken += step.filesTaken;
    total.quarantined += step.quarantined;
    total.decided += step.decided;
    total.alertsSent += step.alertsSent;
    if (o.once) {
      total.problems = step.problems;
      return total;
    }
    if (o.stop != nullptr && o.stop->load()) return total;
    if (!step.problems.empty()) {
      // The database away, a full disk: said, and tried again later, less and less often.
      for (const auto& p : step.problems) {
        if (o.say) o.say(fmt::format("{} (trying again in {:g} s)", p, backoff));
      }
      sleepUnlessStopped(backoff, o.stop);
      backoff = std::min(backoff * 2.0, std::max(300.0, o.pollSeconds));
    } else {
      backoff = o.pollSeconds;
      sleepUnlessStopped(o.pollSeconds, o.stop);
    }
    if (o.stop != nullptr && o.stop->load()) return total;
  }
}

}  // namespace emcalign::validation
