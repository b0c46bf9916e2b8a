// emcalign conditions: the conditions database — calibrations stored by run range in tags
// (conddb/conditions.hpp, docs/campaign.md).
//
//   conditions init URI
//   conditions put URI --tag T --runs FIRST-LAST RESULT.json
//   conditions get URI --tag T --run R -o P.json
//   conditions list URI [--tag T] [--json]
//   conditions lock URI --tag T                  (= state --set published)
//   conditions copy FROM TO --tag T [--as T2] [--snapshot TIME]
//   conditions retire URI --tag T [--reason TEXT] (= state --set invalid)
//   conditions diff URI --tag A --tag B [--json] [--snapshot TIME]
//   conditions export URI --tag T -o T.csv [--snapshot TIME]
//   get and list take --snapshot TIME too; state, promote and history: cmd_conditions_audit.cpp
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/conddb/tag_tables.hpp"
#include "emcalign/conddb/tag_text.hpp"
#include "emcalign/core/text.hpp"

namespace emcalign::app {

namespace {

using io::Json;

struct ConditionsOptions {
  std::string uri, target, tag, as, runs, result, description, output, reason, snapshot;
  std::vector<std::string> tags;  // conditions diff: the two tags
  std::int64_t run = 0;
  bool json = false;
};

int runInit(const ConditionsOptions& o) {
  auto db = must(conddb::Database::open(o.uri, conddb::IfMissing::Create));
  auto tags = must(db->tags());
  fmt::print("{}: conditions database, schema {} ({})\n", db->uri(), conddb::kSchemaVersion,
             counted(tags.size(), "tag"));
  return kExitOk;
}

int runPut(const ConditionsOptions& o) {
  auto runs = must(conddb::parseRunRange(o.runs));
  auto calo = must(loadCalorimeter(""));
  auto db = must(conddb::Database::open(o.uri));
  auto put = must(conddb::putResultFile(*db, {.tag = o.tag,
                                              .firstRun = runs.first,
                                              .lastRun = runs.second,
                                              .path = o.result,
                                              .description = o.description,
                                              .r1 = calo.description().r1()}));
  for (const auto& w : put.warnings) reportWarning(w);
  fmt::print("{}: tag {}{}: runs {}-{} <- {} (payload {})\n", db->uri(), o.tag, put.newTag ? " (new)" : "", runs.first,
             runs.second, o.result, put.payload.substr(0, 12));
  return kExitOk;
}

int runGet(const ConditionsOptions& o) {
  must(checkOutputs({{"-o", o.output}}, {}, conddb::databaseFiles(o.uri, "database")));
  auto db = must(conddb::Database::open(o.uri));
  auto got = must(conddb::calibrationAt(*db, o.tag, o.run, o.snapshot));
  must(io::writeOutputFile(o.output, got.parameterFile.dump(2) + "\n"));
  // The report goes to stderr when the file goes to stdout (checkOutputs).
  say("{}: tag {} run {}{}: IOV {}-{} (payload {}) -> {}\n", db->uri(), o.tag, o.run,
      o.snapshot.empty() ? std::string() : " at " + o.snapshot, got.iov.firstRun, got.iov.lastRun,
      got.iov.payload.substr(0, 12), o.output);
  return kExitOk;
}

// A mistake withdrawn: the tag kept and listed, never served again (state --set invalid).
int runRetire(const ConditionsOptions& o) {
  auto db = must(conddb::Database::open(o.uri));
  auto changed = must(db->setState(o.tag, conddb::TagState::Invalid, o.reason));
  if (changed == conddb::Database::StateChange::Already) {  // a retry: nothing changed, and said so
    fmt::print("{}: tag {} was invalid already: nothing changed\n", db->uri(), o.tag);
    return kExitOk;
  }
  fmt::print("{}: tag {} is invalid: kept and listed; get, correct, simulate, trend and campaign refuse it\n",
             db->uri(), o.tag);
  return kExitOk;
}

// Tag A against tag B, IOV by IOV: each parameter's difference in σ.
int runDiff(const ConditionsOptions& o) {
  if (o.tags[0] == o.tags[1]) {
    refuse(fmt::format("conditions diff: --tag {} twice: a tag compared with itself differs nowhere (give two tags)",
                       o.tags[0]));
  }
  auto db = must(conddb::Database::open(o.uri));
  auto d = must(conddb::diffTags(*db, o.tags[0], o.tags[1], o.snapshot));
  if (o.json) {
    conddb::writeTagDiffJson(d, [](std::string_view piece) { std::fwrite(piece.data(), 1, piece.size(), stdout); });
    std::fputc('\n', stdout);
    return kExitOk;
  }
  fmt::print("{}", conddb::tagDiffText(d, db->uri(), o.snapshot));
  return kExitOk;
}

// A tag as CSV, one row per IOV.
int runExport(const ConditionsOptions& o) {
  must(checkOutputs({{"-o", o.output}}, {}, conddb::databaseFiles(o.uri, "database")));
  auto db = must(conddb::Database::open(o.uri));
  auto csv = must(conddb::tagCsv(*db, o.tag, o.snapshot));
  must(io::writeOutputFile(o.output, csv));
  say("{}: tag {}: one row per IOV -> {}\n", db->uri(), o.tag, o.output == "-" ? "standard output" : o.output);
  return kExitOk;
}

int runList(const ConditionsOptions& o) {
  auto db = must(conddb::Database::open(o.uri));
  auto tags = must(conddb::listTags(*db, o.tag, o.snapshot));
  const std::vector<conddb::TagListing>& listed = tags;
  if (o.json) {
    Json out = Json::array();
    for (const auto& t : listed) out.push_back(conddb::tagJson(t));
    fmt::print("{}\n", (o.tag.empty() ? out : out.front()).dump(2));
    return kExitOk;
  }
  fmt::print("{}", o.tag.empty() ? conddb::tagsText(listed, db->uri(), o.snapshot)
                                 : conddb::tagText(listed.front(), o.snapshot));
  return kExitOk;
}

int runLock(const ConditionsOptions& o) {
  auto db = must(conddb::Database::open(o.uri));
  auto changed = must(db->setState(o.tag, conddb::TagState::Published, {}));
  fmt::print("{}: tag {} {}: its IOVs never change\n", db->uri(), o.tag,
             changed == conddb::Database::StateChange::Already ? "was published already" : "published");
  return kExitOk;
}

int runCopy(const ConditionsOptions& o) {
  auto copy = must(conddb::copyTagBetween(o.uri, o.tag, o.target, o.as, o.snapshot));
  fmt::print("{} {} -> {} {}: {} ({}, as the original{})\n", copy.from, o.tag, copy.to, o.as.empty() ? o.tag : o.as,
             counted(copy.copied.iovs, "IOV"), conddb::name(copy.copied.state),
             o.snapshot.empty() ? std::string() : " was at " + o.snapshot);
  return kExitOk;
}

CLI::Option* addUri(CLI::App& cmd, std::string& uri) {
  return cmd.add_option("uri", uri, "database: sqlite:PATH, a path, or postgresql://user@host:port/db")->required();
}

CLI::Option* addTag(CLI::App& cmd, std::string& tag) {
  return cmd.add_option("--tag", tag, "tag name (letters, digits, '_', '-', '.')")->check(tagName());
}

}  // namespace

void addConditionsCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<ConditionsOptions>();
  auto* cmd = app.add_subcommand("conditions",
                                 "The conditions database: calibrations stored by run range (tags, IOVs, payloads; "
                                 "an SQLite file or a PostgreSQL server)");
  addVersionFlag(*cmd);
  cmd->require_subcommand(1);

