// emcalign conditions state|promote|history: the audit of a conditions database
// (conddb/tag_states.hpp, docs/campaign.md "Tag states").
//
//   conditions state URI --tag T [--set STATE [--reason TEXT]]
//   conditions promote URI --from S --to R --first-safe-run N [--dry-run]
//   conditions history URI --tag T [--json]
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/utf8.hpp"

namespace emcalign::app {

namespace {

using io::Json;

struct AuditOptions {
  std::string uri, tag, set, reason, from, to;
  std::int64_t firstSafeRun = 0;
  bool dryRun = false, json = false;
};

int runState(const AuditOptions& o) {
  auto db = must(conddb::Database::open(o.uri));
  if (o.set.empty()) {
    auto t = must(db->tag(o.tag));
    if (!t) refuse(fmt::format("{}: no tag '{}'", db->uri(), o.tag));
    fmt::print("{}\n", conddb::name(t->state));
    return kExitOk;
  }
  const auto to = conddb::tagStateNamed(o.set);  // checked by the option
  auto before = must(db->tag(o.tag));
  auto changed = must(db->setState(o.tag, *to, o.reason));
  if (changed == conddb::Database::StateChange::Already) {
    fmt::print("{}: tag {} is {} already: nothing changed\n", db->uri(), o.tag, o.set);
    return kExitOk;
  }
  fmt::print("{}: tag {}: {} -> {}{}\n", db->uri(), o.tag, conddb::name(before->state), o.set,
             o.reason.empty() ? std::string() : " (" + o.reason + ")");
  return kExitOk;
}

int runPromote(const AuditOptions& o) {
  auto db = must(conddb::Database::open(o.uri));
  auto p = must(db->promote(o.from, o.to, o.firstSafeRun, o.dryRun));
  const conddb::Iov& last = p.lastBefore;
  fmt::print("{}: {}promotion of {} into {} from run {}: the last IOV of {} {}-{} {}{}; {} appended (runs {}-{})\n",
             db->uri(), o.dryRun ? "dry run, nothing written: " : "", o.from, o.to, o.firstSafeRun, o.to, last.firstRun,
             last.lastRun, o.dryRun ? "would be " + p.lastIovFate() : p.lastIovFate(),
             p.lastIovFate() == "kept" ? std::string() : fmt::format(" to {}-{}", last.firstRun, o.firstSafeRun - 1),
             counted(p.appended.size(), "IOV"), p.appended.front().firstRun, p.appended.back().lastRun);
  if (!o.dryRun) fmt::print("  at {} (conditions history {} --tag {})\n", p.time, db->uri(), o.to);
  return kExitOk;
}

int runHistory(const AuditOptions& o) {
  auto db = must(conddb::Database::open(o.uri));
  auto changes = must(db->history(o.tag));
  if (o.json) {
    Json out = Json::array();
    for (const auto& c : changes) out.push_back(c.json());
    fmt::print("{}\n", out.dump(2));
    return kExitOk;
  }
  std::string text =
      fmt::format("{}: tag {}: {}, oldest first (UTC)\n", db->uri(), o.tag, counted(changes.size(), "change"));
  for (const auto& c : changes) {
    const std::string who = c.user.empty() && c.host.empty() ? std::string("-") : c.user + "@" + c.host;
    // Escaped: the stored text may have been written by another client (a forged line, a
    // terminal escape), as `list` and `state` show it.
    text += fmt::format("{}  {:<20} {:<9}  {}\n", printable(c.time), printable(who), printable(c.change),
                        printable(c.summary()));
  }
  fmt::print("{}", text);
  return kExitOk;
}

CLI::Validator stateName() {
  return CLI::Validator(
      [](std::string& t) -> std::string {
        if (conddb::tagStateNamed(t)) return {};
        return fmt::format("'{}' is no tag state: open, testing, validated, published, running or invalid", t);
      },
      "STATE");
}

}  // namespace

void addConditionsAuditCommands(CLI::App& conditions, int& exitCode) {
  auto o = std::make_shared<AuditOptions>();
  const auto uri = [&](CLI::App& cmd) {
    cmd.add_option("uri", o->uri, "database: sqlite:PATH, a path, or postgresql://user@host:port/db")->required();
  };

  auto* state = conditions.add_subcommand(
      "state",
      "Print a tag's state, or set it (--set): open -> testing|running|published|invalid, testing -> "
      "open|validated|invalid, validated -> published|running|invalid, running -> published|invalid");
  uri(*state);
  state->add_option("--tag", o->tag, "the tag")->required()->check(tagName());
  auto* set = state->add_option("--set", o->set, "the new state (a refused transition exits 1, nothing written)")
                  ->check(stateName());
  state->add_option("--reason", o->reason, "why, kept in the tag's history")->needs(set);
  state->callback([o, &exitCode] { exitCode = runState(*o); });

  auto* promote = conditions.add_subcommand(
      "promote",
      "Append a validated tag's IOVs to a running tag from the first safe run (Belle II's running update), in "
      "one transaction");
  uri(*promote);
  promote->add_option("--from", o->from, "the validated tag (no gaps, its first IOV starting at --first-safe-run)")
      ->required()
      ->check(tagName());
  promote->add_option("--to", o->to, "the running tag (its last IOV then ends at --first-safe-run - 1)")
      ->required()
      ->check(tagName());
  promote->add_option("--first-safe-run", o->firstSafeRun, "the first run still safe to change")
      ->required()
      ->check(integerIn(0, INT64_MAX));
  promote->add_flag("--dry-run", o->dryRun, "say what would be done; write nothing");
  promote->callback([o, &exitCode] { exitCode = runPromote(*o); });

  auto* history = conditions.add_subcommand(
      "history", "Every change of a tag, oldest first: when (UTC), by whom (user@host), what");
  uri(*history);
  history->add_option("--tag", o->tag, "the tag")->required()->check(tagName());
  history->add_flag("--json", o->json,
                    "JSON: [{\"time\", \"change\", \"user\", \"host\", ...what changed}] (time: ISO 8601 UTC, "
                    "microseconds)");
  history->callback([o, &exitCode] { exitCode = runHistory(*o); });
}

}  // namespace emcalign::app
