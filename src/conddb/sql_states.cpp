// The conditions database for every SQL engine: tag states, history and promotion
// (sql_database.hpp).

#include <algorithm>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/secrets.hpp"
#include "emcalign/core/utf8.hpp"
#include "sql_database.hpp"

namespace emcalign::conddb::detail {

using io::Json;

Result<SqlDatabase::Recorder> SqlDatabase::recorder(const std::string& tag) {
  auto last = db_->query("SELECT seq, time FROM emcalign_history WHERE tag = $1 ORDER BY seq DESC LIMIT 1", {tag});
  if (!last) return last.error();
  UtcMicros time = utcNowMicros();
  std::int64_t seq = 0;
  if (!last->empty()) {
    auto previous = runOf((*last)[0][0], db_->uri(), tag);
    if (!previous) return previous.error();
    seq = *previous + 1;
    // After the tag's latest change, even when the clock went back (or another host's is ahead).
    if (auto before = utcMicrosOf(toText((*last)[0][1])); before && *before >= time) time = *before + 1;
  }
  return Recorder{tag, utcMicrosText(time), seq};
}

Status SqlDatabase::record(Recorder& r, std::string_view change, const Json& details) {
  auto row = db_->query(
      "INSERT INTO emcalign_history (tag, seq, time, change, os_user, host, details) VALUES ($1, $2, $3, $4, $5, "
      "$6, $7)",
      {r.tag, r.seq, r.time, std::string(change), osUser(), hostName(), details.dump()});
  if (!row) return row.error();
  ++r.seq;
  return {};
}

Result<std::vector<Change>> SqlDatabase::history(const std::string& tag) {
  if (Status s = checkTagName(tag); !s) return s.error();
  return inTransaction(*db_, Access::Read, [&]() -> Result<std::vector<Change>> {
    auto exists = db_->query("SELECT name FROM emcalign_tags WHERE name = $1", {tag});
    if (!exists) return exists.error();
    if (exists->empty()) {
      return Error{fmt::format("{}: no tag '{}' (the tags: emcalign conditions list {})", db_->uri(), tag, db_->uri())};
    }
    auto rows = db_->query(
        "SELECT time, change, os_user, host, details FROM emcalign_history WHERE tag = $1 ORDER BY seq", {tag});
    if (!rows) return rows.error();
    std::vector<Change> out;
    out.reserve(rows->size());
    for (const Row& r : *rows) {
      Json details = Json::parse(toText(r[4]), nullptr, false);
      if (!details.is_object()) details = {{"unreadable", printable(toText(r[4])).substr(0, 200)}};
      out.push_back({printable(toText(r[0])), printable(toText(r[1])), printable(toText(r[2])), printable(toText(r[3])),
                     std::move(details)});
    }
    return out;
  });
}

Result<std::string> SqlDatabase::lastChange(const std::string& tag) {
  if (Status s = checkTagName(tag); !s) return s.error();
  auto rows = db_->query("SELECT time FROM emcalign_history WHERE tag = $1 ORDER BY seq DESC LIMIT 1", {tag});
  if (!rows) return rows.error();
  if (rows->empty()) return Error{fmt::format("{}: tag '{}' has no history", db_->uri(), tag)};
  return toText((*rows)[0][0]);
}

Result<Database::StateChange> SqlDatabase::setState(const std::string& tag, TagState to,
                                                    const std::string& givenReason) {
  const std::string reason = core::withoutAnyPassword(givenReason);
  if (Status s = checkTagName(tag); !s) return s.error();
  if (Status s = checkText(reason, "the reason"); !s) return s.error();
  return inTransaction(*db_, Access::Write, [&]() -> Result<StateChange> {
    auto rows = lockTagRow(tag);
    if (!rows) return rows.error();
    auto from = stateOfRow(*rows, tag);
    if (!from) return from.error();
    if (*from == to) {
      if (to != TagState::Invalid) return StateChange::Already;
      // Invalid already: the same again (a retry) changes nothing; another reason is refused,
      // naming the one kept.
      auto t = this->tag(tag, {});
      if (!t) return t.error();
      if ((*t)->reason == printable(reason)) return StateChange::Already;
      return Error{
          fmt::format("{}: tag '{}' was made invalid already ({}{}): it keeps its first reason; nothing changed",
                      db_->uri(), tag, (*t)->stateChanged, (*t)->reason.empty() ? "" : ": " + (*t)->reason)};
    }
    if (!transitionAllowed(*from, to)) {
      std::vector<std::string> allowed;
      for (TagState s : transitionsFrom(*from)) allowed.emplace_back(name(s));
      const std::string why =
          *from == TagState::Published
              ? "published is final: a published calibration is never withdrawn, nor changed (store the corrected "
                "one under a new tag, and point the users at it)"
          : *from == TagState::Invalid
              ? "invalid is final"
              : fmt::format("from {} a tag goes to {} only", name(*from), fmt::join(allowed, ", "));
      return Error{fmt::format("{}: tag '{}' is {}, and cannot become {}: {}; nothing changed", db_->uri(), tag,
                               name(*from), name(to), why)};
    }
    auto rec = recorder(tag);
    if (!rec) return rec.error();
    auto changed = db_->query("UPDATE emcalign_tags SET state = $2 WHERE name = $1", {tag, std::string(name(to))});
    if (!changed) return changed.error();
    Json details = {{"from", name(*from)}, {"to", name(to)}};
    if (!reason.empty()) details["reason"] = reason;
    if (Status s = record(*rec, "state", details); !s) return s.error();
    holdWriteForTests();
    return StateChange::Changed;
  });
}

namespace {

// Why S's IOVs cannot be appended from N on: a gap, an overlap, another first run; "" when
// they tile the runs from N.
std::string tilingProblem(const std::vector<Iov>& iovs, std::int64_t n) {
  if (iovs.front().firstRun != n) {
    return fmt::format("its first IOV starts at run {}, not at the first safe run {}", iovs.front().firstRun, n);
  }
  for (std::size_t k = 1; k < iovs.size(); ++k) {
    const Iov& a = iovs[k - 1];
    const Iov& b = iovs[k];
    if (b.firstRun != a.lastRun + 1) {
      return fmt::format("its IOVs {}-{} and {}-{} leave a gap (runs {}-{})", a.firstRun, a.lastRun, b.firstRun,
                         b.lastRun, a.lastRun + 1, b.firstRun - 1);
    }
  }
  return {};
}

}  // namespace

namespace {

Error promotionRefused(const std::string& uri, const std::string& from, const std::string& to,
                       std::int64_t firstSafeRun, const std::string& why) {
  return Error{fmt::format("{}: promotion of '{}' into '{}' from run {} refused: {}; nothing written", uri, from, to,
                           firstSafeRun, why)};
}

}  // namespace

Result<Database::Promotion> SqlDatabase::checkedPromotion(const std::string& from, const std::string& to,
                                                          std::int64_t firstSafeRun) {
  const auto refused = [&](const std::string& why) {
    return promotionRefused(db_->uri(), from, to, firstSafeRun, why);
  };
  // Both rows locked, in name order (two promotions never wait for each other in a circle); a
  // prompt loop appending to `to` waits for this one, or this one for it.
  std::optional<TagState> stateFrom, stateTo;
  for (const std::string& t : from < to ? std::vector{from, to} : std::vector{to, from}) {
    auto rows = lockTagRow(t);
    if (!rows) return rows.error();
    if (rows->empty()) return refused(fmt::format("there is no tag '{}'", t));
    auto s = stateOfRow(*rows, t);
    if (!s) return s.error();
    (t == from ? stateFrom : stateTo) = *s;
  }
  if (*stateFrom != TagState::Validated) {
    return refused(fmt::format("'{}' is {}: only a validated tag is promoted", from, name(*stateFrom)));
  }
  if (*stateTo != TagState::Running) {
    return refused(fmt::format("'{}' is {}: a promotion goes into a running tag", to, name(*stateTo)));
  }
  auto iovsFrom = iovs(from, {});
  if (!iovsFrom) return iovsFrom.error();
  auto iovsTo = iovs(to, {});
  if (!iovsTo) return iovsTo.error();
  if (iovsFrom->empty()) return refused(fmt::format("'{}' has no IOV", from));
  if (iovsTo->empty()) return refused(fmt::format("'{}' has no IOV", to));
  if (std::string why = tilingProblem(*iovsFrom, firstSafeRun); !why.empty()) {
    return refused(fmt::format("'{}': {}", from, why));
  }
  const Iov& last = iovsTo->back();
  if (firstSafeRun <= last.firstRun) {
    return refused(
        fmt::format("the last IOV of '{}' ({}-{}) starts at or after it: runs before the first safe "
                    "run are never changed",
                    to, last.firstRun, last.lastRun));
  }
  return Promotion{from, to, firstSafeRun, last, *iovsFrom, {}};
}

Status SqlDatabase::writePromotion(Promotion& p) {
  const Iov& last = p.lastBefore;
  auto rec = recorder(p.to);
  if (!rec) return rec.error();
  p.time = rec->time;
  if (last.lastRun != p.firstSafeRun - 1) {
    // The IOV as it was, kept for the snapshots before now.
    auto kept = db_->query(
        "INSERT INTO emcalign_iovs_replaced (tag, first_run, last_run, payload, inserted, replaced) SELECT tag, "
        "first_run, last_run, payload, inserted, $3 FROM emcalign_iovs WHERE tag = $1 AND first_run = $2",
        {p.to, last.firstRun, rec->time});
    if (!kept) return kept.error();
    auto cut = db_->query("UPDATE emcalign_iovs SET last_run = $3, inserted = $4 WHERE tag = $1 AND first_run = $2",
                          {p.to, last.firstRun, p.firstSafeRun - 1, rec->time});
    if (!cut) return cut.error();
  }
  for (const Iov& i : p.appended) {
    if (Status s = insertIovRow(p.to, i.firstRun, i.lastRun, i.payload, rec->time); !s) return s.error();
  }
  const Json details = {
      {"from", p.from},
      {"first_safe_run", p.firstSafeRun},
      {"last_iov", {{"was", {last.firstRun, last.lastRun}}, {"now", {last.firstRun, p.firstSafeRun - 1}}}},
      {"last_iov_fate", p.lastIovFate()},
      {"appended", p.appended.size()},
      {"runs", {p.appended.front().firstRun, p.appended.back().lastRun}}};
  if (Status s = record(*rec, "promotion", details); !s) return s.error();
  holdWriteForTests();
  return {};
}

Result<Database::Promotion> SqlDatabase::promote(const std::string& from, const std::string& to,
                                                 std::int64_t firstSafeRun, bool dryRun) {
  if (Status s = checkTagName(from); !s) return s.error();
  if (Status s = checkTagName(to); !s) return s.error();
  if (from == to) return promotionRefused(db_->uri(), from, to, firstSafeRun, "a tag is not promoted into itself");
  // A dry run reads as a write would (the same rows locked), then rolls back.
  if (Status s = db_->beginWrite(); !s) return s.error();
  auto result = checkedPromotion(from, to, firstSafeRun);
  if (result && !dryRun) {
    if (Status s = writePromotion(*result); !s) result = s.error();
  }
  if (!result || dryRun) {
    db_->rollback();
    return result;
  }
  if (Status s = db_->commit(); !s) {
    db_->rollback();
    return s.error();
  }
  return result;
}

}  // namespace emcalign::conddb::detail
