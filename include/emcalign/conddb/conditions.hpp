#pragma once
// The conditions database: calibrations stored by run range (docs/campaign.md).
//
// The model is a small, strict one, learnt from the systems physicists use — CMS CondDB
// (tags, content-addressed payloads), Belle II (inclusive run-range IOVs, immutable
// published tags, a local SQLite file marked with application_id/user_version) and ATLAS
// COOL (a single-version folder refuses overlapping intervals):
//   - a tag has a name, a description and a state (tag_states.hpp: open, testing, validated,
//     published, running, invalid), changed only along the allowed transitions;
//   - an IOV (interval of validity) is an inclusive run range [first_run, last_run] of a
//     tag, holding one payload; the IOVs of a tag never overlap;
//   - a payload is one calibration — the 12 parameters with their errors, covariance,
//     derived parameters, χ²/ndf, status, the number of selected events and the provenance
//     (inputs and their digests, software, corrections, time) — as canonical JSON, stored
//     once under its SHA-256.
//
// Back ends, one schema and one semantics: an SQLite file (`sqlite:PATH`, or a plain path;
// WAL, a busy timeout) and a PostgreSQL server through libpqxx
// (`postgresql://user@host:port/db`; a tag's row is locked for the time of a write). Every
// write is one transaction: concurrent writers lose nothing, and a writer killed in the
// middle leaves the database as it was. The schema version is checked on open, and a
// database of the version before is upgraded then, in one transaction.
//
// Every change to a tag is kept in its history with its time (UTC, to the microsecond, and
// increasing within the tag), the OS user and host; an IOV cut by a promotion is kept as it
// was. So the database answers as it was at any past time (a snapshot, CMS conddb's
// --snapshot), and a job records the time it read to be rerun on the same conditions.

#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "emcalign/calib/model_identity.hpp"
#include "emcalign/calib/sigma_sys.hpp"
#include "emcalign/conddb/tag_states.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::conddb {

/// The schema this emcalign reads and writes; a database of version 1 is upgraded on open.
inline constexpr int kSchemaVersion = 2;
inline constexpr std::string_view kPayloadFormat = "emcalign-payload/1";

struct Tag {
  std::string name;
  std::string description;
  TagState state = TagState::Open;
  std::string created;       ///< UTC, ISO 8601 to the microsecond
  std::string stateChanged;  ///< when it came into its state ("" when created in it)
  std::string reason;        ///< the reason given for that change ("" for none)
};

/// One change of a tag, as its history keeps it: when (UTC, ISO 8601 to the microsecond), what
/// ("created", "copy", "iov", "state", "promotion", "prompt"), by whom (the OS user and host;
/// empty for the changes of a database upgraded from schema 1, where they were not kept) and
/// the details (runs, payload, states, reason, …).
struct Change {
  std::string time;
  std::string change;
  std::string user, host;
  io::Json details;
  /// {"time", "change", "user", "host", ...details}.
  [[nodiscard]] io::Json json() const;
  /// What changed, in a few words ("runs 1-40, payload 3f2a…", "open -> testing: why", …).
  [[nodiscard]] std::string summary() const;
};

/// A time for `--snapshot` in the database's form (utcMicrosText), from what a person or a
/// record gives (core/clock.hpp's parseUtcTime); the error names `option`.
Result<std::string> parseSnapshot(std::string_view text, std::string_view option = "--snapshot");
/// A snapshot as the database compares and records it: parseSnapshot's form, "" (now) for "".
Result<std::string> snapshotForm(const std::string& at);
class Database;
/// The error for a tag `db` does not hold at snapshot `at` ("" : now): "did not exist at AT
/// (created …)" when it exists now, else "no tag".
Error missingTag(Database& db, const std::string& tag, const std::string& at);

struct Iov {
  std::int64_t firstRun = 0;  ///< inclusive
  std::int64_t lastRun = 0;   ///< inclusive
  std::string payload;        ///< its SHA-256
  std::string inserted;       ///< UTC, ISO 8601 to the microsecond
};

/// One value of a payload as stored, in file units (deg, cm); NaN where the payload has none,
/// or something else than a number (a database can hold anything).
struct StoredValue {
  double value = std::numeric_limits<double>::quiet_NaN();
  double error = std::numeric_limits<double>::quiet_NaN();
  /// The part of `error` the events make, without σ_sys (calib::FitResult::statisticalErrors);
  /// NaN in payloads of fits made before it was recorded.
  double statisticalError = std::numeric_limits<double>::quiet_NaN();
};

