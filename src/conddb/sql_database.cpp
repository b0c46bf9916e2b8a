// The semantics of the conditions database, once, for every SQL engine (sql_backend.hpp).

#include <charconv>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <thread>

#include <fmt/format.h>

#include "emcalign/core/secrets.hpp"

#include "emcalign/core/utf8.hpp"
#include "sql_backend.hpp"

namespace emcalign::conddb::detail {

namespace {

using io::Json;

constexpr const char* kSchema[] = {
    "CREATE TABLE IF NOT EXISTS emcalign_meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)",
    "CREATE TABLE IF NOT EXISTS emcalign_tags (name TEXT PRIMARY KEY, description TEXT NOT NULL, "
    "state TEXT NOT NULL CHECK (state IN ('open', 'locked')), created TEXT NOT NULL)",
    "CREATE TABLE IF NOT EXISTS emcalign_payloads (hash TEXT PRIMARY KEY, content TEXT NOT NULL)",
    "CREATE TABLE IF NOT EXISTS emcalign_iovs (tag TEXT NOT NULL REFERENCES emcalign_tags (name), "
    "first_run BIGINT NOT NULL, last_run BIGINT NOT NULL, payload TEXT NOT NULL REFERENCES emcalign_payloads (hash), "
    "inserted TEXT NOT NULL, PRIMARY KEY (tag, first_run), CHECK (first_run <= last_run))",
    "CREATE INDEX IF NOT EXISTS emcalign_iovs_last ON emcalign_iovs (tag, last_run)",
};

enum class Access { Read, Write };

// Runs `body` in a transaction; any error rolls it back.
template <typename F>
auto inTransaction(SqlBackend& db, Access access, F&& body) -> decltype(body()) {
  if (Status s = access == Access::Write ? db.beginWrite() : db.beginRead(); !s) return s.error();
  auto result = body();
  if (!result) {
    db.rollback();
    return result;
  }
  if (Status s = db.commit(); !s) {
    db.rollback();
    return s.error();
  }
  return result;
}

// Fault injection for the tests of a writer killed mid-write (tests/unit/conddb): with
// EMCALIGN_FAULT_HOLD_WRITE=PATH, a write creates PATH once everything is written but not
// yet committed, and waits there (up to a minute) to be killed.
void holdWriteForTests() {
  const char* path = std::getenv("EMCALIGN_FAULT_HOLD_WRITE");
  if (path == nullptr || *path == '\0') return;
  if (std::FILE* f = std::fopen(path, "w"); f != nullptr) std::fclose(f);
  std::this_thread::sleep_for(std::chrono::seconds(60));
}

std::string toText(const std::optional<std::string>& s) { return s ? *s : std::string(); }

// A run number as stored: an integer, 0 or more. Anything else (2.5, 'x', -5: a database edited
// by hand) is an error, not a number read as well as it goes.
Result<std::int64_t> runOf(const std::optional<std::string>& s, const std::string& uri, const std::string& tag) {
  std::int64_t run = -1;
  const std::string text = s.value_or("");
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), run);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size() || run < 0) {
    return Error{
        fmt::format("{}: tag '{}': the run '{}' of an IOV is not a run number (the database was edited behind "
                    "emcalign's back?)",
                    uri, tag, printable(text).substr(0, 32))};
  }
  return run;
}

std::int64_t toInt(const std::optional<std::string>& s) {
  std::int64_t x = 0;
  if (s) std::from_chars(s->data(), s->data() + s->size(), x);
  return x;
}

// The IOV of a row (first_run, last_run, payload, inserted), its runs checked.
Result<Iov> iovOf(const Row& r, const std::string& uri, const std::string& tag) {
  auto first = runOf(r[0], uri, tag);
  if (!first) return first.error();
  auto last = runOf(r[1], uri, tag);
  if (!last) return last.error();
  return Iov{*first, *last, toText(r[2]), printable(toText(r[3]))};
}

