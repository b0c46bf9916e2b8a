// A plan's tasks run (validation/task_plan.hpp): each task under its lock, its record and log,
// what the records say of the tasks done, and the merge's record.

#include "emcalign/validation/task_plan.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/core/clock.hpp"
#include "emcalign/core/regular_file.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/utf8.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::validation {

namespace {

namespace fs = std::filesystem;
using io::Json;

std::string hostName() {
  char name[256] = {};
  if (::gethostname(name, sizeof name - 1) != 0) return "?";
  return name;
}

// The last line of a file that is not empty (its last 4 KiB read), its terminal controls
// shown as escapes; opened like every input (a FIFO or a device there is said, never waited on).
std::string lastLineOf(const std::string& path) {
  auto file = RegularFile::open(path);
  if (!file) return fmt::format("(not read: {})", file.error().message);
  // Only the last 4 KiB are read, however large the file (a log grown huge, or a sparse one).
  std::string tail(4096, '\0');
  auto n = file->seekToLast(tail.size()) ? file->read(tail.data(), tail.size()) : Result<std::size_t>(0);
  if (!n) return fmt::format("(not read: {})", n.error().message);
  tail.resize(*n);
  while (!tail.empty() && (tail.back() == '\n' || tail.back() == '\r' || tail.back() == ' ' || tail.back() == '\0')) {
    tail.pop_back();
  }
  const auto at = tail.find_last_of('\n');
  std::string line = at == std::string::npos ? tail : tail.substr(at + 1);
  constexpr std::size_t kShown = 300;  // a line without an end (a binary file) is not shown whole
  if (line.size() > kShown) line = "…" + line.substr(line.size() - kShown);
  return printable(line);
}

// Whether the record at `path` says this plan's task (or, with none, its merge) ended well,
// with `key` (none: any), and (`outputs`) whether the files the task writes are there as it
// wrote them (their sizes: a file removed or truncated since does not count; a database's IOV
// is the merge's to check).
bool recordSays(const std::string& path, const std::string& planSha256, std::optional<std::size_t> task,
                const std::optional<std::string>& key = std::string(), const PlannedTask* outputs = nullptr) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;
  auto text = io::readOwnOutput(path);
  if (!text) return false;
  auto j = io::parseJson(*text, path);
  if (!j || !j->is_object() || j->value("format", std::string()) != kTaskRecordFormat) return false;
  if (j->value("plan_sha256", std::string()) != planSha256) return false;
  if (!task) return j->value("finish", false);
  if (key && j->value("key", std::string()) != *key) return false;
  if (!(*j)["task"].is_number_unsigned() || (*j)["task"].get<std::size_t>() != *task) return false;
  if (outputs == nullptr) return true;
  // As the task wrote them: by content (a file edited since to the same size does not count);
  // records of an earlier emcalign keep the sizes only.
  const Json digests = j->value("sha256", Json::object());
  const Json bytes = j->value("bytes", Json::object());
  for (const std::string& w : outputs->writes) {
    if (w.empty() || w.front() != '/') continue;
    if (!fs::is_regular_file(w, ec)) return false;
    if (digests.is_object() && digests.contains(w)) {
      auto now = sha256OfFile(w);
      if (!now || digests[w] != *now) return false;
    } else if (bytes.is_object() && bytes.contains(w) && bytes[w] != fs::file_size(w, ec)) {
      return false;
    }
  }
  return true;
}

// The SHA-256 of the files a task wrote, for its record.
Json writtenDigests(const PlannedTask& task) {
  Json digests = Json::object();
  std::error_code ec;
  for (const std::string& w : task.writes) {
    if (w.empty() || w.front() != '/' || !fs::is_regular_file(w, ec)) continue;
    if (auto digest = sha256OfFile(w)) digests[w] = *digest;
  }
  return digests;
}

}  // namespace

FileLock::FileLock(const std::string& path) {
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    error_ = fmt::format("{}: cannot open the lock: {}", path, std::strerror(errno));
    return;
  }
  while (::flock(fd_, LOCK_EX) != 0) {
    if (errno == EINTR) continue;
    unlocked_ = true;  // ENOLCK, EOPNOTSUPP: no locks here
    break;
  }
}