/// The values of a payload: the 12 fit parameters with their errors, then the five derived
/// ones (β, ψ, μ, τ, dx_rel) — one per entry of kAllQuantities, in its order.
using StoredValues = std::array<StoredValue, kAllQuantities.size()>;

/// A calibration as stored: canonical JSON (`emcalign-payload/1`), addressed by its hash.
/// Its content is written by makePayload; the members below read it (each lenient: what the
/// payload does not say, or not as makePayload writes it, reads as absent).
struct Payload {
  io::Json content;
  /// SHA-256 of the compact dump of `content`.
  [[nodiscard]] std::string hash() const;
  /// The parameter file of this calibration (docs/contract.md §3: parameters, errors, covariance, …).
  [[nodiscard]] io::Json parameterFile() const;
  /// The model of the fit behind it (calib/model_identity.hpp): the corrections a campaign
  /// named, or those under model_corrections, or the paper's model with its depth offset;
  /// unsaid for a parameter file stored without its fit.
  [[nodiscard]] calib::ModelIdentity modelIdentity() const;
  /// Its parameters, errors (quoted and statistical) and derived values.
  [[nodiscard]] StoredValues values() const;
  /// The selected events of its fit; none when the payload does not say.
  [[nodiscard]] std::optional<std::int64_t> selectedEvents() const;
  /// The SHA-256 of each file its fit read, as (file name, SHA-256) in the order stored; empty
  /// when it records none.
  [[nodiscard]] std::vector<std::pair<std::string, std::string>> inputDigests() const;
  /// The corrections a campaign fitted it with, as the campaign named them; "" when the
  /// payload names none (a fit result stored with `conditions put` records its model under
  /// model_corrections instead: see modelIdentity() and depthOffsetCm()).
  [[nodiscard]] std::string correctionsFile() const;
  /// The SHA-256 of the corrections a campaign fitted it with; "" when the payload names none.
  [[nodiscard]] std::string correctionsSha256() const;
  /// The depth offset in cm of its fit's model when the payload records that model's
  /// corrections (0 without an offset); none when it does not record them.
  [[nodiscard]] std::optional<double> depthOffsetCm() const;
  /// The choice of σ_sys its fit was made with (the paper's, for payloads made before the
  /// choice was recorded); an error naming what it records when that is no choice a fit makes.
  [[nodiscard]] Result<calib::SigmaSysChoice> sigmaSysChoice() const;
};

/// A payload from a fit result (docs/contract.md §3) or a parameter file, with its provenance (free JSON
/// added under "provenance"). A fit result must be usable (core/fit_status.hpp).
Result<Payload> makePayload(const io::Json& resultOrParameters, double r1, std::string_view source,
                            io::Json provenance = io::Json::object());

/// Tag names: letters, digits, '_', '-', '.', 1 to 100 characters.
Status checkTagName(std::string_view tag);

/// The file of an SQLite database URI ("sqlite:PATH", "sqlite://PATH" or a plain path);
/// empty for a server (postgresql://…) or a URI without a file. A command checks that no
/// output of its overwrites it.
std::string sqliteFileOf(const std::string& uri);

/// What opening a database does when there is none, and what storing does when the tag is new.
enum class IfMissing {
  Refuse,  ///< an error naming what is missing (and how to create it)
  Create,  ///< a new SQLite file with its schema (a PostgreSQL database must exist); a new, open tag
};

class Database {
 public:
  /// Opens a database: `sqlite:PATH`, a plain path, or `postgresql://…` / `postgres://…`. An
  /// existing database must have this schema version, or the one before (upgraded now, in one
  /// transaction, and said once through the notice handler); `IfMissing::Create` makes a new
  /// SQLite file (a PostgreSQL database must exist) and `init()`s its schema.
  /// `busyMs`: how long an SQLite write waits for another writer's lock (0: two minutes); a loop
  /// that must stay responsive (prompt) waits less and tries again later.
  static Result<std::unique_ptr<Database>> open(const std::string& uri, IfMissing missing = IfMissing::Refuse,
                                                int busyMs = 0);
  /// Where a notice goes (the upgrade of a database); the default writes
  /// "emcalign: note: TEXT" to standard error.
  static void setNoticeHandler(std::function<void(const std::string&)> handler);
  virtual ~Database() = default;