class SqlDatabase final : public Database {
 public:
  explicit SqlDatabase(std::unique_ptr<SqlBackend> db) : db_(std::move(db)) {}
  using Database::put;

  Status init() override {
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

  // On open: the schema must be this one.
  Status checkSchema() {
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
    if (version->empty() || toText((*version)[0][0]) != std::to_string(kSchemaVersion)) {
      return Error{fmt::format("{}: schema version {}, this emcalign reads version {}", db_->uri(),
                               version->empty() ? "unknown" : toText((*version)[0][0]), kSchemaVersion)};
    }
    return {};
  }

  Result<std::vector<Tag>> tags() override {
    auto rows = db_->query(tagColumns() + " ORDER BY t.name");
    if (!rows) return rows.error();
    std::vector<Tag> out;
    for (const Row& r : *rows) {
      auto t = tagOf(r);
      if (!t) return t.error();
      out.push_back(std::move(*t));
    }
    return out;
  }

  Result<std::optional<Tag>> tag(const std::string& name) override {
    if (Status s = checkTagName(name); !s) return s.error();
    auto rows = db_->query(tagColumns() + " WHERE t.name = $1", {name});
    if (!rows) return rows.error();
    if (rows->empty()) return std::optional<Tag>();
    auto t = tagOf((*rows)[0]);
    if (!t) return t.error();
    return std::optional<Tag>(std::move(*t));
  }

  Status put(const std::string& tag, const std::vector<NewIov>& iovs, IfMissing newTag,
             const std::string& givenDescription) override {
    // The command line's passwords are never stored (a URI pasted into a description).
    const std::string description = core::withoutAnyPassword(givenDescription);
    if (Status s = checkTagName(tag); !s) return s;
    if (Status s = checkText(description, "a tag's description"); !s) return s;
    for (const NewIov& n : iovs) {
      if (n.firstRun > n.lastRun) {
        return Error{fmt::format("runs {}-{}: the first run is after the last", n.firstRun, n.lastRun)};
      }
    }
    return inTransaction(*db_, Access::Write, [&]() -> Status {
      auto state = lockTagRow(tag);
      if (!state) return Error{fmt::format("tag '{}': {}", tag, state.error().message)};
      if (state->empty()) {
        if (newTag == IfMissing::Refuse) {
          return Error{
              fmt::format("{}: no tag '{}' (conditions put creates it; list the tags with: emcalign "
                          "conditions list {})",
                          db_->uri(), tag, db_->uri())};
        }
        auto created = db_->query(
            "INSERT INTO emcalign_tags (name, description, state, created) VALUES ($1, $2, 'open', $3) "
            "ON CONFLICT (name) DO NOTHING",
            {tag, description, utcNow()});
        if (!created) return created.error();
        state = lockTagRow(tag);
        if (!state) return Error{fmt::format("tag '{}': {}", tag, state.error().message)};
      }
      if (state->empty()) return Error{fmt::format("{}: tag '{}' vanished while writing", db_->uri(), tag)};
      if (toText((*state)[0][0]) == "locked") {
        return Error{
            fmt::format("{}: tag '{}' is locked: its IOVs never change (write to a new tag)", db_->uri(), tag)};
      }
      if (toText((*state)[0][0]) != "open") {  // edited by hand: written to only when surely open
        return Error{fmt::format("{}: tag '{}' has the state '{}', neither open nor locked: not written", db_->uri(),
                                 tag, printable(toText((*state)[0][0])))};
      }
      if (Status s = notRetired(tag); !s) return s;
      auto running = isRunning(tag);
      if (!running) return running.error();
      const std::string now = utcNow();
      for (const NewIov& n : iovs) {
        if (*running) {
          auto last = lastRunOf(tag);
          if (!last) return last.error();
          if (*last && n.firstRun <= **last) {
            return Error{fmt::format(
                "{}: tag '{}' is running: IOVs are only appended after its last run {}, and runs {}-{} are not",
                db_->uri(), tag, **last, n.firstRun, n.lastRun)};
          }
        }
        // Checked against the IOVs stored before and those of this same write.
        if (Status s = insertIov(tag, n, now); !s) return s;
      }
      holdWriteForTests();
      return {};
    });
  }

  Result<std::optional<std::pair<Iov, Payload>>> get(const std::string& tag, std::int64_t run) override {
    using Out = std::optional<std::pair<Iov, Payload>>;
    if (Status s = checkTagName(tag); !s) return s.error();
    return inTransaction(*db_, Access::Read, [&]() -> Result<Out> {
      if (Status s = notRetired(tag); !s) return s.error();
      auto rows = db_->query(
          "SELECT i.first_run, i.last_run, i.payload, i.inserted, p.content FROM emcalign_iovs i JOIN "
          "emcalign_payloads p ON p.hash = i.payload WHERE i.tag = $1 AND i.first_run <= $2 AND i.last_run >= $2",
          {tag, run});
      if (!rows) return rows.error();
      if (rows->empty()) return Out();
      if (rows->size() > 1) {
        return Error{
            fmt::format("{}: tag '{}': {} IOVs hold run {}: they overlap (the database was edited behind "
                        "emcalign's back?)",
                        db_->uri(), tag, rows->size(), run)};
      }
      const Row& r = (*rows)[0];
      auto payload = verifiedPayload(toText(r[2]), toText(r[4]));
      if (!payload) return payload.error();
      auto iov = iovOf(r, db_->uri(), tag);
      if (!iov) return iov.error();
      return Out(std::pair{std::move(*iov), std::move(*payload)});
    });
  }

  Result<std::vector<Iov>> iovs(const std::string& tag) override {
    if (Status s = checkTagName(tag); !s) return s.error();
    auto rows = db_->query(
        "SELECT first_run, last_run, payload, inserted FROM emcalign_iovs WHERE tag = $1 ORDER BY first_run", {tag});
    if (!rows) return rows.error();
    std::vector<Iov> out;
    for (const Row& r : *rows) {
      auto read = iovOf(r, db_->uri(), tag);
      if (!read) return read.error();
      Iov iov = std::move(*read);
      // Written by emcalign, the IOVs of a tag never overlap; by hand, they might.
      if (iov.firstRun > iov.lastRun || (!out.empty() && iov.firstRun <= out.back().lastRun)) {
        return Error{fmt::format("{}: tag '{}': the IOV {}-{} {} (the database was edited behind emcalign's back?)",
                                 db_->uri(), tag, iov.firstRun, iov.lastRun,
                                 iov.firstRun > iov.lastRun
                                     ? "runs backwards"
                                     : fmt::format("overlaps the IOV {}-{}", out.back().firstRun, out.back().lastRun))};
      }
      out.push_back(std::move(iov));
    }
    return out;
  }

  Result<Payload> payload(const std::string& hash) override {
    auto rows = db_->query("SELECT content FROM emcalign_payloads WHERE hash = $1", {hash});
    if (!rows) return rows.error();
    if (rows->empty()) return Error{fmt::format("{}: no payload {}", db_->uri(), printable(hash))};
    return verifiedPayload(hash, toText((*rows)[0][0]));
  }

  Status lock(const std::string& tag) override {
    if (Status s = checkTagName(tag); !s) return s;
    return inTransaction(*db_, Access::Write, [&]() -> Status {
      if (Status s = notRetired(tag); !s) return s;
      auto rows = db_->query("UPDATE emcalign_tags SET state = 'locked' WHERE name = $1", {tag});
      if (!rows) return rows.error();
      auto exists = db_->query("SELECT state FROM emcalign_tags WHERE name = $1", {tag});
      if (!exists) return exists.error();
      if (exists->empty()) return Error{fmt::format("{}: no tag '{}'", db_->uri(), tag)};
      return {};
    });
  }

  Status retire(const std::string& tag, const std::string& givenReason) override {
    const std::string reason = core::withoutAnyPassword(givenReason);
    if (Status s = checkTagName(tag); !s) return s;
    if (Status s = checkText(reason, "the reason"); !s) return s;
    return inTransaction(*db_, Access::Write, [&]() -> Status {
      auto state = lockTagRow(tag);
      if (!state) return state.error();
      if (state->empty()) return Error{fmt::format("{}: no tag '{}'", db_->uri(), tag)};
      if (toText((*state)[0][0]) == "locked") {
        return Error{fmt::format(
            "{}: tag '{}' is locked: a published calibration is never withdrawn (store the corrected one under a "
            "new tag, and point the users at it)",
            db_->uri(), tag)};
      }
      // Retired already: the same again (a retry) changes nothing; another reason is refused,
      // naming the one kept.
      auto earlier = db_->query("SELECT value FROM emcalign_meta WHERE key = $1", {std::string(kRetiredPrefix) + tag});
      if (!earlier) return earlier.error();
      if (!earlier->empty()) {
        const Json was = Json::parse(toText((*earlier)[0][0]), nullptr, false);
        if (was.is_object() && was.value("reason", std::string()) == reason) return {};
        return Error{
            fmt::format("{}: tag '{}' was retired already ({}): a retirement keeps its first reason; nothing changed",
                        db_->uri(), tag, retiredNote(toText((*earlier)[0][0])))};
      }
      const Json mark = {{"retired", utcNow()}, {"reason", reason}};
      auto r = db_->query("INSERT INTO emcalign_meta (key, value) VALUES ($1, $2) ON CONFLICT (key) DO NOTHING",
                          {std::string(kRetiredPrefix) + tag, mark.dump()});
      if (!r) return r.error();
      return {};
    });
  }

  Status makeRunning(const std::string& tag, const std::string& givenDescription) override {
    const std::string description = core::withoutAnyPassword(givenDescription);
    if (Status s = checkTagName(tag); !s) return s;
    if (Status s = checkText(description, "a tag's description"); !s) return s;
    return inTransaction(*db_, Access::Write, [&]() -> Status {
      auto state = lockTagRow(tag);
      if (!state) return state.error();
      if (state->empty()) {
        const std::string now = utcNow();
        auto created =
            db_->query("INSERT INTO emcalign_tags (name, description, state, created) VALUES ($1, $2, 'open', $3)",
                       {tag, description, now});
        if (!created) return created.error();
        auto mark = db_->query("INSERT INTO emcalign_meta (key, value) VALUES ($1, $2)",
                               {std::string(kRunningPrefix) + tag, Json{{"since", now}}.dump()});
        if (!mark) return mark.error();
        return {};
      }
      auto t = this->tag(tag);
      if (!t) return t.error();
      if ((*t)->state != TagState::Running) {
        return Error{
            fmt::format("{}: tag '{}' is {}, not running: a prompt loop writes only a running tag (its own, "
                        "made by it); give it a new tag",
                        db_->uri(), tag, name((*t)->state))};
      }
      return {};
    });
  }

  Status appendPrompt(const std::string& tag, const PromptRecord& r) override {
    if (Status s = checkTagName(tag); !s) return s;
    if (Status s = checkText(r.decision, "a decision"); !s) return s;
    return inTransaction(*db_, Access::Write, [&]() -> Status {
      auto state = lockTagRow(tag);
      if (!state) return state.error();
      auto t = this->tag(tag);
      if (!t) return t.error();
      if (!t->has_value() || (*t)->state != TagState::Running) {
        return Error{fmt::format("{}: tag '{}' is {}: a decision is stored only into a running tag", db_->uri(), tag,
                                 t->has_value() ? std::string(name((*t)->state)) : std::string("missing"))};
      }
      const std::string key = promptKey(tag, r.group);
      auto earlier = db_->query("SELECT value FROM emcalign_meta WHERE key = $1", {key});
      if (!earlier) return earlier.error();
      if (!earlier->empty()) {
        if (toText((*earlier)[0][0]) == r.decision) return {};  // a retry: stored already
        return Error{fmt::format("{}: tag '{}': group {} was decided already, otherwise: a group is decided once",
                                 db_->uri(), tag, r.group)};
      }
      auto decided = promptRecordsOf(tag);
      if (!decided) return decided.error();
      if (static_cast<std::int64_t>(decided->size()) != r.group) {
        return Error{fmt::format("{}: tag '{}' has {} decided groups: group {} is not the next", db_->uri(), tag,
                                 decided->size(), r.group)};
      }
      if (r.iov) {
        auto last = lastRunOf(tag);
        if (!last) return last.error();
        if (r.iov->firstRun > r.iov->lastRun || (*last && r.iov->firstRun != **last + 1)) {
          return Error{
              fmt::format("{}: tag '{}': runs {}-{} do not start right after its last IOV (run {}): a "
                          "running tag's IOVs tile the runs",
                          db_->uri(), tag, r.iov->firstRun, r.iov->lastRun, last->value_or(-1))};
        }
        if (Status s = insertIov(tag, *r.iov, utcNow()); !s) return s;
      }
      auto thresholds =
          db_->query("INSERT INTO emcalign_meta (key, value) VALUES ($1, $2) ON CONFLICT (key) DO NOTHING",
                     {std::string(kThresholdsPrefix) + r.thresholdsSha256, r.thresholds});
      if (!thresholds) return thresholds.error();
      auto record = db_->query("INSERT INTO emcalign_meta (key, value) VALUES ($1, $2)", {key, r.decision});
      if (!record) return record.error();
      holdWriteForTests();
      return {};
    });
  }

  Result<std::vector<std::string>> promptRecords(const std::string& tag) override {
    if (Status s = checkTagName(tag); !s) return s.error();
    return inTransaction(*db_, Access::Read, [&] { return promptRecordsOf(tag); });
  }

  Result<std::string> claimPrompt(const std::string& tag, const std::string& me,
                                  const std::function<bool(const std::string&)>& alive) override {
    if (Status s = checkTagName(tag); !s) return s.error();
    return inTransaction(*db_, Access::Write, [&]() -> Result<std::string> {
      const std::string key = std::string(kOwnerPrefix) + tag;
      auto owner = db_->query(fmt::format("SELECT value FROM emcalign_meta WHERE key = $1{}", db_->forUpdate()), {key});
      if (!owner) return owner.error();
      if (!owner->empty()) {
        const std::string other = toText((*owner)[0][0]);
        if (other != me && alive(other)) return printable(other);
        auto r = db_->query("UPDATE emcalign_meta SET value = $2 WHERE key = $1", {key, me});
        if (!r) return r.error();
        return std::string();
      }
      auto r = db_->query("INSERT INTO emcalign_meta (key, value) VALUES ($1, $2)", {key, me});
      if (!r) return r.error();
      return std::string();
    });
  }

  Result<std::optional<std::string>> thresholds(const std::string& sha256) override {
    auto rows = db_->query("SELECT value FROM emcalign_meta WHERE key = $1", {std::string(kThresholdsPrefix) + sha256});
    if (!rows) return rows.error();
    if (rows->empty()) return std::optional<std::string>();
    return std::optional<std::string>(toText((*rows)[0][0]));
  }

  [[nodiscard]] const std::string& uri() const override { return db_->uri(); }

 private:
  // "prompt:TAG:000000000042": in the order of the groups as text.
  static std::string promptKey(const std::string& tag, std::int64_t group) {
    return fmt::format("{}{}:{:012}", kPromptPrefix, tag, group);
  }

  Result<std::vector<std::string>> promptRecordsOf(const std::string& tag) {
    const std::string prefix = fmt::format("{}{}:", kPromptPrefix, tag);
    auto rows = db_->query("SELECT value FROM emcalign_meta WHERE substr(key, 1, $1) = $2 ORDER BY key",
                           {static_cast<std::int64_t>(prefix.size()), prefix});
    if (!rows) return rows.error();
    std::vector<std::string> out;
    for (const Row& r : *rows) out.push_back(toText(r[0]));
    return out;
  }

  // The state of a tag's row, locked for the rest of the write (no rows: no such tag).
  Result<std::vector<Row>> lockTagRow(const std::string& tag) {
    return db_->query(fmt::format("SELECT state FROM emcalign_tags WHERE name = $1{}", db_->forUpdate()), {tag});
  }

  Result<bool> isRunning(const std::string& tag) {
    auto mark = db_->query("SELECT value FROM emcalign_meta WHERE key = $1", {std::string(kRunningPrefix) + tag});
    if (!mark) return mark.error();
    return !mark->empty();
  }

  // The last run of the tag's IOVs; none without IOVs.
  Result<std::optional<std::int64_t>> lastRunOf(const std::string& tag) {
    auto rows = db_->query("SELECT MAX(last_run) FROM emcalign_iovs WHERE tag = $1", {tag});
    if (!rows) return rows.error();
    if (rows->empty() || !(*rows)[0][0]) return std::optional<std::int64_t>();
    auto run = runOf((*rows)[0][0], db_->uri(), tag);
    if (!run) return run.error();
    return std::optional<std::int64_t>(*run);
  }

  // One IOV with its payload (stored once under its hash); the overlap checked.
  Status insertIov(const std::string& tag, const NewIov& n, const std::string& now) {
    auto overlap = db_->query(
        "SELECT first_run, last_run FROM emcalign_iovs WHERE tag = $1 AND first_run <= $2 AND last_run >= $3 "
        "ORDER BY first_run LIMIT 1",
        {tag, n.lastRun, n.firstRun});
    if (!overlap) return overlap.error();
    if (!overlap->empty()) {
      return Error{fmt::format("{}: tag '{}': runs {}-{} overlap its IOV {}-{} (the IOVs of a tag never overlap)",
                               db_->uri(), tag, n.firstRun, n.lastRun, toInt((*overlap)[0][0]),
                               toInt((*overlap)[0][1]))};
    }
    auto stored =
        db_->query("INSERT INTO emcalign_payloads (hash, content) VALUES ($1, $2) ON CONFLICT (hash) DO NOTHING",
                   {n.payload.hash(), n.payload.content.dump()});
    if (!stored) return stored.error();
    auto iov = db_->query(
        "INSERT INTO emcalign_iovs (tag, first_run, last_run, payload, inserted) VALUES ($1, $2, $3, $4, $5)",
        {tag, n.firstRun, n.lastRun, n.payload.hash(), now});
    if (!iov) return iov.error();
    return {};
  }

  static constexpr const char* kRetiredPrefix = "retired:";
  static constexpr const char* kRunningPrefix = "running:";
  static constexpr const char* kPromptPrefix = "prompt:";
  static constexpr const char* kThresholdsPrefix = "thresholds:";
  static constexpr const char* kOwnerPrefix = "prompt-owner:";
  // A tag's row with its retirement mark, if any (the columns tagOf reads).
  static std::string tagColumns() {
    return fmt::format(
        "SELECT t.name, t.description, t.state, t.created, m.value, r.value FROM emcalign_tags t LEFT JOIN "
        "emcalign_meta m ON m.key = '{}' || t.name LEFT JOIN emcalign_meta r ON r.key = '{}' || t.name",
        kRetiredPrefix, kRunningPrefix);
  }

  // Lookups and writes refuse a retired tag, naming when and why it was retired.
  Status notRetired(const std::string& tag) const {
    auto mark = db_->query("SELECT value FROM emcalign_meta WHERE key = $1", {std::string(kRetiredPrefix) + tag});
    if (!mark) return mark.error();
    if (mark->empty()) return {};
    return Error{
        fmt::format("{}: tag '{}' was retired ({}): it is kept and listed, but never served or written "
                    "to",
                    db_->uri(), tag, retiredNote(toText((*mark)[0][0])))};
  }

  // "2026-12-02T01:02:03Z: the wrong corrections" from a mark's JSON.
  static std::string retiredNote(const std::string& text) {
    const Json j = Json::parse(text, nullptr, false);
    if (!j.is_object()) return "?";
    const std::string when = j.value("retired", std::string("?")), why = j.value("reason", std::string());
    return printable(why.empty() ? when : when + ": " + why);
  }

  // Text read back is made printable (a database edited by hand may hold anything: bytes that
  // are not UTF-8, terminal escapes): core/utf8.hpp.
  Result<Tag> tagOf(const Row& r) const {
    const std::string state = toText(r[2]);
    if (state != "open" && state != "locked") {
      return Error{
          fmt::format("{}: tag '{}' has the state '{}', neither open nor locked (the database was edited "
                      "behind emcalign's back?)",
                      db_->uri(), printable(toText(r[0])), printable(state))};
    }
    Tag t{printable(toText(r[0])),
          printable(toText(r[1])),
          state == "locked" ? TagState::Locked : TagState::Open,
          printable(toText(r[3])),
          {}};
    if (r.size() > 4 && r[4]) {
      if (t.state == TagState::Locked) {
        return Error{
            fmt::format("{}: tag '{}' is locked and retired at once (the database was edited behind "
                        "emcalign's back?)",
                        db_->uri(), t.name)};
      }
      t.state = TagState::Retired;
      t.retired = retiredNote(*r[4]);
    } else if (r.size() > 5 && r[5] && t.state == TagState::Open) {
      t.state = TagState::Running;
    }
    return t;
  }

  // A payload as stored under `hash`: its content must still have that hash (every read
  // checks it, so an edit behind the tool's back is never served under the old name).
  Result<Payload> verifiedPayload(const std::string& hash, const std::string& text) const {
    const std::string source = fmt::format("{}: payload {}…", db_->uri(), printable(hash).substr(0, 12));
    if (!isValidUtf8(text)) return Error{fmt::format("{}: not UTF-8 text (edited by hand?)", source)};
    auto content = io::parseJson(text, source);
    if (!content) return content.error();
    Payload p{std::move(*content)};
    if (p.hash() != hash) {
      return Error{
          fmt::format("{}: its content no longer has that hash (the database was edited behind emcalign's "
                      "back?): refusing to use it",
                      source)};
    }
    return p;
  }

  static Status checkText(const std::string& text, std::string_view what) {
    if (text.find('\0') != std::string::npos) return Error{fmt::format("{} holds a NUL character", what)};
    if (!isValidUtf8(text)) return Error{fmt::format("{} is not UTF-8 text", what)};
    return {};
  }

  std::unique_ptr<SqlBackend> db_;
};

}  // namespace

Status checkParams(const std::vector<Param>& params, const std::string& uri) {
  for (const Param& p : params) {
    if (std::holds_alternative<std::string>(p) && std::get<std::string>(p).find('\0') != std::string::npos) {
      return Error{fmt::format("{}: a text with a NUL character cannot be stored or looked up", uri)};
    }
  }
  return {};
}

std::unique_ptr<Database> makeSqlDatabase(std::unique_ptr<SqlBackend> backend) {
  return std::make_unique<SqlDatabase>(std::move(backend));
}

Status checkSchemaOf(Database& db) { return static_cast<SqlDatabase&>(db).checkSchema(); }

}  // namespace emcalign::conddb::detail
