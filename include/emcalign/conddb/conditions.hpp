#pragma once
// The conditions database: calibrations stored by run range (docs/campaign.md).
//
// The model is a small, strict one, learnt from the systems physicists use — CMS CondDB
// (tags, content-addressed payloads), Belle II (inclusive run-range IOVs, immutable
// published tags, a local SQLite file marked with application_id/user_version) and ATLAS
// COOL (a single-version folder refuses overlapping intervals):
//   - a tag has a name, a description and a state, open or locked; a locked tag never
//     changes again;
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
// middle leaves the database as it was. The schema version is checked on open.

#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "emcalign/calib/sigma_sys.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::conddb {

/// The schema this emcalign reads and writes.
inline constexpr int kSchemaVersion = 1;
inline constexpr std::string_view kPayloadFormat = "emcalign-payload/1";

/// Open: IOVs may be added. Locked: never changes again. Retired: an open tag withdrawn (a
/// mistake): kept and listed, never served to a lookup, never written to (its mark is a row
/// "retired:TAG" of emcalign_meta: no schema change). Running: a prompt loop's tag, whose IOVs
/// are only appended after its last one (its mark is a row "running:TAG").
enum class TagState { Open, Locked, Retired, Running };
std::string_view name(TagState s);

struct Tag {
  std::string name;
  std::string description;
  TagState state = TagState::Open;
  std::string created;  ///< UTC, ISO 8601
  std::string retired;  ///< Retired: "when: why"
};

struct Iov {
  std::int64_t firstRun = 0;  ///< inclusive
  std::int64_t lastRun = 0;   ///< inclusive
  std::string payload;        ///< its SHA-256
  std::string inserted;       ///< UTC, ISO 8601
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
  /// The parameter file of this calibration (SPEC §3: parameters, errors, covariance, …).
  [[nodiscard]] io::Json parameterFile() const;
  /// The model of the fit behind it, in words: "the paper's model" (with "depth offset …"
  /// when one was set), "corrections PATH"; "" when the payload does not say (a parameter
  /// file stored without its fit).
  [[nodiscard]] std::string model() const;
  /// Its parameters, errors (quoted and statistical) and derived values.
  [[nodiscard]] StoredValues values() const;
  /// The selected events of its fit; none when the payload does not say.
  [[nodiscard]] std::optional<std::int64_t> selectedEvents() const;
  /// The SHA-256 of each file its fit read, as (file name, SHA-256) in the order stored; empty
  /// when it records none.
  [[nodiscard]] std::vector<std::pair<std::string, std::string>> inputDigests() const;
  /// The corrections a campaign fitted it with, as the campaign named them; "" when the
  /// payload names none (a fit result stored with `conditions put` records its model under
  /// model_corrections instead: see model() and depthOffsetCm()).
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

/// A payload from a fit result (SPEC §3) or a parameter file, with its provenance (free JSON
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
  /// existing database must have this schema version; `IfMissing::Create` makes a new SQLite
  /// file (a PostgreSQL database must exist) and `init()`s its schema.
  /// `busyMs`: how long an SQLite write waits for another writer's lock (0: two minutes); a loop
  /// that must stay responsive (prompt) waits less and tries again later.
  static Result<std::unique_ptr<Database>> open(const std::string& uri, IfMissing missing = IfMissing::Refuse,
                                                int busyMs = 0);
  virtual ~Database() = default;

  /// Creates the schema (idempotent: an existing one of this version is left as it is).
  virtual Status init() = 0;

  virtual Result<std::vector<Tag>> tags() = 0;
  virtual Result<std::optional<Tag>> tag(const std::string& name) = 0;
  /// Stores `payload` for runs [first, last] of `tag` (a tag that does not exist is created,
  /// open, with `description`, or refused, as `newTag` says), in one transaction; refused for a
  /// locked tag, an overlap with an IOV of the tag, or first > last.
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
  /// The IOV of `tag` that contains `run`, with its payload; none if no IOV does.
  virtual Result<std::optional<std::pair<Iov, Payload>>> get(const std::string& tag, std::int64_t run) = 0;
  /// The IOVs of a tag by first run.
  virtual Result<std::vector<Iov>> iovs(const std::string& tag) = 0;
  virtual Result<Payload> payload(const std::string& hash) = 0;
  /// Locks a tag: no IOV is added to it afterwards (refused for a retired tag).
  virtual Status lock(const std::string& tag) = 0;
  /// Retires an open tag (refused for a locked one: a published calibration is never
  /// withdrawn); retiring a retired tag again with the same reason changes nothing (a retry),
  /// with another reason is refused, naming the first.
  virtual Status retire(const std::string& tag, const std::string& reason) = 0;

  /// Makes `tag` a running tag: created (with `description`) when missing; an existing one must
  /// be running already (SPEC §13: a prompt loop refuses a tag in another state).
  virtual Status makeRunning(const std::string& tag, const std::string& description) = 0;
  /// One decided group of a prompt loop (validation/prompt.hpp), stored in one transaction: its
  /// IOV (none: a veto with nothing in force), its decision record (decisions.jsonl's line) and
  /// the thresholds it was decided by (kept once under their SHA-256). Refused unless the tag is
  /// running, `group` is the number of groups it has decided, and the IOV starts right after
  /// the tag's last one (anywhere for its first). The same record again (a retry after a kill)
  /// changes nothing.
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
  /// Fails when the tag does not exist, or is retired (unless `allowRetired`: a table of it,
  /// a comparison, never a lookup).
  static Result<TagSnapshot> load(Database& db, const std::string& tag, bool allowRetired = false);
  [[nodiscard]] const Tag& tag() const { return tag_; }
  [[nodiscard]] const std::vector<Iov>& iovs() const { return iovs_; }
  /// The IOV containing `run`, or null.
  [[nodiscard]] const Iov* find(std::int64_t run) const;
  /// The payload of an IOV of this tag.
  Result<const Payload*> payload(const Iov& iov);
  /// The IOV containing `run` with its payload; the error names the run, the tag and the database.
  Result<std::pair<const Iov*, const Payload*>> at(std::int64_t run);

 private:
  Database* db_ = nullptr;
  Tag tag_;
  std::vector<Iov> iovs_;
  std::vector<std::unique_ptr<Payload>> payloads_;  // parallel to iovs_ (shared hashes fetched once)
};

}  // namespace emcalign::conddb
