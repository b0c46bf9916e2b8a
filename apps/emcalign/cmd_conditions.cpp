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
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common.hpp"
#include "emcalign/conddb/address.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/conddb/tag_tables.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/utf8.hpp"

namespace emcalign::app {

namespace {

using io::Json;
namespace fs = std::filesystem;

struct ConditionsOptions {
  std::string uri, target, tag, as, runs, result, description, output, reason, snapshot;
  std::vector<std::string> tags;  // conditions diff: the two tags
  std::int64_t run = 0;
  bool json = false;
};

// "FIRST-LAST" or "RUN".
Result<std::pair<std::int64_t, std::int64_t>> parseRuns(const std::string& text) {
  auto number = [&](std::string_view s, std::int64_t& out) {
    if (s.empty()) return false;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
    return ec == std::errc() && p == s.data() + s.size() && out >= 0;
  };
  std::int64_t first = 0, last = 0;
  const auto dash = text.find('-');
  const bool ok = dash == std::string::npos ? number(text, first) && (last = first, true)
                                            : number(std::string_view(text).substr(0, dash), first) &&
                                                  number(std::string_view(text).substr(dash + 1), last);
  if (!ok) return Error{fmt::format("--runs '{}': expected FIRST-LAST (runs are integers >= 0), e.g. 1-40", text)};
  if (first > last) return Error{fmt::format("--runs '{}': the first run is after the last", text)};
  return std::pair{first, last};
}

int runInit(const ConditionsOptions& o) {
  auto db = conddb::Database::open(o.uri, conddb::IfMissing::Create);
  if (!db) return reportError(db.error());
  auto tags = (*db)->tags();
  if (!tags) return reportError(tags.error());
  fmt::print("{}: conditions database, schema {} ({})\n", (*db)->uri(), conddb::kSchemaVersion,
             counted(tags->size(), "tag"));
  return kExitOk;
}

int runPut(const ConditionsOptions& o) {
  auto runs = parseRuns(o.runs);
  if (!runs) return reportError(runs.error());
  auto calo = loadCalorimeter("");
  if (!calo) return reportError(calo.error());
  auto db = conddb::Database::open(o.uri);
  if (!db) return reportError(db.error());
  auto put = conddb::putResultFile(**db, {.tag = o.tag,
                                          .firstRun = runs->first,
                                          .lastRun = runs->second,
                                          .path = o.result,
                                          .description = o.description,
                                          .r1 = calo->description().r1()});
  if (!put) return reportError(put.error());
  for (const auto& w : put->warnings) reportWarning(w);
  fmt::print("{}: tag {}{}: runs {}-{} <- {} (payload {})\n", (*db)->uri(), o.tag, put->newTag ? " (new)" : "",
             runs->first, runs->second, o.result, put->payload.substr(0, 12));
  return kExitOk;
}

int runGet(const ConditionsOptions& o) {
  if (Status s = checkOutputs({{"-o", o.output}}, {}, conddb::databaseFiles(o.uri, "database")); !s) {
    return reportError(s.error());
  }
  auto db = conddb::Database::open(o.uri);
  if (!db) return reportError(db.error());
  auto got = conddb::calibrationAt(**db, o.tag, o.run, o.snapshot);
  if (!got) return reportError(got.error());
  if (Status s = io::writeOutputFile(o.output, got->parameterFile.dump(2) + "\n"); !s) return reportError(s.error());
  // The report goes to stderr when the file goes to stdout (checkOutputs).
  fmt::print(reportStream(), "{}: tag {} run {}{}: IOV {}-{} (payload {}) -> {}\n", (*db)->uri(), o.tag, o.run,
             o.snapshot.empty() ? std::string() : " at " + o.snapshot, got->iov.firstRun, got->iov.lastRun,
             got->iov.payload.substr(0, 12), o.output);
  return kExitOk;
}

// A mistake withdrawn: the tag kept and listed, never served again (state --set invalid).
int runRetire(const ConditionsOptions& o) {
  auto db = conddb::Database::open(o.uri);
  if (!db) return reportError(db.error());
  auto changed = (*db)->setState(o.tag, conddb::TagState::Invalid, o.reason);
  if (!changed) return reportError(changed.error());
  if (*changed == conddb::Database::StateChange::Already) {  // a retry: nothing changed, and said so
    fmt::print("{}: tag {} was invalid already: nothing changed\n", (*db)->uri(), o.tag);
    return kExitOk;
  }
  fmt::print("{}: tag {} is invalid: kept and listed; get, correct, simulate, trend and campaign refuse it\n",
             (*db)->uri(), o.tag);
  return kExitOk;
}

// Tag A against tag B, IOV by IOV: each parameter's difference in σ.
int runDiff(const ConditionsOptions& o) {
  if (o.tags.size() != 2) return reportError(Error{"conditions diff: give two tags, --tag A --tag B"});
  if (o.tags[0] == o.tags[1]) {
    return reportError(Error{fmt::format(
        "conditions diff: --tag {} twice: a tag compared with itself differs nowhere (give two tags)", o.tags[0])});
  }
  auto db = conddb::Database::open(o.uri);
  if (!db) return reportError(db.error());
  auto d = conddb::diffTags(**db, o.tags[0], o.tags[1], o.snapshot);
  if (!d) return reportError(d.error());
  if (o.json) {
    conddb::writeTagDiffJson(*d, [](std::string_view piece) { std::fwrite(piece.data(), 1, piece.size(), stdout); });
    std::fputc('\n', stdout);
    return kExitOk;
  }
  fmt::print("{}: tag {} against tag {}{}, (a - b) / sqrt(error_a^2 + error_b^2) of each parameter\n", (*db)->uri(),
             d->tagA, d->tagB, o.snapshot.empty() ? std::string() : " as they were at " + o.snapshot);
  // The models the two tags were fitted with: differences that are the models', not the detector's.
  if (!d->pairs.empty()) {
    const conddb::ModelComparison models = conddb::compareModels(*d);
    // σ_sys sets the errors the pulls below are in units of: said beside the models.
    const std::string sigmaA = conddb::sigmaSysSummary(d->listingA), sigmaB = conddb::sigmaSysSummary(d->listingB);
    fmt::print("models: tag {}: {}, sigma_sys {}; tag {}: {}, sigma_sys {}\n", d->tagA, printable(models.a), sigmaA,
               d->tagB, printable(models.b), sigmaB);
    if (!models.same) {
      fmt::print("  the models differ: {}\n",
                 models.paperOnOneSide
                     ? "differences common to every IOV (the gaps dp1-dp3, dx_rel, the shifts' scale) are the paper's "
                       "model's against the corrections' (docs/validation.md), not the detector's"
                     : "differences common to every IOV are the models', not the detector's");
    }
    if (sigmaA != sigmaB) {
      fmt::print("  sigma_sys differs: the errors, and the pulls in their units, are not alike in the two tags\n");
    }
  }
  fmt::print("{:>17}", "runs");
  for (Quantity q : kAllQuantities) fmt::print(" {:>8} ", q);  // the last column of a cell: its mark
  fmt::print("\n");
  int beyond3 = 0;
  for (const auto& p : d->pairs) {
    fmt::print("{:>17}", fmt::format("{}-{}", p.firstRun, p.lastRun));
    if (p.samePayload()) {
      fmt::print("  the same payload\n");
      continue;
    }
    for (double z : p.z) {
      // Two decimals cut toward zero, so that a cell reads 3.00 or more exactly when it is
      // counted (rounded, -2.996 would read -3.00); the counted cells are marked too.
      const bool counted3 = std::isfinite(z) && std::abs(z) >= 3.0;
      fmt::print(" {:>8}{}", std::isfinite(z) ? fixed(std::trunc(z * 100.0) / 100.0, 2, true) : std::string("-"),
                 counted3 ? "*" : " ");
      beyond3 += counted3 ? 1 : 0;
    }
    fmt::print("\n");
  }
  for (const auto& [f, l] : d->onlyA) fmt::print("runs {}-{}: only in tag {}\n", f, l, d->tagA);
  for (const auto& [f, l] : d->onlyB) fmt::print("runs {}-{}: only in tag {}\n", f, l, d->tagB);
  fmt::print(
      "{}, {} of 3 sigma or more (marked *; the errors of one fit each, not independent when the tags fitted the "
      "same events)\n",
      counted(d->pairs.size(), "IOV pair"), counted(beyond3, "difference"));
  return kExitOk;
}

// A tag as CSV, one row per IOV.
int runExport(const ConditionsOptions& o) {
  if (Status s = checkOutputs({{"-o", o.output}}, {}, conddb::databaseFiles(o.uri, "database")); !s) {
    return reportError(s.error());
  }
  auto db = conddb::Database::open(o.uri);
  if (!db) return reportError(db.error());
  auto csv = conddb::tagCsv(**db, o.tag, o.snapshot);
  if (!csv) return reportError(csv.error());
  if (Status s = io::writeOutputFile(o.output, *csv); !s) return reportError(s.error());
  fmt::print(reportStream(), "{}: tag {}: one row per IOV -> {}\n", (*db)->uri(), o.tag,
             o.output == "-" ? "standard output" : o.output);
  return kExitOk;
}

int runList(const ConditionsOptions& o) {
  auto db = conddb::Database::open(o.uri);
  if (!db) return reportError(db.error());
  auto tags = conddb::listTags(**db, o.tag, o.snapshot);
  if (!tags) return reportError(tags.error());
  const std::vector<conddb::TagListing>& listed = *tags;
  if (o.json) {
    Json out = Json::array();
    for (const auto& t : listed) out.push_back(conddb::tagJson(t));
    fmt::print("{}\n", (o.tag.empty() ? out : out.front()).dump(2));
    return kExitOk;
  }
  if (o.tag.empty()) {
    if (!o.snapshot.empty()) fmt::print("{}: as it was at {}\n", (*db)->uri(), o.snapshot);
    fmt::print("{:<24} {:<9} {:>6} {:>17}  {:<28} {:<22} {}\n", "tag", "state", "IOVs", "runs", "model", "sigma_sys",
               "description");
    for (const auto& t : listed) {
      const auto& iovs = t.iovs;
      const std::string runs =
          iovs.empty() ? "-" : fmt::format("{}-{}", iovs.front().iov.firstRun, iovs.back().iov.lastRun);
      fmt::print("{:<24} {:<9} {:>6} {:>17}  {:<28} {:<22} {}\n", t.tag.name, name(t.tag.state), iovs.size(), runs,
                 conddb::modelSummary(iovs), conddb::sigmaSysSummary(iovs), t.tag.description);
    }
    return kExitOk;
  }
  const conddb::TagListing& t = listed.front();
  fmt::print("tag {} ({}), created {}{}{}\n", o.tag, name(t.tag.state), t.tag.created,
             t.tag.description.empty() ? "" : ": " + t.tag.description,
             o.snapshot.empty() ? std::string() : ", as it was at " + o.snapshot);
  if (!t.tag.stateChanged.empty()) {
    fmt::print("{} since {}{}\n", name(t.tag.state), t.tag.stateChanged,
               t.tag.reason.empty() ? std::string() : ": " + t.tag.reason);
  }
  fmt::print("model: {}; sigma_sys: {}\n", conddb::modelSummary(t.iovs, false), conddb::sigmaSysSummary(t.iovs));
  fmt::print("{:>10} {:>10} {:>9} {:>12} {:>12} {:<12} {:<12} {}\n", "first_run", "last_run", "events", "chi2/ndf",
             "stat. only", "status", "payload", "inserted");
  for (const auto& i : t.iovs) {
    const auto ratio = [&](const std::optional<double>& chi2) {
      return chi2 && std::isfinite(*chi2) && i.ndf ? fmt::format("{:.1f}/{}", *chi2, *i.ndf) : std::string("-");
    };
    // sigma_sys auto makes chi2/ndf 1: the chi2 with the statistical errors alone beside it.
    const std::string events = i.selectedEvents ? std::to_string(*i.selectedEvents) : "-";
    // Text of a payload is printed escaped: a database can hold anything (core/utf8.hpp).
    const std::string status = i.status ? printable(*i.status) : "-";
    fmt::print("{:>10} {:>10} {:>9} {:>12} {:>12} {:<12} {:<12} {}\n", i.iov.firstRun, i.iov.lastRun, events,
               ratio(i.chi2), ratio(i.chi2Statistical), status, i.iov.payload.substr(0, 12), i.iov.inserted);
  }
  return kExitOk;
}

int runLock(const ConditionsOptions& o) {
  auto db = conddb::Database::open(o.uri);
  if (!db) return reportError(db.error());
  auto changed = (*db)->setState(o.tag, conddb::TagState::Published, {});
  if (!changed) return reportError(changed.error());
  fmt::print("{}: tag {} {}: its IOVs never change\n", (*db)->uri(), o.tag,
             *changed == conddb::Database::StateChange::Already ? "was published already" : "published");
  return kExitOk;
}

// Whether two addresses are one SQLite file under two names (a hard link): opened by both
// names, SQLite would keep two write-ahead logs of one database.
bool sameSqliteFile(const std::string& a, const std::string& b) {
  auto x = conddb::DatabaseAddress::parse(a);
  auto y = conddb::DatabaseAddress::parse(b);
  if (!x || !y || x->kind != conddb::DatabaseAddress::Kind::Sqlite ||
      y->kind != conddb::DatabaseAddress::Kind::Sqlite) {
    return false;
  }
  std::error_code ec;
  return std::filesystem::equivalent(x->file, y->file, ec) && !ec;
}

int runCopy(const ConditionsOptions& o) {
  auto from = conddb::Database::open(o.uri);
  if (!from) return reportError(from.error());
  // The source read first: a new target is created only now, and removed again if the copy
  // fails before storing.
  if (auto t = conddb::TagSnapshot::load(**from, o.tag, false, o.snapshot); !t) return reportError(t.error());
  conddb::DatabaseToWrite target(sameSqliteFile(o.uri, o.target) ? o.uri : o.target);
  if (Status s = target.prepare(); !s) return reportError(s.error());
  auto to = target.create();
  if (!to) return reportError(to.error());
  const std::string name = o.as.empty() ? o.tag : o.as;
  auto copied = conddb::copyTag(**from, o.tag, **to, name, o.snapshot);
  if (!copied) return reportError(copied.error());
  fmt::print("{} {} -> {} {}: {} ({}, as the original{})\n", (*from)->uri(), o.tag, (*to)->uri(), name,
             counted(copied->iovs, "IOV"), conddb::name(copied->state),
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
  diff->add_option("--tag", o->tags, "the two tags: --tag A --tag B")->required()->check(tagName());
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
