// A plan of tasks (validation/task_plan.hpp): the plan file written and read back, the paths it
// names (for the batch scripts' checks), and the blocks of samples a study's tasks take.

#include "emcalign/validation/task_plan.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <tuple>

#include <fmt/format.h>

#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/secrets.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/utf8.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/csv.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/io/strict_json.hpp"

namespace emcalign::validation {

namespace {

namespace fs = std::filesystem;
using io::Json;

Json taskJson(std::size_t k, const PlannedTask& t) {
  return {{"task", k}, {"what", t.what}, {"writes", t.writes}, {"inputs", t.inputs}};
}

std::vector<std::string> stringList(const io::strict::StrictObject& o, std::string_view key) {
  const Json& a = o.at(key);
  if (!a.is_array()) o.fail(o.pathOf(key), fmt::format("expected an array of strings, got {}", a.type_name()));
  std::vector<std::string> out;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!a[i].is_string()) o.fail(fmt::format("{}[{}]", o.pathOf(key), i), "expected a string");
    out.push_back(a[i].get<std::string>());
  }
  return out;
}

}  // namespace

// A plan's paths go into batch scripts — comments, #SBATCH lines (which sbatch splits into words,
// where '\\' escapes and which end at a newline), a shell's command line: one holding a control
// character (a newline ends the line: what follows would run), '"' or '\\' is refused wherever a
// plan is written or read. So is "hetjob" or "packjob" in any case: sbatch blanks the word in an
// #SBATCH line and starts another component of a heterogeneous job there.
Status checkScriptSafe(std::string_view what, const std::string& p, const std::string& source) {
  if (!isValidUtf8(p)) {
    return Error{fmt::format("{}: {} {} is not UTF-8: a plan is JSON text, which must be; rename it", source, what,
                             io::quotedText(printable(p), 200))};
  }
  const auto unsafe = std::find_if(p.begin(), p.end(),
                                   [](char c) { return c == '"' || c == '\\' || (c >= 0 && c < 0x20) || c == 0x7f; });
  std::string lower = p;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  const bool component = lower.find("hetjob") != std::string::npos || lower.find("packjob") != std::string::npos;
  if (unsafe == p.end() && !component) return {};
  return Error{fmt::format(
      "{}: {} {} holds {}: a plan's paths go into batch scripts, where it could end a line and run what follows "
      "or change the job's directives; rename it without control characters, '\"', '\\', \"hetjob\" or "
      "\"packjob\"",
      source, what, io::quotedText(printable(p), 200),
      unsafe == p.end() ? "the word sbatch reads as another job's start"
      : *unsafe == '"'  ? "a double quote"
      : *unsafe == '\\' ? "a backslash"
                        : "a control character")};
}

Result<ProgramIdentity> ProgramIdentity::ofThisProcess() {
  static const Result<ProgramIdentity> identity = []() -> Result<ProgramIdentity> {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (ec) return Error{fmt::format("/proc/self/exe: cannot find this program's executable: {}", ec.message())};
    auto digest = sha256OfFile(exe.string());
    if (!digest) return digest.error();
    return ProgramIdentity{kVersion, *digest, exe.string()};
  }();
  return identity;
}

std::string realPlanPath(const std::string& planPath) {
  std::error_code ec;
  // Links resolved (a plan reached through a link has the one work directory of the real one),
  // as far as the path exists (a plan about to be written).
  fs::path p = fs::weakly_canonical(fs::absolute(planPath, ec), ec);
  if (ec) p = fs::absolute(planPath, ec).lexically_normal();
  return p.string();
}

std::string planWorkDirectory(const std::string& planPath) {
  const fs::path p = realPlanPath(planPath);
  return (p.parent_path() / (p.stem().string() + ".tasks")).string();
}

std::string Plan::workDirectory() const { return planWorkDirectory(path); }
std::string Plan::recordOf(std::size_t k) const {
  return (fs::path(workDirectory()) / fmt::format("task-{}.json", k)).string();
}
std::string Plan::logOf(std::size_t k) const {
  return (fs::path(workDirectory()) / fmt::format("task-{}.log", k)).string();
}
std::string Plan::finishLog() const { return (fs::path(workDirectory()) / "finish.log").string(); }
std::string Plan::finishRecord() const { return (fs::path(workDirectory()) / "finish.json").string(); }

