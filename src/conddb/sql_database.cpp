// The conditions database for every SQL engine: reading (now or at a snapshot) and writing IOVs
// (sql_database.hpp says where the rest is).

#include "sql_database.hpp"

#include <pwd.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include <fmt/format.h>

#include "emcalign/core/secrets.hpp"
#include "emcalign/core/utf8.hpp"

namespace emcalign::conddb::detail {

using io::Json;

void holdWriteForTests() {
  const char* path = std::getenv("EMCALIGN_FAULT_HOLD_WRITE");
  if (path == nullptr || *path == '\0') return;
  if (std::FILE* f = std::fopen(path, "w"); f != nullptr) std::fclose(f);
  // EMCALIGN_FAULT_HOLD_SECONDS: how long (default 60, for a test that kills the writer).
  double seconds = 60.0;
  if (const char* s = std::getenv("EMCALIGN_FAULT_HOLD_SECONDS"); s != nullptr)
    seconds = std::clamp(std::atof(s), 0.0, 600.0);
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
}

std::string toText(const std::optional<std::string>& s) { return s ? *s : std::string(); }

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

Result<Iov> iovOf(const Row& r, const std::string& uri, const std::string& tag) {
  auto first = runOf(r[0], uri, tag);
  if (!first) return first.error();
  auto last = runOf(r[1], uri, tag);
  if (!last) return last.error();
  return Iov{*first, *last, toText(r[2]), printable(toText(r[3]))};
}

Status checkText(const std::string& text, std::string_view what) {
  if (text.find('\0') != std::string::npos) return Error{fmt::format("{} holds a NUL character", what)};
  if (!isValidUtf8(text)) return Error{fmt::format("{} is not UTF-8 text", what)};
  return {};
}

const std::string& osUser() {
  static const std::string user = [] {
    std::vector<char> buffer(16384);
    passwd pw{};
    passwd* found = nullptr;
    if (::getpwuid_r(::geteuid(), &pw, buffer.data(), buffer.size(), &found) == 0 && found != nullptr &&
        found->pw_name != nullptr) {
      return std::string(found->pw_name);
    }
    if (const char* u = std::getenv("USER"); u != nullptr && *u != '\0') return std::string(u);
    return fmt::format("uid {}", ::geteuid());
  }();
  return user;
}

const std::string& hostName() {
  static const std::string host = [] {
    char name[256] = {};
    if (::gethostname(name, sizeof name - 1) != 0) return std::string("?");
    return std::string(name);
  }();
  return host;
}

Result<std::vector<Tag>> SqlDatabase::tags(const std::string& atText) {
  auto snapshot = snapshotForm(atText);
  if (!snapshot) return snapshot.error();
  const std::string& at = *snapshot;
  auto rows = at.empty() ? db_->query("SELECT name, description, state, created FROM emcalign_tags ORDER BY name")
                         : db_->query(
                               "SELECT name, description, state, created FROM emcalign_tags WHERE created <= $1 "
                               "ORDER BY name",
                               {at});
  if (!rows) return rows.error();
  std::vector<Tag> out;
  for (const Row& r : *rows) {
    auto t = tagOf(r, at);
    if (!t) return t.error();
    if (t->has_value()) out.push_back(std::move(**t));
  }
  return out;
}

Result<std::optional<Tag>> SqlDatabase::tag(const std::string& name, const std::string& atText) {
  if (Status s = checkTagName(name); !s) return s.error();
  auto at = snapshotForm(atText);
  if (!at) return at.error();
  auto rows = db_->query("SELECT name, description, state, created FROM emcalign_tags WHERE name = $1", {name});
  if (!rows) return rows.error();
  if (rows->empty()) return std::optional<Tag>();
  return tagOf((*rows)[0], *at);
}

Result<std::optional<std::pair<Iov, Payload>>> SqlDatabase::get(const std::string& tag, std::int64_t run,
                                                                const std::string& atText) {
  using Out = std::optional<std::pair<Iov, Payload>>;
  if (Status s = checkTagName(tag); !s) return s.error();
  auto snapshot = snapshotForm(atText);
  if (!snapshot) return snapshot.error();
  const std::string& at = *snapshot;
  return inTransaction(*db_, Access::Read, [&]() -> Result<Out> {
    if (Status s = notInvalid(tag); !s) return s.error();
    auto rows = iovRows(tag, at, "AND first_run <= $3 AND last_run >= $3", {run});
    if (!rows) return rows.error();
    if (rows->empty()) return Out();
    if (rows->size() > 1) {
      return Error{
          fmt::format("{}: tag '{}': {} IOVs hold run {}: they overlap (the database was edited behind "
                      "emcalign's back?)",
                      db_->uri(), tag, rows->size(), run)};
    }
    auto iov = iovOf((*rows)[0], db_->uri(), tag);
    if (!iov) return iov.error();
    auto p = payload(iov->payload);
    if (!p) return p.error();
    return Out(std::pair{std::move(*iov), std::move(*p)});
  });
}

Result<std::vector<Iov>> SqlDatabase::iovs(const std::string& tag, const std::string& atText) {
  auto snapshot = snapshotForm(atText);
  if (!snapshot) return snapshot.error();
  const std::string& at = *snapshot;
  if (Status s = checkTagName(tag); !s) return s.error();
  auto rows = iovRows(tag, at);
  if (!rows) return rows.error();
  std::vector<Iov> out;
  out.reserve(rows->size());
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

Result<std::vector<Row>> SqlDatabase::iovRows(const std::string& tag, const std::string& at, std::string_view where,
                                              std::vector<Param> more) {
  constexpr std::string_view kColumns = "SELECT first_run, last_run, payload, inserted";
  std::vector<Param> params{tag, at};
  params.insert(params.end(), more.begin(), more.end());
  if (at.empty()) {
    // $2 unused: the parameters keep their numbers.
    return db_->query(
        fmt::format("{} FROM emcalign_iovs WHERE tag = $1 AND $2 = '' {} ORDER BY first_run", kColumns, where), params);
  }
  // As it was at `at`: what was inserted by then, and of that what was replaced after.
  return db_->query(fmt::format("{} FROM emcalign_iovs WHERE tag = $1 AND inserted <= $2 {} UNION ALL {} FROM "
                                "emcalign_iovs_replaced WHERE tag = $1 AND inserted <= $2 AND replaced > $2 {} "
                                "ORDER BY 1",
                                kColumns, where, kColumns, where),
                    params);
}

Result<Payload> SqlDatabase::payload(const std::string& hash) {
  auto rows = db_->query("SELECT content FROM emcalign_payloads WHERE hash = $1", {hash});
  if (!rows) return rows.error();
  if (rows->empty()) return Error{fmt::format("{}: no payload {}", db_->uri(), printable(hash))};
  return verifiedPayload(hash, toText((*rows)[0][0]));
}

Result<std::map<std::string, std::shared_ptr<const Payload>>> SqlDatabase::payloadsOf(const std::string& tag) {
  if (Status s = checkTagName(tag); !s) return s.error();
  auto rows = db_->query(
      "SELECT hash, content FROM emcalign_payloads WHERE hash IN (SELECT payload FROM emcalign_iovs WHERE tag = $1 "
      "UNION SELECT payload FROM emcalign_iovs_replaced WHERE tag = $1)",
      {tag});
  if (!rows) return rows.error();
  std::map<std::string, std::shared_ptr<const Payload>> out;
  for (const Row& r : *rows) {
    auto p = verifiedPayload(toText(r[0]), toText(r[1]));
    if (!p) return p.error();
    out.emplace(toText(r[0]), std::make_shared<const Payload>(std::move(*p)));
  }
  return out;
}

Status SqlDatabase::put(const std::string& tag, const std::vector<NewIov>& iovs, IfMissing newTag,
                        const std::string& givenDescription) {
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
    auto rows = lockTagRow(tag);
    if (!rows) return Error{fmt::format("tag '{}': {}", tag, rows.error().message)};
    const bool created = rows->empty();
    if (created) {
      if (newTag == IfMissing::Refuse) {
        return Error{
            fmt::format("{}: no tag '{}' (conditions put creates it; list the tags with: emcalign "
                        "conditions list {})",
                        db_->uri(), tag, db_->uri())};
      }
      auto made = db_->query(
          "INSERT INTO emcalign_tags (name, description, state, created) VALUES ($1, $2, 'open', $3) "
          "ON CONFLICT (name) DO NOTHING",
          {tag, description, utcMicrosText(utcNowMicros())});
      if (!made) return made.error();
      rows = lockTagRow(tag);
      if (!rows) return Error{fmt::format("tag '{}': {}", tag, rows.error().message)};
      if (rows->empty()) return Error{fmt::format("{}: tag '{}' vanished while writing", db_->uri(), tag)};
    }
    auto state = stateOfRow(*rows, tag);
    if (!state) return state.error();
    if (iovWrites(*state) == IovWrites::None) {
      return Error{fmt::format("{}: tag '{}' is {}: {}", db_->uri(), tag, name(*state), whyNoIovs(*state))};
    }
    auto rec = recorder(tag);
    if (!rec) return rec.error();
    if (created) {
      // The creation's time is the tag's first change's.
      auto t = db_->query("UPDATE emcalign_tags SET created = $2 WHERE name = $1", {tag, rec->time});
      if (!t) return t.error();
      if (Status s = record(*rec, "created", {{"state", "open"}, {"description", description}}); !s) return s;
    }
    for (const NewIov& n : iovs) {
      if (iovWrites(*state) == IovWrites::Appended) {
        auto last = lastRunOf(tag);
        if (!last) return last.error();
        if (*last && n.firstRun <= **last) {
          return Error{fmt::format(
              "{}: tag '{}' is running: IOVs are only appended after its last run {}, and runs {}-{} are not",
              db_->uri(), tag, **last, n.firstRun, n.lastRun)};
        }
      }
      // Checked against the IOVs stored before and those of this same write.
      if (Status s = insertIov(tag, n, rec->time); !s) return s;
      if (Status s =
              record(*rec, "iov", {{"first_run", n.firstRun}, {"last_run", n.lastRun}, {"payload", n.payload.hash()}});
          !s) {
        return s;
      }
    }
    holdWriteForTests();
    return {};
  });
}