  /// Creates the schema (idempotent: an existing one of this version is left as it is).
  virtual Status init() = 0;

  // Reading. `at`: a snapshot time (parseSnapshot's form) — the database as it was then: the
  // tags created by then in the state they had, the IOVs they had (one cut later as it was);
  // empty: as it is now.

  virtual Result<std::vector<Tag>> tags(const std::string& at = {}) = 0;
  virtual Result<std::optional<Tag>> tag(const std::string& name, const std::string& at = {}) = 0;
  /// The IOV of `tag` that contains `run`, with its payload; none if no IOV does. Refused for a
  /// tag that is invalid now, whatever `at`.
  virtual Result<std::optional<std::pair<Iov, Payload>>> get(const std::string& tag, std::int64_t run,
                                                             const std::string& at = {}) = 0;
  /// The IOVs of a tag by first run.
  virtual Result<std::vector<Iov>> iovs(const std::string& tag, const std::string& at = {}) = 0;
  virtual Result<Payload> payload(const std::string& hash) = 0;
  /// Every payload the tag's IOVs hold or held, by hash, read at once (a listing of 10 000 IOVs
  /// is one query, not 10 000); each hash checked.
  virtual Result<std::map<std::string, std::shared_ptr<const Payload>>> payloadsOf(const std::string& tag) = 0;
  /// The changes of a tag, oldest first.
  virtual Result<std::vector<Change>> history(const std::string& tag) = 0;
  /// The time of the tag's latest change: a snapshot at it sees the tag as it is now.
  virtual Result<std::string> lastChange(const std::string& tag) = 0;

  // Writing: each one transaction, refused as a whole (nothing written, no history entry).

  /// Stores `payload` for runs [first, last] of `tag` (a tag that does not exist is created,
  /// open, with `description`, or refused, as `newTag` says), in one transaction; refused for a
  /// tag whose state takes no IOVs (tag_states.hpp), an overlap with an IOV of the tag, an IOV
  /// of a running tag not after its last one, or first > last.
  Status put(const std::string& tag, std::int64_t first, std::int64_t last, const Payload& payload, IfMissing newTag,
             const std::string& description = {}) {
    return put(tag, {NewIov{first, last, payload}}, newTag, description);
  }
  /// Several IOVs in one transaction: all are stored or none.
  struct NewIov {
    std::int64_t firstRun;
    std::int64_t lastRun;
    Payload payload;
  };
  virtual Status put(const std::string& tag, const std::vector<NewIov>& iovs, IfMissing newTag,
                     const std::string& description = {}) = 0;

  /// A new tag made whole in one transaction: its IOVs, then its state; its history says
  /// "created" (or "copy", with `copyOf` in the details, when `copyOf` is an object).
  struct NewTag {
    std::string name, description;
    TagState state = TagState::Open;
    std::vector<NewIov> iovs = {};
    io::Json copyOf = nullptr;  ///< {"conditions": URI without password, "tag", "snapshot"?}
  };
  /// false (and nothing written) when a tag of that name exists.
  virtual Result<bool> createTag(const NewTag& tag) = 0;

  /// What setState did: the tag changed state, or was in it already (a retry: nothing written).
  enum class StateChange { Changed, Already };
  /// Sets a tag's state along an allowed transition (tag_states.hpp), with an optional reason.
  /// Setting the state it has changes nothing — except for `invalid` with another reason than
  /// the one kept, which is refused.
  virtual Result<StateChange> setState(const std::string& tag, TagState to, const std::string& reason) = 0;
  /// setState(published).
  Status lock(const std::string& tag) {
    auto r = setState(tag, TagState::Published, {});
    return r ? Status{} : Status{r.error()};
  }
  /// setState(invalid, reason).
  Status retire(const std::string& tag, const std::string& reason) {
    auto r = setState(tag, TagState::Invalid, reason);
    return r ? Status{} : Status{r.error()};
  }