namespace {

// --plan replaces an earlier plan only: any other file there (an input of another command, a
// study's output, notes) is refused.
Status replacesOnlyAPlan(const std::string& path) {
  std::error_code ec;
  const auto status = fs::symlink_status(path, ec);
  if (ec || status.type() == fs::file_type::not_found) return {};
  const auto refuse = [&](const std::string& what) {
    return Error{
        fmt::format("--plan {}: {}, not a plan: --plan replaces only an earlier plan (emcalign-plan/1); "
                    "remove it or give another name",
                    path, what)};
  };
  if (status.type() != fs::file_type::regular) return refuse("this exists and is not a regular file");
  auto text = io::readOwnOutput(path);
  auto j = text ? io::parseJson(*text, path) : Result<Json>(text.error());
  if (!j || !j->is_object() || j->value("format", Json()) != kPlanFormat) {
    return refuse("this file exists and holds something else");
  }
  return {};
}

}  // namespace

Result<Plan> writePlan(const std::string& path, const std::string& command, const std::vector<std::string>& arguments,
                       const PlannedJob& job) {
  auto program = ProgramIdentity::ofThisProcess();
  if (!program) return program.error();
  std::error_code ec;
  Plan plan;
  plan.path = realPlanPath(path);
  plan.command = command;
  plan.arguments = arguments;
  plan.directory = fs::current_path(ec).string();
  if (ec) return Error{fmt::format("cannot tell the current directory: {}", ec.message())};
  plan.program = *program;
  plan.tasks = job.tasks();
  plan.data = job.data();
  if (plan.tasks.empty()) return Error{"the plan has no task: nothing to run"};
  // A plan never holds a password (its tasks refuse one): none of its arguments either.
  for (const std::string& a : arguments) {
    if (core::holdsPassword(a)) {
      return Error{fmt::format(
          "{}: an argument holds a password ({}): a plan never does (its tasks would refuse it); give it to libpq "
          "(PGPASSFILE, PGPASSWORD)",
          path, io::quotedText(a, 60))};
    }
  }
  for (const auto& [what, p] : {std::pair{"its path", plan.path}, std::pair{"its directory", plan.directory},
                                std::pair{"the program", plan.program.path}}) {
    if (Status s = checkScriptSafe(what, p, path); !s) return s.error();
  }
  if (plan.workDirectory() == plan.path) {
    return Error{
        fmt::format("{}: a plan's tasks keep their records in PLAN.tasks beside it: name the plan "
                    "PLAN.json, not PLAN.tasks",
                    path)};
  }
  if (Status s = replacesOnlyAPlan(plan.path); !s) return s.error();
  if (fs::path(plan.path).parent_path().extension() == ".tasks") {
    return Error{
        fmt::format("{}: inside a plan's work directory (NAME.tasks holds its tasks' records and logs): put "
                    "the plan beside it",
                    path)};
  }
  // NAME.json only: "q", "q.json" and "q.JSON" would share the work directory q.tasks.
  if (fs::path(plan.path).extension() != ".json") {
    return Error{fmt::format(
        "{}: a plan is named NAME.json (its tasks' records and logs go to NAME.tasks beside it, which another "
        "name, NAME or NAME.JSON, would share)",
        path)};
  }
  Json tasks = Json::array();
  for (std::size_t k = 0; k < plan.tasks.size(); ++k) tasks.push_back(taskJson(k, plan.tasks[k]));
  const Json j = {{"format", kPlanFormat},
                  {"command", command},
                  {"arguments", arguments},
                  {"directory", plan.directory},
                  {"program", {{"version", program->version}, {"sha256", program->sha256}, {"path", program->path}}},
                  {"work_directory", plan.workDirectory()},
                  {"tasks", tasks},
                  {"data", plan.data}};
  const std::string text = j.dump(1) + "\n";
  fs::create_directories(plan.workDirectory(), ec);
  if (ec) return Error{fmt::format("{}: cannot create the tasks' directory: {}", plan.workDirectory(), ec.message())};
  if (Status s = io::writeOutputFile(path, text); !s) return s.error();
  // The records and logs of an earlier plan at this path say nothing of this one.
  for (const auto& e : fs::directory_iterator(plan.workDirectory(), ec)) {
    const std::string name = e.path().filename().string();
    const bool ours = (name.rfind("task-", 0) == 0 || name.rfind("finish.", 0) == 0) &&
                      (e.path().extension() == ".json" || e.path().extension() == ".log");
    std::error_code ignored;
    if (ours && e.is_regular_file(ignored)) fs::remove(e.path(), ignored);
  }
  plan.sha256 = sha256(text);
  return plan;
}