Result<bool> SqlDatabase::createTag(const NewTag& t) {
  const std::string description = core::withoutAnyPassword(t.description);
  if (Status s = checkTagName(t.name); !s) return s.error();
  if (Status s = checkText(description, "a tag's description"); !s) return s.error();
  return inTransaction(*db_, Access::Write, [&]() -> Result<bool> {
    auto made = db_->query(
        "INSERT INTO emcalign_tags (name, description, state, created) VALUES ($1, $2, $3, $4) "
        "ON CONFLICT (name) DO NOTHING RETURNING name",
        {t.name, description, std::string(name(t.state)), utcMicrosText(utcNowMicros())});
    if (!made) return made.error();
    if (made->empty()) return false;  // it exists
    auto rec = recorder(t.name);
    if (!rec) return rec.error();
    auto stamped = db_->query("UPDATE emcalign_tags SET created = $2 WHERE name = $1", {t.name, rec->time});
    if (!stamped) return stamped.error();
    for (const NewIov& n : t.iovs) {
      if (n.firstRun > n.lastRun) {
        return Error{fmt::format("runs {}-{}: the first run is after the last", n.firstRun, n.lastRun)};
      }
      if (Status s = insertIov(t.name, n, rec->time); !s) return s.error();
    }
    Json details = {{"state", name(t.state)}, {"description", description}, {"iovs", t.iovs.size()}};
    if (!t.iovs.empty()) details["runs"] = {t.iovs.front().firstRun, t.iovs.back().lastRun};
    const bool copy = t.copyOf.is_object();
    if (copy) details["copy_of"] = t.copyOf;
    if (Status s = record(*rec, copy ? "copy" : "created", details); !s) return s.error();
    holdWriteForTests();
    return true;
  });
}