FileLock::~FileLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the lock
}

bool taskDone(const Plan& plan, std::size_t k) {
  return k < plan.tasks.size() && recordSays(plan.recordOf(k), plan.sha256, k, std::nullopt, &plan.tasks[k]);
}

Status forgetTask(const Plan& plan, std::size_t k) {
  std::error_code ec;
  for (const std::string& record : {plan.recordOf(k), plan.finishRecord()}) {
    fs::remove(record, ec);
    if (ec) return Error{fmt::format("{}: cannot remove the record: {}", record, ec.message())};
  }
  return {};
}

Status forgetMerge(const Plan& plan) {
  std::error_code ec;
  fs::remove(plan.finishRecord(), ec);
  if (ec) return Error{fmt::format("{}: cannot remove the record: {}", plan.finishRecord(), ec.message())};
  return {};
}

std::vector<std::string> taskWarnings(const Plan& plan) {
  std::vector<std::string> out;
  for (std::size_t k = 0; k < plan.tasks.size(); ++k) {
    auto text = io::readOwnOutput(plan.recordOf(k));
    auto j = text ? io::parseJson(*text, plan.recordOf(k)) : Result<Json>(text.error());
    if (!j || !j->is_object() || !(*j)["warnings"].is_array()) continue;
    for (const auto& w : (*j)["warnings"]) {
      if (w.is_string()) out.push_back(fmt::format("task {}: {}", k, w.get<std::string>()));
    }
  }
  return out;
}

TaskState failedMerge(const Plan& plan) {
  TaskState state;
  std::error_code ec;
  if (finished(plan) || !fs::exists(plan.finishLog(), ec)) return state;
  state.log = plan.finishLog();
  state.lastLine = lastLineOf(state.log);
  return state;
}

std::vector<TaskState> taskStates(const Plan& plan) {
  std::vector<TaskState> states(plan.tasks.size());
  for (std::size_t k = 0; k < plan.tasks.size(); ++k) {
    states[k].done = taskDone(plan, k);
    std::error_code ec;
    if (fs::exists(plan.logOf(k), ec)) {
      states[k].log = plan.logOf(k);
      states[k].lastLine = lastLineOf(states[k].log);
    }
  }
  return states;
}

double peakMemoryMb() {
  rusage self{}, children{};
  ::getrusage(RUSAGE_SELF, &self);
  ::getrusage(RUSAGE_CHILDREN, &children);
  return static_cast<double>(std::max(self.ru_maxrss, children.ru_maxrss)) / 1024.0;  // KiB on Linux
}