PlanPaths pathsOfPlan(const Plan& plan) {
  PlanPaths out;
  out.files.push_back({"the plan itself", plan.path});
  out.files.push_back({"the program the plan runs", plan.program.path});
  if (auto running = ProgramIdentity::ofThisProcess()) out.files.push_back({"the program the jobs run", running->path});
  out.directories.push_back({"the plan's work directory", plan.workDirectory()});
  for (std::size_t k = 0; k < plan.tasks.size(); ++k) {
    for (const auto& f : plan.tasks[k].inputs)
      out.files.push_back({fmt::format("which the plan's task {} reads", k), f});
    for (const auto& f : plan.tasks[k].writes)
      out.files.push_back({fmt::format("which the plan's task {} writes", k), f});
  }
  const auto named = [&](const std::string& option, const std::string& value, bool output) {
    if (value.empty() || value == "-") return;
    const std::string what = option.empty()     ? "named by the plan's command line"
                             : option == "data" ? "named in the plan's data"
                                                : "the plan's " + option;
    if (value.starts_with("sqlite:")) {
      const std::string file = conddb::sqliteFileOf(value);
      if (file.empty()) return;
      const fs::path f = fs::absolute(fs::path(plan.directory) / file);
      for (const char* suffix : {"", "-wal", "-shm", "-journal"}) out.files.push_back({what, f.string() + suffix});
      return;
    }
    if (value.find("://") != std::string::npos) return;  // a server
    const fs::path p = (fs::path(plan.directory) / value).lexically_normal();
    std::error_code ec;
    const auto status = fs::status(p, ec);
    if (status.type() == fs::file_type::directory || (output && status.type() == fs::file_type::not_found)) {
      out.directories.push_back({what, p.string()});
    }
    if (status.type() != fs::file_type::directory && (output || fs::exists(status))) {
      for (const char* suffix : {"", "-wal", "-shm", "-journal"}) out.files.push_back({what, p.string() + suffix});
    }
  };
  static const std::vector<std::string> kOutputs = {"-o", "--output", "--write-corrections", "--profile-out"};
  for (std::size_t i = 0; i < plan.arguments.size(); ++i) {
    const std::string& a = plan.arguments[i];
    const bool option = a.starts_with("-") && a.size() > 1;
    if (!option) {
      const std::string previous = i > 0 ? plan.arguments[i - 1] : "";
      named(previous.starts_with("-") ? previous : "", a,
            std::find(kOutputs.begin(), kOutputs.end(), previous) != kOutputs.end());
    } else if (const auto eq = a.find('='); eq != std::string::npos) {
      const std::string name = a.substr(0, eq);
      named(name, a.substr(eq + 1), std::find(kOutputs.begin(), kOutputs.end(), name) != kOutputs.end());
    }
  }
  // What the tasks take from the plan's data (a campaign's database and files): every string
  // there that names a database or a file.
  std::vector<const Json*> pending = {&plan.data};
  while (!pending.empty()) {
    const Json* j = pending.back();
    pending.pop_back();
    if (j->is_string()) {
      const std::string& v = j->get_ref<const std::string&>();
      if (!v.empty() && v.size() < 4096) named("data", v, false);
    } else if (j->is_structured()) {
      for (const Json& child : *j) pending.push_back(&child);
    }
  }
  return out;
}

namespace {

// Whether a key or string anywhere in `j` holds a password.
bool anyStringHoldsPassword(const Json& j) {
  std::vector<const Json*> pending = {&j};
  while (!pending.empty()) {
    const Json* at = pending.back();
    pending.pop_back();
    if (at->is_string() && core::holdsPassword(at->get_ref<const std::string&>(), true)) return true;
    if (at->is_object()) {
      for (const auto& [key, value] : at->items()) {
        if (core::holdsPassword(key, true)) return true;
        pending.push_back(&value);
      }
    } else if (at->is_array()) {
      for (const Json& child : *at) pending.push_back(&child);
    }
  }
  return false;
}

}  // namespace

