#pragma once
// Internal to the conddb module: the one implementation of the database's semantics on top of
// an SQL engine (sql_backend.hpp), in files of one concern each:
//   sql_database.cpp  reading, and writing IOVs (put, createTag)
//   sql_states.cpp    states, history, promotion
//   sql_prompt.cpp    a prompt loop's tag and decisions
//   sql_schema.cpp    the schema, its check on open, the upgrade from schema 1

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "sql_backend.hpp"

namespace emcalign::conddb::detail {

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

/// Fault injection for the tests of a writer killed mid-write (tests/unit/conddb): with
/// EMCALIGN_FAULT_HOLD_WRITE=PATH, a write creates PATH once everything is written but not
/// yet committed, and waits there (up to a minute) to be killed.
void holdWriteForTests();

std::string toText(const std::optional<std::string>& s);

/// A run number as stored: an integer, 0 or more; anything else (a database edited by hand)
/// is an error naming the tag.
Result<std::int64_t> runOf(const std::optional<std::string>& s, const std::string& uri, const std::string& tag);
/// The IOV of a row (first_run, last_run, payload, inserted), its runs checked.
Result<Iov> iovOf(const Row& r, const std::string& uri, const std::string& tag);
/// Text to be stored: no NUL, UTF-8.
Status checkText(const std::string& text, std::string_view what);

/// The OS user and host of this process, as the history records them.
const std::string& osUser();
const std::string& hostName();

class SqlDatabase final : public Database {
 public:
  explicit SqlDatabase(std::unique_ptr<SqlBackend> db) : db_(std::move(db)) {}
  using Database::put;

  // sql_schema.cpp
  Status init() override;
  /// On open: the schema must be this one; one of schema 1 is upgraded (said once).
  Status checkSchema();

  // sql_database.cpp
  Result<std::vector<Tag>> tags(const std::string& at) override;
  Result<std::optional<Tag>> tag(const std::string& name, const std::string& at) override;
  Result<std::optional<std::pair<Iov, Payload>>> get(const std::string& tag, std::int64_t run,
                                                     const std::string& at) override;
  Result<std::vector<Iov>> iovs(const std::string& tag, const std::string& at) override;
  Result<Payload> payload(const std::string& hash) override;
  Result<std::map<std::string, std::shared_ptr<const Payload>>> payloadsOf(const std::string& tag) override;
  Status put(const std::string& tag, const std::vector<NewIov>& iovs, IfMissing newTag,
             const std::string& givenDescription) override;
  Result<bool> createTag(const NewTag& tag) override;

  // sql_states.cpp
  Result<std::vector<Change>> history(const std::string& tag) override;
  Result<std::string> lastChange(const std::string& tag) override;
  Result<StateChange> setState(const std::string& tag, TagState to, const std::string& reason) override;
  Result<Promotion> promote(const std::string& from, const std::string& to, std::int64_t firstSafeRun,
                            bool dryRun) override;

  // sql_prompt.cpp
  Status makeRunning(const std::string& tag, const std::string& givenDescription) override;
  Status appendPrompt(const std::string& tag, const PromptRecord& r) override;
  Result<std::vector<std::string>> promptRecords(const std::string& tag) override;
  Result<std::string> claimPrompt(const std::string& tag, const std::string& me,
                                  const std::function<bool(const std::string&)>& alive) override;
  Result<std::optional<std::string>> thresholds(const std::string& sha256) override;

  [[nodiscard]] const std::string& uri() const override { return db_->uri(); }

 private:
  // The changes of one write to a tag: their time (after the tag's latest, so increasing within
  // the tag) and the next number in its history.
  struct Recorder {
    std::string tag, time;
    std::int64_t seq = 0;
  };
  // After the tag's row is locked (or, for a new tag, its name taken).
  Result<Recorder> recorder(const std::string& tag);
  Status record(Recorder& r, std::string_view change, const io::Json& details);

  // The state of a tag's row, locked for the rest of the write (no rows: no such tag).
  Result<std::vector<Row>> lockTagRow(const std::string& tag);
  // The current state of a locked row; an error for a state this emcalign does not know.
  Result<TagState> stateOfRow(const std::vector<Row>& rows, const std::string& tag) const;
  // A tag's row as read (name, description, state, created), with its state at `at`.
  Result<std::optional<Tag>> tagOf(const Row& r, const std::string& at);
  // The IOVs of a tag at `at` ("" : now) with `where` added (params from $3 on).
  Result<std::vector<Row>> iovRows(const std::string& tag, const std::string& at, std::string_view where = {},
                                   std::vector<Param> more = {});
  // The last run of the tag's IOVs; none without IOVs.
  Result<std::optional<std::int64_t>> lastRunOf(const std::string& tag);
  // One IOV with its payload (stored once under its hash); the overlap checked.
  Status insertIov(const std::string& tag, const NewIov& n, const std::string& time);
  Status insertIovRow(const std::string& tag, std::int64_t first, std::int64_t last, const std::string& hash,
                      const std::string& time);
  // Lookups refuse an invalid tag, naming when and why it became invalid.
  Status notInvalid(const std::string& tag);
  Result<Payload> verifiedPayload(const std::string& hash, const std::string& text) const;
  Result<std::vector<std::string>> promptRecordsOf(const std::string& tag);
  // A promotion checked, both tags' rows locked (sql_states.cpp): `from` validated, `to` running,
  // `from`'s IOVs tiling the runs from firstSafeRun on, after the first run of `to`'s last IOV.
  Result<Promotion> checkedPromotion(const std::string& from, const std::string& to, std::int64_t firstSafeRun);
  // A checked promotion written: `to`'s last IOV cut or extended (as it was kept), `from`'s IOVs
  // appended, the change in `to`'s history; its time into `p`.
  Status writePromotion(Promotion& p);
  Status upgradeFrom1();

  std::unique_ptr<SqlBackend> db_;
};

/// The prefixes of emcalign_meta's keys.
inline constexpr const char* kPromptPrefix = "prompt:";
inline constexpr const char* kThresholdsPrefix = "thresholds:";
inline constexpr const char* kOwnerPrefix = "prompt-owner:";

}  // namespace emcalign::conddb::detail