Result<std::vector<Row>> SqlDatabase::lockTagRow(const std::string& tag) {
  return db_->query(fmt::format("SELECT state FROM emcalign_tags WHERE name = $1{}", db_->forUpdate()), {tag});
}

Result<TagState> SqlDatabase::stateOfRow(const std::vector<Row>& rows, const std::string& tag) const {
  if (rows.empty()) return Error{fmt::format("{}: no tag '{}'", db_->uri(), tag)};
  const std::string text = toText(rows[0][0]);
  const auto state = tagStateNamed(text);
  if (!state) {
    return Error{
        fmt::format("{}: tag '{}' has the state '{}', which this emcalign does not know (the database was "
                    "edited behind emcalign's back?): not written",
                    db_->uri(), tag, printable(text))};
  }
  return *state;
}

Result<std::optional<Tag>> SqlDatabase::tagOf(const Row& r, const std::string& at) {
  const std::string tagName = toText(r[0]);
  Tag t{printable(tagName), printable(toText(r[1])), TagState::Open, printable(toText(r[3])), {}, {}};
  const std::string state = toText(r[2]);
  const auto now = tagStateNamed(state);
  if (!now) {
    return Error{fmt::format(
        "{}: tag '{}' has the state '{}', which this emcalign does not know (the database was edited behind "
        "emcalign's back?)",
        db_->uri(), t.name, printable(state))};
  }
  if (!at.empty() && toText(r[3]) > at) return std::optional<Tag>();  // created later
  // Its state at `at` (now: the row's) and since when, from its history.
  auto changes = at.empty() ? db_->query(
                                  "SELECT change, time, details FROM emcalign_history WHERE tag = $1 AND change = "
                                  "'state' ORDER BY seq DESC LIMIT 1",
                                  {tagName})
                            : db_->query(
                                  "SELECT change, time, details FROM emcalign_history WHERE tag = $1 AND time <= $2 "
                                  "AND change IN ('created', 'copy', 'state') ORDER BY seq",
                                  {tagName, at});
  if (!changes) return changes.error();
  t.state = *now;
  std::optional<TagState> then;
  for (const Row& c : *changes) {
    const Json d = Json::parse(toText(c[2]), nullptr, false);
    if (!d.is_object()) continue;
    const bool transition = toText(c[0]) == "state";
    const auto s = tagStateNamed(d.value(transition ? "to" : "state", std::string()));
    if (!s) continue;
    then = s;
    t.stateChanged = transition ? printable(toText(c[1])) : std::string();
    t.reason = transition ? printable(d.value("reason", std::string())) : std::string();
  }
  if (!at.empty()) t.state = then.value_or(TagState::Open);
  return std::optional<Tag>(std::move(t));
}