Result<Plan> parsePlan(const std::string& text, const std::string& path) {
  auto j = io::parseJson(text, path);
  if (!j) return j.error();
  // A plan never holds a password (campaign --plan refuses one): an edited plan neither, in its
  // text or in any string JSON's escapes ("\/", "\u0073") make of it; refused before any of it is shown.
  if (core::holdsPassword(text, true) || anyStringHoldsPassword(*j)) {
    return Error{fmt::format(
        "{}: holds a password (a database URI with user:password@ or password=): a plan never does; give it to "
        "libpq (PGPASSFILE, PGPASSWORD) and make the plan again",
        path)};
  }
  if (Status s = io::expectFormat(*j, kPlanFormat, "a plan (emcalign-plan/1)", path); !s) return s.error();
  return io::strict::guarded([&]() -> Plan {
    const io::strict::StrictObject o(*j, "", path);
    o.allowOnly({"format", "command", "arguments", "directory", "program", "work_directory", "tasks", "data"});
    if (o.string("format") != kPlanFormat) o.fail("format", fmt::format("expected \"{}\"", kPlanFormat));
    Plan plan;
    plan.path = realPlanPath(path);
    plan.sha256 = sha256(text);
    plan.command = o.string("command");
    if (std::find(std::begin(kPlannedCommands), std::end(kPlannedCommands), plan.command) ==
        std::end(kPlannedCommands)) {
      o.fail("command", "expected validate, systematics, derive-corrections or campaign");
    }
    plan.arguments = stringList(o, "arguments");
    plan.directory = o.string("directory");
    const auto program = o.object("program");
    program.allowOnly({"version", "sha256", "path"});
    plan.program = {program.string("version"), program.string("sha256"), program.string("path")};
    const Json& tasks = o.at("tasks");
    if (!tasks.is_array() || tasks.empty()) o.fail("tasks", "expected an array of tasks, not empty");
    for (std::size_t k = 0; k < tasks.size(); ++k) {
      const io::strict::StrictObject t(tasks[k], fmt::format("tasks[{}]", k), path);
      t.allowOnly({"task", "what", "writes", "inputs"});
      if (!t.at("task").is_number_unsigned() || t.at("task").get<std::size_t>() != k) {
        t.fail(t.pathOf("task"), fmt::format("expected {} (the tasks in order)", k));
      }
      plan.tasks.push_back({t.string("what"), stringList(t, "writes"), stringList(t, "inputs")});
    }
    plan.data = o.has("data") ? o.at("data") : Json(nullptr);
    // Refused where read, not only where written: a copy of a plan in a directory of another
    // name, or an edited plan, goes into a script as it is.
    for (const auto& [what, p, key] :
         {std::tuple{"its path", plan.path, ""}, std::tuple{"its directory", plan.directory, "directory"},
          std::tuple{"its program", plan.program.path, "program.path"}}) {
      if (Status s = checkScriptSafe(what, p, path); !s) {
        if (std::string_view(key).empty()) throw io::strict::BadInput{s.error().message};
        o.fail(key,
               "holds a control character, '\"', '\\', \"hetjob\" or \"packjob\": a plan's paths go into batch "
               "scripts");
      }
    }
    return plan;
  });
}

Result<Plan> readPlan(const std::string& path) {
  auto text = io::readTextFile(path);
  if (!text) return text.error();
  auto plan = parsePlan(*text, path);
  if (!plan) return plan.error();
  auto program = ProgramIdentity::ofThisProcess();
  if (!program) return program.error();
  if (plan->program.version != program->version || plan->program.sha256 != program->sha256) {
    return Error{fmt::format(
        "{}: the plan was made by emcalign {} ({}, SHA-256 {}…), this is emcalign {} ({}, SHA-256 {}…): its tasks "
        "run with the program that made it (another build may give other numbers); use that one, or make the plan "
        "again",
        path, plan->program.version, plan->program.path, plan->program.sha256.substr(0, 12), program->version,
        program->path, program->sha256.substr(0, 12))};
  }
  // The script and the merge run the program at program.path: it must be the one the plan
  // names by its digest (an edited path would run another program on every node).
  if (plan->program.path != program->path) {
    const auto digest = plan->program.path.starts_with('/') ? sha256OfFile(plan->program.path)
                                                            : Result<std::string>(Error{"not an absolute path"});
    if (!digest || *digest != plan->program.sha256) {
      return Error{fmt::format(
          "{}: key 'program.path': {} is not the program that made the plan (SHA-256 {}…): {}; its tasks and "
          "merge run that program: make the plan again",
          path, io::quotedText(printable(plan->program.path), 200), plan->program.sha256.substr(0, 12),
          digest ? fmt::format("its SHA-256 is {}…", digest->substr(0, 12)) : digest.error().message)};
    }
  }
  return plan;
}

std::vector<SampleBlock> sampleBlocks(int samples, int perTask, int campaigns, int otherTasks) {
  int per = perTask;
  if (per <= 0) {
    const long long total = static_cast<long long>(samples) * std::max(campaigns, 1);
    const long long room = std::max(1, kMaxPlanTasks - otherTasks);
    per = static_cast<int>(std::max(1LL, (total + room - 1) / room));
  }
  std::vector<SampleBlock> blocks;
  for (int first = 0; first < samples; first += per) blocks.push_back({first, std::min(samples, first + per) - 1});
  return blocks;
}

std::string samplesText(const SampleBlock& b) {
  return b.first == b.last ? fmt::format("sample {}", b.first) : fmt::format("samples {}-{}", b.first, b.last);
}

std::string taskRanges(const std::vector<std::size_t>& tasks) {
  std::string out;
  for (std::size_t i = 0; i < tasks.size();) {
    std::size_t j = i;
    while (j + 1 < tasks.size() && tasks[j + 1] == tasks[j] + 1) ++j;
    if (!out.empty()) out += ",";
    out += j == i ? fmt::format("{}", tasks[i]) : fmt::format("{}-{}", tasks[i], tasks[j]);
    i = j + 1;
  }
  return out;
}

}  // namespace emcalign::validation