  /// A promotion (Belle II's running update): the IOVs of a validated tag appended to a running
  /// one from the first run still safe to change.
  struct Promotion {
    std::string from, to;
    std::int64_t firstSafeRun = 0;
    Iov lastBefore;             ///< the running tag's last IOV before
    std::vector<Iov> appended;  ///< the validated tag's IOVs, as appended
    std::string time;           ///< of the change; "" for a dry run
    /// "cut", "extended" or "kept": what became of the running tag's last IOV.
    [[nodiscard]] std::string lastIovFate() const;
  };
  /// Appends the IOVs of `from` to `to`: refused unless `from` is validated, `to` running, both
  /// have IOVs, `from`'s tile the runs from `firstSafeRun` on (no gap, no overlap) and
  /// `firstSafeRun` is after the first run of `to`'s last IOV; that IOV then ends at
  /// firstSafeRun − 1 (cut or extended, the IOV as it was kept for snapshots). One transaction,
  /// with `to`'s row locked as a prompt loop's appends lock it. `dryRun`: the same checks and
  /// answer, nothing written.
  virtual Result<Promotion> promote(const std::string& from, const std::string& to, std::int64_t firstSafeRun,
                                    bool dryRun) = 0;

  /// Makes `tag` a running tag: created (with `description`) when missing; an existing one must
  /// be running already (docs/contract.md §13: a prompt loop refuses a tag in another state).
  virtual Status makeRunning(const std::string& tag, const std::string& description) = 0;
  /// One decided group of a prompt loop (validation/prompt.hpp), stored in one transaction: its
  /// IOV (none: a veto with nothing in force, or runs a promotion covered), its decision record
  /// (decisions.jsonl's line) and the thresholds it was decided by (kept once under their
  /// SHA-256). Refused unless the tag is running, `group` is the number of groups it has
  /// decided, and the IOV starts right after the tag's last one (anywhere for its first). The
  /// same record again (a retry after a kill) changes nothing.
  struct PromptRecord {
    std::int64_t group = 0;
    std::string decision;  ///< compact JSON
    std::optional<NewIov> iov;
    std::string thresholdsSha256, thresholds;  ///< thresholds: compact JSON
  };
  virtual Status appendPrompt(const std::string& tag, const PromptRecord& record) = 0;
  /// The decision records of a running tag's groups, in order (compact JSON each).
  virtual Result<std::vector<std::string>> promptRecords(const std::string& tag) = 0;
  /// Records `me` (JSON text naming a prompt loop) as the one loop writing `tag`, unless another
  /// is recorded and `alive` says it still runs: then returns that one's record ("" when
  /// claimed). One transaction: of two loops started at once, one claims it.
  virtual Result<std::string> claimPrompt(const std::string& tag, const std::string& me,
                                          const std::function<bool(const std::string&)>& alive) = 0;
  /// Thresholds stored by appendPrompt, by SHA-256 (compact JSON); none when not stored.
  virtual Result<std::optional<std::string>> thresholds(const std::string& sha256) = 0;

  /// The URI it was opened with (for messages), without any password.
  [[nodiscard]] virtual const std::string& uri() const = 0;
};

/// The IOVs of one tag read once, with their payloads fetched on demand and kept: the lookups
/// of a job that needs the calibration of many runs (correct, simulate, trend).
class TagSnapshot {
 public:
  /// Fails when the tag does not exist (at `at`), or is invalid now (unless `allowInvalid`: a
  /// table of it, a comparison, never a lookup). `at`: a snapshot time, empty for now.
  static Result<TagSnapshot> load(Database& db, const std::string& tag, bool allowInvalid = false,
                                  const std::string& at = {});
  /// The snapshot time it was read at ("" : now).
  [[nodiscard]] const std::string& at() const { return at_; }
  [[nodiscard]] const Tag& tag() const { return tag_; }
  [[nodiscard]] const std::vector<Iov>& iovs() const { return iovs_; }
  /// The IOV containing `run`, or null.
  [[nodiscard]] const Iov* find(std::int64_t run) const;
  /// The payload of an IOV of this tag.
  Result<const Payload*> payload(const Iov& iov);
  /// Reads the payloads of every IOV at once (before a listing of all of them).
  Status fetchAll();
  /// The IOV containing `run` with its payload; the error names the run, the tag and the database.
  Result<std::pair<const Iov*, const Payload*>> at(std::int64_t run);

 private:
  Database* db_ = nullptr;
  std::string at_;
  Tag tag_;
  std::vector<Iov> iovs_;
  std::vector<std::shared_ptr<const Payload>> payloads_;          // parallel to iovs_
  std::map<std::string, std::shared_ptr<const Payload>> byHash_;  // each hash fetched once
};

}  // namespace emcalign::conddb