  auto* init = cmd->add_subcommand("init", "Create a database (an SQLite file) or its schema (PostgreSQL)");
  addUri(*init, o->uri);
  init->callback([o, &exitCode] { exitCode = runInit(*o); });

  auto* put = cmd->add_subcommand("put",
                                  "Store a fit result or a parameter file for a run range of a tag "
                                  "(the tag is created if new)");
  addUri(*put, o->uri);
  addTag(*put, o->tag)->required();
  put->add_option("--runs", o->runs, "FIRST-LAST, inclusive (or one run)")->required();
  put->add_option("result", o->result, "fit result or parameter file (JSON)")->required()->check(CLI::ExistingFile);
  put->add_option("--description", o->description, "description of a new tag");
  put->callback([o, &exitCode] { exitCode = runPut(*o); });

  auto* get = cmd->add_subcommand("get", "Write the parameter file valid for a run (exit 1 if no IOV holds it)");
  addUri(*get, o->uri);
  addTag(*get, o->tag)->required();
  get->add_option("--run", o->run, "run number")->required()->check(integerIn(0, INT64_MAX));
  get->add_option("-o,--output", o->output, "parameter file ('-': standard output)")->required();
  addSnapshotOption(*get, o->snapshot);
  get->callback([o, &exitCode] { exitCode = runGet(*o); });