Result<bool> runPlannedTask(const Plan& plan, const PlannedJob& job, std::size_t k, std::FILE* log) {
  if (k >= plan.tasks.size()) {
    return Error{fmt::format("task {}: the plan {} has tasks 0 to {}", k, plan.path, plan.tasks.size() - 1)};
  }
  const PlannedTask& task = plan.tasks[k];
  const auto jobTasks = job.tasks();
  // The files it writes and reads too (a database's IOV, in words, is the record key's to check:
  // a campaign's plan may leave the database to the task).
  const auto files = [](const std::vector<std::string>& paths) {
    std::vector<std::string> out;
    for (const auto& p : paths) {
      if (!p.empty() && p.front() == '/') out.push_back(p);
    }
    return out;
  };
  if (jobTasks.size() != plan.tasks.size() || jobTasks[k].what != task.what ||
      files(jobTasks[k].writes) != files(task.writes) || files(jobTasks[k].inputs) != files(task.inputs)) {
    return Error{fmt::format(
        "{}: task {} is not what the plan's command makes now ({}): the plan was edited, or its inputs changed "
        "since it was made; make the plan again",
        plan.path, k, printable(task.what))};
  }
  const std::string record = plan.recordOf(k);
  const auto say = [&](const std::string& line) {
    fmt::print(log, "{}\n", line);
    std::fflush(log);
  };
  const std::string key = job.recordKey();
  if (recordSays(record, plan.sha256, k, key, &task)) {
    say(fmt::format("task {} ({}) is done already ({}): nothing to do", k, task.what, record));
    return false;
  }
  std::error_code ec;
  fs::create_directories(plan.workDirectory(), ec);
  const FileLock lock((fs::path(plan.workDirectory()) / fmt::format("task-{}.lock", k)).string());
  if (!lock.error().empty()) return Error{lock.error()};
  if (recordSays(record, plan.sha256, k, key, &task)) {
    say(fmt::format("task {} ({}) was done meanwhile by another copy: nothing to do", k, task.what));
    return false;
  }
  const std::string started = utcNow();
  const auto t0 = std::chrono::steady_clock::now();
  say(fmt::format("emcalign task {} of {} ({} tasks, emcalign {}): {}", k, plan.path, plan.tasks.size(), plan.command,
                  task.what));
  say(fmt::format("  on {} (pid {}), started {}{}", hostName(), ::getpid(), started,
                  lock.unlocked() ? "; this file system has no locks: a second copy may run alongside" : ""));
  for (const auto& in : task.inputs) say("  reads " + in);
  for (const auto& out : task.writes) say("  writes " + out);
  const auto seconds = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  std::vector<std::string> warnings;
  const TaskContext context{[&](const std::string& line) { say("  " + line); }, plan.workDirectory(),
                            [&](const std::string& w) {
                              say("  warning: " + w);
                              warnings.push_back(w);
                            }};
  if (Status s = job.runTask(k, context); !s) {
    say(fmt::format("task {} failed after {:.1f} s, peak memory {:.0f} MB", k, seconds(), peakMemoryMb()));
    return Error{fmt::format("task {} ({}): {}", k, task.what, s.error().message)};
  }
  const Json r = {{"format", kTaskRecordFormat},
                  {"plan", plan.path},
                  {"plan_sha256", plan.sha256},
                  {"task", k},
                  {"what", task.what},
                  {"key", key},
                  {"host", hostName()},
                  {"started", started},
                  {"seconds", seconds()},
                  {"peak_memory_mb", peakMemoryMb()},
                  {"sha256", writtenDigests(task)},
                  {"warnings", warnings}};
  if (Status s = io::writeOutputFile(record, r.dump(1) + "\n", io::Placement::InDirectory); !s) return s.error();
  say(fmt::format("task {} done in {:.1f} s, peak memory {:.0f} MB", k, seconds(), peakMemoryMb()));
  return true;
}

Status checkAllTasksDone(const Plan& plan) {
  const auto states = taskStates(plan);
  std::vector<std::size_t> missing;
  std::string logs;
  for (std::size_t k = 0; k < states.size(); ++k) {
    if (states[k].done) continue;
    missing.push_back(k);
    if (!states[k].log.empty() && logs.size() < 2000) {
      logs += fmt::format("\n  task {}: {} ends: {}", k, states[k].log, states[k].lastLine);
    }
  }
  if (missing.empty()) return {};
  return Error{fmt::format(
      "{}: {} of {} tasks not done: {} (nothing written; run them: emcalign batch submit {} --missing, or emcalign "
      "task {} K; then finish again){}",
      plan.path, missing.size(), plan.tasks.size(), taskRanges(missing), shellArgument(plan.path),
      shellArgument(plan.path), logs)};
}

Status recordFinished(const Plan& plan, double seconds) {
  const Json r = {{"format", kTaskRecordFormat}, {"plan", plan.path},
                  {"plan_sha256", plan.sha256},  {"finish", true},
                  {"host", hostName()},          {"ended", utcNow()},
                  {"seconds", seconds},          {"peak_memory_mb", peakMemoryMb()}};
  return io::writeOutputFile(plan.finishRecord(), r.dump(1) + "\n", io::Placement::InDirectory);
}

bool finished(const Plan& plan) { return recordSays(plan.finishRecord(), plan.sha256, std::nullopt); }

}  // namespace emcalign::validation