Result<std::optional<std::int64_t>> SqlDatabase::lastRunOf(const std::string& tag) {
  auto rows = db_->query("SELECT MAX(last_run) FROM emcalign_iovs WHERE tag = $1", {tag});
  if (!rows) return rows.error();
  if (rows->empty() || !(*rows)[0][0]) return std::optional<std::int64_t>();
  auto run = runOf((*rows)[0][0], db_->uri(), tag);
  if (!run) return run.error();
  return std::optional<std::int64_t>(*run);
}

Status SqlDatabase::insertIov(const std::string& tag, const NewIov& n, const std::string& time) {
  auto stored =
      db_->query("INSERT INTO emcalign_payloads (hash, content) VALUES ($1, $2) ON CONFLICT (hash) DO NOTHING",
                 {n.payload.hash(), n.payload.content.dump()});
  if (!stored) return stored.error();
  return insertIovRow(tag, n.firstRun, n.lastRun, n.payload.hash(), time);
}

Status SqlDatabase::insertIovRow(const std::string& tag, std::int64_t first, std::int64_t last, const std::string& hash,
                                 const std::string& time) {
  // What the readers take back (runOf): a run number is 0 or more.
  if (first < 0) {
    return Error{fmt::format("{}: tag '{}': runs {}-{}: a run number is 0 or more (the events' run numbers are wrong)",
                             db_->uri(), tag, first, last)};
  }
  auto overlap = db_->query(
      "SELECT first_run, last_run FROM emcalign_iovs WHERE tag = $1 AND first_run <= $2 AND last_run >= $3 "
      "ORDER BY first_run LIMIT 1",
      {tag, last, first});
  if (!overlap) return overlap.error();
  if (!overlap->empty()) {
    return Error{fmt::format("{}: tag '{}': runs {}-{} overlap its IOV {}-{} (the IOVs of a tag never overlap)",
                             db_->uri(), tag, first, last, toText((*overlap)[0][0]), toText((*overlap)[0][1]))};
  }
  auto iov =
      db_->query("INSERT INTO emcalign_iovs (tag, first_run, last_run, payload, inserted) VALUES ($1, $2, $3, $4, $5)",
                 {tag, first, last, hash, time});
  if (!iov) return iov.error();
  return {};
}

Status SqlDatabase::notInvalid(const std::string& tag) {
  auto rows = db_->query("SELECT name, description, state, created FROM emcalign_tags WHERE name = $1", {tag});
  if (!rows) return rows.error();
  if (rows->empty() || toText((*rows)[0][2]) != name(TagState::Invalid)) return {};
  auto t = tagOf((*rows)[0], {});
  if (!t) return t.error();
  const Tag& x = **t;
  return Error{
      fmt::format("{}: tag '{}' is invalid (since {}{}): it is kept and listed, but never served or written to",
                  db_->uri(), tag, x.stateChanged.empty() ? std::string("its creation") : x.stateChanged,
                  x.reason.empty() ? std::string() : ": " + x.reason)};
}

Result<Payload> SqlDatabase::verifiedPayload(const std::string& hash, const std::string& text) const {
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
