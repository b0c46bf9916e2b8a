// The prompt calibration loop (validation/prompt.hpp): its state, its database, its alerts and
// its steps; the watched directory is prompt_files.cpp's, the groups and decisions
// prompt_groups.cpp's.

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
#include <memory>
#include <optional>
#include <sstream>
#include <thread>

#include <fmt/format.h>

#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/clock.hpp"
#include "emcalign/core/secrets.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/subprocess.hpp"
#include "emcalign/core/utf8.hpp"
#include "emcalign/io/output_file.hpp"
#include "prompt_loop.hpp"

namespace emcalign::validation {

namespace fs = std::filesystem;
using io::Json;

namespace {

constexpr int kAlertSeconds = 30;

// Sleeps `seconds`, waking early when `stop` is set.
void sleepUnlessStopped(double seconds, const std::atomic<bool>* stop) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < until) {
    if (stop != nullptr && stop->load()) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

}  // namespace

namespace prompt {

Result<std::unique_ptr<StateLock>> StateLock::take(const std::string& dir) {
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

StateLock::~StateLock() {
  if (fd_ >= 0) ::close(fd_);
}

Status Loop::start() {
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
      return Error{
          fmt::format("{}: the {} runs taken and not yet decided were read with {}, not {}: start again with the same "
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
std::string Loop::databaseIdentity() const {
  const std::string file = conddb::sqliteFileOf(o_.conditions);
  if (!file.empty()) return "sqlite:" + fs::absolute(file).lexically_normal().string();
  return core::withoutAnyPassword(o_.conditions);
}

// What a run's fill depends on: the corrections (the depth, the parting plane) and the detector,
// by content. Not σ_sys: it acts on the fit only.
Json Loop::modelIdentity() const {
  std::string detector = "embedded";
  if (!o_.detector.empty()) {
    auto sha = sha256OfFile(o_.detector);
    detector = sha ? *sha : o_.detector;
  }
  return {{"corrections_sha256", model_.correctionsSha256}, {"detector_sha256", detector}};
}

// One step; problems (the database away, a full disk) go to `summary` and the step ends.
void Loop::step(PromptSummary& summary) {
  if (Status s = connect(); !s) return problem(summary, s.error().message);
  if (Status s = catchUp(summary); !s) return problem(summary, s.error().message);
  if (Status s = takeFiles(summary); !s) return problem(summary, s.error().message);
  if (Status s = decideClosed(summary); !s) return problem(summary, s.error().message);
  if (Status s = sendAlerts(summary); !s) return problem(summary, s.error().message);
}

// The SQLite file it is open on, to see it removed or replaced while the loop runs.
std::optional<std::uint64_t> Loop::sqliteInode() const {
  const std::string file = conddb::sqliteFileOf(o_.conditions);
  if (file.empty()) return std::nullopt;
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) return 0;
  return static_cast<std::uint64_t>(st.st_ino);
}

Status Loop::connect() {
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
Json Loop::thisLoop() const {
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
bool Loop::stillRuns(const std::string& text, const Json& me) {
  const Json other = Json::parse(text, nullptr, false);
  if (!other.is_object()) return false;
  if (other.value("state_dir", std::string()) == me["state_dir"].get<std::string>()) return false;
  if (other.value("host", std::string()) != me["host"].get<std::string>()) return true;
  if (other.value("boot", std::string()) != me["boot"].get<std::string>()) return false;
  const auto pid = other.value("pid", std::int64_t{-1});
  return pid > 0 && startOf(pid) == other.value("start", std::string("?"));
}

// The start time of a process (/proc/PID/stat, field 22), "" when there is none.
std::string Loop::startOf(std::int64_t pid) {
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

std::string Loop::bootId() {
  std::ifstream in("/proc/sys/kernel/random/boot_id");
  std::string id;
  std::getline(in, id);
  return id;
}

Status Loop::saveState() { return io::writeFileIn(o_.stateDir, "state.json", state_.toJson().dump(1) + "\n"); }

// The database is the record of what was decided: the runs of decided groups leave the
// open ones, decisions.jsonl and quarantine.json are brought up to date.
Status Loop::catchUp(PromptSummary&) {
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
std::string Loop::decisionsDigest() const {
  std::string text;
  for (const std::string& r : records_) text += r + "\n";
  return sha256(text);
}

Status Loop::writeDecisions() {
  std::string text;
  for (const std::string& r : records_) text += r + "\n";
  const std::string path = (fs::path(o_.stateDir) / "decisions.jsonl").string();
  if (auto now = io::readOwnOutput(path); now && *now == text) return {};
  return io::writeFileIn(o_.stateDir, "decisions.jsonl", text);
}

Status Loop::writeStatus() {
  const prompt::StatusInput in{state_,       records_,
                               o_.tag,       db_ ? db_->uri() : std::string(),
                               o_.minEvents, Json{{"sha256", thresholds_.sha256}, {"json", thresholds_.json}},
                               utcNow()};
  return io::writeFileIn(o_.stateDir, "status.html", prompt::statusPage(in));
}

// Vetoes, quarantined files and rewritten files, each sent once acknowledged (at least once).
Status Loop::sendAlerts(PromptSummary& summary) {
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
    nextAlertTry_ = std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                           std::chrono::duration<double>(alertBackoff_));
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

bool Loop::pending(const std::string& key) const {
  return std::any_of(pendingAlerts_.begin(), pendingAlerts_.end(), [&](const auto& p) { return p.first == key; });
}

}  // namespace prompt

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
  prompt::Loop loop(o, std::move(*thresholds), std::move(*model));
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