  auto* list = cmd->add_subcommand("list", "List the tags, or the IOVs of one tag");
  addUri(*list, o->uri);
  addTag(*list, o->tag);
  list->add_flag("--json", o->json,
                 "JSON: {\"tag\", \"state\", \"iovs\": [{\"first_run\", \"last_run\", ...}]} "
                 "(an array of them without --tag); state: open, testing, validated, published, running or invalid");
  addSnapshotOption(*list, o->snapshot);
  list->callback([o, &exitCode] { exitCode = runList(*o); });

  auto* lock = cmd->add_subcommand("lock", "Publish a tag (state --set published): its IOVs never change again");
  addUri(*lock, o->uri);
  addTag(*lock, o->tag)->required();
  lock->callback([o, &exitCode] { exitCode = runLock(*o); });

  auto* copy = cmd->add_subcommand("copy",
                                   "Copy a tag to another database (e.g. SQLite <-> PostgreSQL), in one "
                                   "transaction");
  addUri(*copy, o->uri);
  copy->add_option("target", o->target, "destination database (created if an SQLite path)")->required();
  addTag(*copy, o->tag)->required();
  copy->add_option("--as", o->as, "name of the copy (default: the same)")->check(tagName());
  addSnapshotOption(*copy, o->snapshot);
  copy->callback([o, &exitCode] { exitCode = runCopy(*o); });

  auto* retire = cmd->add_subcommand(
      "retire",
      "Withdraw a tag made by mistake (state --set invalid): kept and listed, never served again (a published "
      "tag is never withdrawn)");
  addUri(*retire, o->uri);
  addTag(*retire, o->tag)->required();
  retire->add_option("--reason", o->reason, "why, recorded with the date (shown by conditions list)");
  retire->callback([o, &exitCode] { exitCode = runRetire(*o); });

  auto* diff = cmd->add_subcommand("diff", "Compare two tags IOV by IOV: each parameter's difference in sigma");
  addUri(*diff, o->uri);
  diff->add_option("--tag", o->tags, "the two tags: --tag A --tag B")->required()->expected(2)->check(tagName());
  diff->add_flag("--json", o->json, "JSON: every pair of IOVs with both values, errors, difference and z");
  addSnapshotOption(*diff, o->snapshot);
  diff->callback([o, &exitCode] { exitCode = runDiff(*o); });

  auto* exportTag = cmd->add_subcommand(
      "export", "Write a tag as CSV: one row per IOV (runs, status, chi2, every parameter and its error)");
  addUri(*exportTag, o->uri);
  addTag(*exportTag, o->tag)->required();
  exportTag->add_option("-o,--output", o->output, "CSV file ('-': standard output)")->required();
  addSnapshotOption(*exportTag, o->snapshot);
  exportTag->callback([o, &exitCode] { exitCode = runExport(*o); });
  addConditionsAuditCommands(*cmd, exitCode);
}

}  // namespace emcalign::app
