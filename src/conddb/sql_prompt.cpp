// The conditions database for every SQL engine: a prompt loop's running tag, its decisions and
// their thresholds, and the one loop that writes it (sql_database.hpp, validation/prompt.hpp).

#include <fmt/format.h>

#include "emcalign/core/secrets.hpp"
#include "emcalign/core/utf8.hpp"
#include "sql_database.hpp"

namespace emcalign::conddb::detail {

using io::Json;

namespace {

// "prompt:TAG:000000000042": in the order of the groups as text.
std::string promptKey(const std::string& tag, std::int64_t group) {
  return fmt::format("{}{}:{:012}", kPromptPrefix, tag, group);
}

}  // namespace

Status SqlDatabase::makeRunning(const std::string& tag, const std::string& givenDescription) {
  const std::string description = core::withoutAnyPassword(givenDescription);
  if (Status s = checkTagName(tag); !s) return s;
  if (Status s = checkText(description, "a tag's description"); !s) return s;
  auto made = createTag({.name = tag, .description = description, .state = TagState::Running});
  if (!made) return made.error();
  if (*made) return {};
  auto t = this->tag(tag, {});
  if (!t) return t.error();
  if (!t->has_value()) return Error{fmt::format("{}: tag '{}' vanished while making it", db_->uri(), tag)};
  if ((*t)->state != TagState::Running) {
    return Error{
        fmt::format("{}: tag '{}' is {}, not running: a prompt loop writes only a running tag (its own, "
                    "made by it); give it a new tag",
                    db_->uri(), tag, name((*t)->state))};
  }
  return {};
}

Status SqlDatabase::appendPrompt(const std::string& tag, const PromptRecord& r) {
  if (Status s = checkTagName(tag); !s) return s;
  if (Status s = checkText(r.decision, "a decision"); !s) return s;
  return inTransaction(*db_, Access::Write, [&]() -> Status {
    auto rows = lockTagRow(tag);
    if (!rows) return rows.error();
    auto state = rows->empty() ? Result<TagState>(Error{"missing"}) : stateOfRow(*rows, tag);
    if (!state || *state != TagState::Running) {
      return Error{fmt::format("{}: tag '{}' is {}: a decision is stored only into a running tag", db_->uri(), tag,
                               state ? std::string(name(*state)) : std::string("missing"))};
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
    auto rec = recorder(tag);
    if (!rec) return rec.error();
    Json details = {{"group", r.group}};
    const Json decision = Json::parse(r.decision, nullptr, false);
    if (decision.is_object() && decision.contains("decision")) details["decision"] = decision["decision"];
    if (r.iov) {
      auto last = lastRunOf(tag);
      if (!last) return last.error();
      if (r.iov->firstRun > r.iov->lastRun || (*last && r.iov->firstRun != **last + 1)) {
        return Error{
            fmt::format("{}: tag '{}': runs {}-{} do not start right after its last IOV (run {}): a "
                        "running tag's IOVs tile the runs",
                        db_->uri(), tag, r.iov->firstRun, r.iov->lastRun, last->value_or(-1))};
      }
      if (Status s = insertIov(tag, *r.iov, rec->time); !s) return s;
      details["first_run"] = r.iov->firstRun;
      details["last_run"] = r.iov->lastRun;
      details["payload"] = r.iov->payload.hash();
    }
    auto thresholds = db_->query("INSERT INTO emcalign_meta (key, value) VALUES ($1, $2) ON CONFLICT (key) DO NOTHING",
                                 {std::string(kThresholdsPrefix) + r.thresholdsSha256, r.thresholds});
    if (!thresholds) return thresholds.error();
    auto stored = db_->query("INSERT INTO emcalign_meta (key, value) VALUES ($1, $2)", {key, r.decision});
    if (!stored) return stored.error();
    if (Status s = record(*rec, "prompt", details); !s) return s;
    holdWriteForTests();
    return {};
  });
}

Result<std::vector<std::string>> SqlDatabase::promptRecords(const std::string& tag) {
  if (Status s = checkTagName(tag); !s) return s.error();
  return inTransaction(*db_, Access::Read, [&] { return promptRecordsOf(tag); });
}

Result<std::vector<std::string>> SqlDatabase::promptRecordsOf(const std::string& tag) {
  const std::string prefix = fmt::format("{}{}:", kPromptPrefix, tag);
  auto rows = db_->query("SELECT value FROM emcalign_meta WHERE substr(key, 1, $1) = $2 ORDER BY key",
                         {static_cast<std::int64_t>(prefix.size()), prefix});
  if (!rows) return rows.error();
  std::vector<std::string> out;
  for (const Row& r : *rows) out.push_back(toText(r[0]));
  return out;
}

Result<std::string> SqlDatabase::claimPrompt(const std::string& tag, const std::string& me,
                                             const std::function<bool(const std::string&)>& alive) {
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

Result<std::optional<std::string>> SqlDatabase::thresholds(const std::string& sha256) {
  auto rows = db_->query("SELECT value FROM emcalign_meta WHERE key = $1", {std::string(kThresholdsPrefix) + sha256});
  if (!rows) return rows.error();
  if (rows->empty()) return std::optional<std::string>();
  return std::optional<std::string>(toText((*rows)[0][0]));
}

}  // namespace emcalign::conddb::detail
