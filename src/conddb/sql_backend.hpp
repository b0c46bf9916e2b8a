#pragma once
// Internal to the conddb module: the few SQL operations the database needs, for SQLite and
// PostgreSQL alike, and the one implementation of the database's semantics on top of them
// (sql_database.cpp). The SQL is written once, with $1, $2, … parameters (SQLite gets ?1,
// ?2, …) and types both engines take (TEXT, BIGINT).

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "emcalign/conddb/address.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/clock.hpp"

namespace emcalign::conddb::detail {

using Param = std::variant<std::int64_t, std::string>;
using Row = std::vector<std::optional<std::string>>;

class SqlBackend {
 public:
  virtual ~SqlBackend() = default;
  /// A transaction that writes: it holds the write lock (SQLite) from its start.
  virtual Status beginWrite() = 0;
  virtual Status beginRead() = 0;
  virtual Status commit() = 0;
  virtual void rollback() noexcept = 0;
  virtual Result<std::vector<Row>> query(std::string_view sql, const std::vector<Param>& params = {}) = 0;
  /// " FOR UPDATE" where the engine locks selected rows (PostgreSQL); "" otherwise.
  [[nodiscard]] virtual std::string_view forUpdate() const = 0;
  /// Called first in the transaction that creates the schema: two `init`s take turns.
  virtual Status serializeSchemaChanges() = 0;
  /// Whether the schema's tables exist.
  virtual Result<bool> hasSchema() = 0;
  /// Engine-specific setup after the tables are made (SQLite: application_id, user_version).
  virtual Status afterInit() = 0;
  /// Around the transaction that upgrades schema 1 (SQLite: its foreign keys off while the tags
  /// table is rebuilt, as SQLite's documented procedure has it; they cannot change inside a
  /// transaction).
  virtual Status beforeSchemaUpgrade() = 0;
  virtual void afterSchemaUpgrade() noexcept = 0;
  /// In the upgrade's transaction: schema 1's tags table (states 'open', 'locked') made to take
  /// the six states of `createTags`, and 'locked' renamed 'published'.
  virtual Status widenTagStates(std::string_view createTags) = 0;
  [[nodiscard]] virtual const std::string& uri() const = 0;
};

/// The tags table of schema 2.
inline constexpr const char* kCreateTags =
    "CREATE TABLE IF NOT EXISTS emcalign_tags (name TEXT PRIMARY KEY, description TEXT NOT NULL, state TEXT NOT NULL "
    "CHECK (state IN ('open', 'testing', 'validated', 'published', 'running', 'invalid')), created TEXT NOT NULL)";

/// Where notices go (Database::setNoticeHandler).
std::function<void(const std::string&)>& noticeHandler();

std::unique_ptr<Database> makeSqlDatabase(std::unique_ptr<SqlBackend> backend);
Result<std::unique_ptr<SqlBackend>> openSqlite(const std::string& path, IfMissing missing, int busyMs = 0);
Result<std::unique_ptr<SqlBackend>> openPostgres(const DatabaseAddress& address);

/// Checks, on open, that the database has the schema of this emcalign.
Status checkSchemaOf(Database& db);

/// Text parameters must not hold NUL: an engine's C API would cut the text there (a lock of
/// "base\0x" locking "base").
Status checkParams(const std::vector<Param>& params, const std::string& uri);

using emcalign::utcNow;  // core/clock.hpp

}  // namespace emcalign::conddb::detail
