// The conditions database for every SQL engine: the schema, its check on open, and the upgrade
// of a database made by schema 1 (sql_database.hpp).

#include <algorithm>
#include <map>
#include <mutex>
#include <tuple>

#include <fmt/format.h>

#include "sql_database.hpp"

namespace emcalign::conddb::detail {

using io::Json;

namespace {

constexpr const char* kSchema[] = {
    "CREATE TABLE IF NOT EXISTS emcalign_meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)",
    kCreateTags,
    "CREATE TABLE IF NOT EXISTS emcalign_payloads (hash TEXT PRIMARY KEY, content TEXT NOT NULL)",
    "CREATE TABLE IF NOT EXISTS emcalign_iovs (tag TEXT NOT NULL REFERENCES emcalign_tags (name), "
    "first_run BIGINT NOT NULL, last_run BIGINT NOT NULL, payload TEXT NOT NULL REFERENCES emcalign_payloads (hash), "
    "inserted TEXT NOT NULL, PRIMARY KEY (tag, first_run), CHECK (first_run <= last_run))",
    "CREATE INDEX IF NOT EXISTS emcalign_iovs_last ON emcalign_iovs (tag, last_run)",
    // An IOV as it was before a promotion cut or extended it, for the snapshots before then.
    "CREATE TABLE IF NOT EXISTS emcalign_iovs_replaced (tag TEXT NOT NULL REFERENCES emcalign_tags (name), "
    "first_run BIGINT NOT NULL, last_run BIGINT NOT NULL, payload TEXT NOT NULL REFERENCES emcalign_payloads (hash), "
    "inserted TEXT NOT NULL, replaced TEXT NOT NULL, CHECK (first_run <= last_run))",
    "CREATE INDEX IF NOT EXISTS emcalign_iovs_replaced_tag ON emcalign_iovs_replaced (tag, first_run)",
    // Every change of a tag, numbered within it (seq), at increasing times.
    "CREATE TABLE IF NOT EXISTS emcalign_history (tag TEXT NOT NULL REFERENCES emcalign_tags (name), "
    "seq BIGINT NOT NULL, time TEXT NOT NULL, change TEXT NOT NULL, os_user TEXT NOT NULL, host TEXT NOT NULL, "
    "details TEXT NOT NULL, PRIMARY KEY (tag, seq))",
};

}  // namespace

std::function<void(const std::string&)>& noticeHandler() {
  static std::function<void(const std::string&)> handler = [](const std::string& text) {
    fmt::print(stderr, "emcalign: note: {}\n", text);
  };
  return handler;
}

namespace {

// A schema-1 time ("2026-12-05T04:47:58Z") in schema 2's form; other text kept as it is.
std::string microsOf(const std::string& text) {
  const auto t = utcMicrosOf(text);
  return t ? utcMicrosText(*t) : text;
}

}  // namespace

Status SqlDatabase::init() {
  // A database of schema 1 is upgraded (a prompt loop creating its database when missing opens
  // an existing one this way too).
  auto has = db_->hasSchema();
  if (!has) return has.error();
  if (*has) {
    auto version = db_->query("SELECT value FROM emcalign_meta WHERE key = 'schema_version'");
    if (!version) return version.error();
    if (!version->empty() && toText((*version)[0][0]) == "1") return upgradeFrom1();
  }
  return inTransaction(*db_, Access::Write, [&]() -> Status {
    if (Status s = db_->serializeSchemaChanges(); !s) return s;
    for (const char* sql : kSchema) {
      if (auto r = db_->query(sql); !r) return r.error();
    }
    auto version = db_->query("SELECT value FROM emcalign_meta WHERE key = 'schema_version'");
    if (!version) return version.error();
    if (version->empty()) {
      auto r = db_->query("INSERT INTO emcalign_meta (key, value) VALUES ('schema_version', $1)",
                          {std::to_string(kSchemaVersion)});
      if (!r) return r.error();
    } else if (toText((*version)[0][0]) != std::to_string(kSchemaVersion)) {
      return Error{fmt::format("{}: schema version {}, this emcalign knows {}", db_->uri(), toText((*version)[0][0]),
                               kSchemaVersion)};
    }
    return db_->afterInit();
  });
}

Status SqlDatabase::checkSchema() {
  auto has = db_->hasSchema();
  if (!has) return has.error();
  if (!*has) {
    return Error{
        fmt::format("{}: not an emcalign conditions database (no emcalign tables; create one with: emcalign "
                    "conditions init {})",
                    db_->uri(), db_->uri())};
  }
  auto version = db_->query("SELECT value FROM emcalign_meta WHERE key = 'schema_version'");
  if (!version) return version.error();
  const std::string v = version->empty() ? "unknown" : toText((*version)[0][0]);
  if (v == "1") return upgradeFrom1();
  if (v != std::to_string(kSchemaVersion)) {
    return Error{fmt::format("{}: schema version {}, this emcalign reads version {} (and upgrades 1)", db_->uri(), v,
                             kSchemaVersion)};
  }
  return {};
}

namespace {

// One change of a schema-1 tag, rebuilt from what that schema kept.
struct OldChange {
  std::string time;
  int order = 0;  // at one time: the creation, the IOVs, the state changes
  std::string change;
  Json details;
};

// The history schema 1 kept of tag `t` (name, description, state, created): its creation, its
// IOVs (`iovs`), its marks in emcalign_meta (running:, retired:, each a change of state), a lock
// last (its time not kept: `now`, the upgrade's); in order. The tag's state after them into
// `state`.
Result<std::vector<OldChange>> oldChanges(SqlBackend& db, const Row& t, const std::vector<Row>& iovs,
                                          const std::string& now, std::string& state) {
  const std::string name = toText(t[0]);
  const std::string created = microsOf(toText(t[3]));
  std::vector<OldChange> changes{{created, 0, "created", {{"state", "open"}, {"description", toText(t[1])}}}};
  for (const Row& i : iovs) {
    auto first = runOf(i[0], db.uri(), name);
    auto last = runOf(i[1], db.uri(), name);
    if (!first || !last) return (first ? last.error() : first.error());
    changes.push_back(
        {microsOf(toText(i[3])), 1, "iov", {{"first_run", *first}, {"last_run", *last}, {"payload", toText(i[2])}}});
  }
  auto marks = db.query("SELECT key, value FROM emcalign_meta WHERE key = $1 OR key = $2",
                        {"running:" + name, "retired:" + name});
  if (!marks) return marks.error();
  state = toText(t[2]);
  for (const std::string kind : {"running:", "retired:"}) {
    for (const Row& m : *marks) {
      if (toText(m[0]) != kind + name) continue;
      const Json mark = Json::parse(toText(m[1]), nullptr, false);
      const bool retired = kind == "retired:";
      const std::string when =
          mark.is_object() ? mark.value(retired ? "retired" : "since", std::string()) : std::string();
      const std::string to = retired ? "invalid" : "running";
      if (state == "published" || state == "invalid") continue;
      Json details = {{"from", state}, {"to", to}};
      if (retired && mark.is_object() && !mark.value("reason", std::string()).empty()) {
        details["reason"] = mark.value("reason", std::string());
      }
      changes.push_back({when.empty() ? now : microsOf(when), 2, "state", details});
      state = to;
    }
  }
  if (state == "published") {
    changes.push_back({now,
                       3,
                       "state",
                       {{"from", "open"},
                        {"to", "published"},
                        {"note", "locked under schema 1, which did not keep when: the time is the upgrade's"}}});
  }
  std::stable_sort(changes.begin(), changes.end(), [](const OldChange& a, const OldChange& b) {
    return std::tie(a.time, a.order) < std::tie(b.time, b.order);
  });
  return changes;
}

// Schema-1 tag `t` in schema 2: its history written (from_schema 1), its state, and the times
// of its creation and its IOVs to the microsecond.
Status upgradeTag(SqlBackend& db, const Row& t, const std::string& now) {
  const std::string name = toText(t[0]);
  const std::string created = microsOf(toText(t[3]));
  auto iovs = db.query(
      "SELECT first_run, last_run, payload, inserted FROM emcalign_iovs WHERE tag = $1 ORDER BY first_run", {name});
  if (!iovs) return iovs.error();
  std::string state;
  auto changes = oldChanges(db, t, *iovs, now, state);
  if (!changes) return changes.error();
  for (std::size_t k = 0; k < changes->size(); ++k) {
    const OldChange& c = (*changes)[k];
    Json details = c.details;
    details["from_schema"] = 1;
    auto r = db.query(
        "INSERT INTO emcalign_history (tag, seq, time, change, os_user, host, details) VALUES ($1, $2, $3, $4, "
        "'', '', $5)",
        {name, static_cast<std::int64_t>(k), c.time, c.change, details.dump()});
    if (!r) return r.error();
  }
  auto row = db.query("UPDATE emcalign_tags SET state = $2, created = $3 WHERE name = $1", {name, state, created});
  if (!row) return row.error();
  for (const Row& i : *iovs) {
    auto r = db.query("UPDATE emcalign_iovs SET inserted = $3 WHERE tag = $1 AND first_run = $2",
                      {name, std::stoll(toText(i[0])), microsOf(toText(i[3]))});
    if (!r) return r.error();
  }
  return {};
}

}  // namespace

// Schema 1 → 2: the six tag states (locked → published, the retired:/running: marks of
// emcalign_meta → invalid, running), times to the microsecond, the tables of replaced IOVs and
// of history, each tag's history rebuilt from what schema 1 kept (its creation, its IOVs, its
// marks; a lock's time was not kept: the upgrade's). One transaction; said once.
Status SqlDatabase::upgradeFrom1() {
  if (Status s = db_->beforeSchemaUpgrade(); !s) return s;
  bool upgraded = false;
  std::size_t tagCount = 0;
  Status done = inTransaction(*db_, Access::Write, [&]() -> Status {
    if (Status s = db_->serializeSchemaChanges(); !s) return s;
    auto version = db_->query("SELECT value FROM emcalign_meta WHERE key = 'schema_version'");
    if (!version) return version.error();
    if (!version->empty() && toText((*version)[0][0]) == std::to_string(kSchemaVersion)) return {};  // another did
    if (Status s = db_->widenTagStates(kCreateTags); !s) return s;
    for (const char* sql : kSchema) {
      if (auto r = db_->query(sql); !r) return r.error();
    }
    const std::string now = utcMicrosText(utcNowMicros());
    auto tags = db_->query("SELECT name, description, state, created FROM emcalign_tags ORDER BY name");
    if (!tags) return tags.error();
    tagCount = tags->size();
    for (const Row& t : *tags) {
      if (Status s = upgradeTag(*db_, t, now); !s) return s;
    }
    for (const char* prefix : {"running:", "retired:"}) {
      auto r = db_->query("DELETE FROM emcalign_meta WHERE substr(key, 1, $1) = $2",
                          {static_cast<std::int64_t>(std::string_view(prefix).size()), std::string(prefix)});
      if (!r) return r.error();
    }
    auto v = db_->query("UPDATE emcalign_meta SET value = $1 WHERE key = 'schema_version'",
                        {std::to_string(kSchemaVersion)});
    if (!v) return v.error();
    if (Status s = db_->afterInit(); !s) return s;
    upgraded = true;
    return {};
  });
  db_->afterSchemaUpgrade();
  if (!done) {
    return Error{
        fmt::format("{}: a database of schema 1, which this emcalign upgrades to {} on opening, and could not: "
                    "{} (nothing changed)",
                    db_->uri(), kSchemaVersion, done.error().message)};
  }
  if (upgraded) {
    noticeHandler()(fmt::format(
        "{}: upgraded from schema 1 to {} ({} tags): tag states (locked is now published, retired invalid), each "
        "tag's history (from what schema 1 kept) and snapshots; emcalign before this version no longer opens it",
        db_->uri(), kSchemaVersion, tagCount));
  }
  return {};
}

}  // namespace emcalign::conddb::detail

namespace emcalign::conddb {

void Database::setNoticeHandler(std::function<void(const std::string&)> handler) {
  detail::noticeHandler() = std::move(handler);
}

}  // namespace emcalign::conddb
