// SQLite back end of the conditions database: a local file, WAL journal (readers never wait
// for the writer), a busy timeout (writers wait for each other), BEGIN IMMEDIATE for writes
// (the write lock is taken before anything is read, so two writers cannot both decide from
// the same state), application_id and user_version marking the file as emcalign's.

#include <sqlite3.h>
#include <sys/stat.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <vector>

#include <fmt/format.h>

#include "emcalign/core/text.hpp"

#include "emcalign/io/file_kind.hpp"
#include "emcalign/io/output_file.hpp"
#include "sql_backend.hpp"

namespace emcalign::conddb::detail {

namespace {

constexpr int kApplicationId = 0x454D4341;  // "EMCA"
constexpr int kBusyTimeoutMs = 120000;

// The database and its journals, by the name given and the name of the file a link points to.
std::vector<io::NamedPath> filesOf(const std::vector<std::string>& bases) {
  std::vector<io::NamedPath> files;
  for (const std::string& base : bases) {
    for (const char* suffix : {"", "-wal", "-shm", "-journal"}) files.push_back({"--conditions", base + suffix});
  }
  return files;
}

class Sqlite final : public SqlBackend {
 public:
  // While it is open, the database and its journals are inputs no output may replace or
  // create (io::InputGuard), in the command-line tool and in Python alike.
  Sqlite(sqlite3* db, std::string uri, const std::vector<std::string>& bases)
      : db_(db), uri_(std::move(uri)), guard_(filesOf(bases)) {}
  ~Sqlite() override { sqlite3_close_v2(db_); }

  Status beginWrite() override { return run("BEGIN IMMEDIATE"); }
  Status beginRead() override { return run("BEGIN"); }
  Status commit() override { return run("COMMIT"); }
  void rollback() noexcept override { sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr); }
  [[nodiscard]] std::string_view forUpdate() const override { return ""; }
  Status serializeSchemaChanges() override { return {}; }  // BEGIN IMMEDIATE already does
  [[nodiscard]] const std::string& uri() const override { return uri_; }

  Result<std::vector<Row>> query(std::string_view sql, const std::vector<Param>& params) override {
    if (Status s = checkParams(params, uri_); !s) return s.error();
    std::string text(sql);
    for (char& c : text) {
      if (c == '$') c = '?';  // $1 → ?1: SQLite's numbered parameters
    }
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db_, text.c_str(), -1, &stmt, nullptr) != SQLITE_OK) return failure("prepare");
    std::vector<Row> rows;
    for (std::size_t i = 0; i < params.size(); ++i) {
      const int k = static_cast<int>(i) + 1;
      const int rc =
          std::holds_alternative<std::int64_t>(params[i])
              ? sqlite3_bind_int64(stmt, k, std::get<std::int64_t>(params[i]))
              : sqlite3_bind_text(stmt, k, std::get<std::string>(params[i]).data(),
                                  static_cast<int>(std::get<std::string>(params[i]).size()), SQLITE_TRANSIENT);
      if (rc != SQLITE_OK) {
        sqlite3_finalize(stmt);
        return failure("bind");
      }
    }
    while (true) {
      const int rc = sqlite3_step(stmt);
      if (rc == SQLITE_DONE) break;
      if (rc != SQLITE_ROW) {
        auto e = failure("execute");
        sqlite3_finalize(stmt);
        return e;
      }
      Row row;
      for (int c = 0; c < sqlite3_column_count(stmt); ++c) {
        // The whole value, NUL bytes included (a text edited by hand is not cut there).
        const auto* t = sqlite3_column_text(stmt, c);
        const auto bytes = static_cast<std::size_t>(sqlite3_column_bytes(stmt, c));
        row.push_back(t == nullptr ? std::nullopt
                                   : std::optional<std::string>(std::string(reinterpret_cast<const char*>(t), bytes)));
      }
      rows.push_back(std::move(row));
    }
    sqlite3_finalize(stmt);
    return rows;
  }

  Result<bool> hasSchema() override {
    auto rows = query("SELECT name FROM sqlite_master WHERE type = 'table' AND name = 'emcalign_meta'", {});
    if (!rows) return rows.error();
    return !rows->empty();
  }

  Status afterInit() override {
    if (Status s = run(fmt::format("PRAGMA application_id = {}", kApplicationId)); !s) return s;
    return run(fmt::format("PRAGMA user_version = {}", kSchemaVersion));
  }

  Status beforeSchemaUpgrade() override { return run("PRAGMA foreign_keys = OFF"); }
  void afterSchemaUpgrade() noexcept override {
    sqlite3_exec(db_, "PRAGMA foreign_keys = ON", nullptr, nullptr, nullptr);
  }

  // SQLite cannot change a CHECK constraint: the table is made again, copied, and put in the
  // old one's place (foreign keys off, beforeSchemaUpgrade), then the references checked.
  Status widenTagStates(std::string_view createTags) override {
    std::string create(createTags);
    const std::string from = "emcalign_tags (", to = "emcalign_tags_2 (";
    create.replace(create.find(from), from.size(), to);
    for (const std::string& sql :
         {create,
          std::string("INSERT INTO emcalign_tags_2 (name, description, state, created) SELECT name, description, "
                      "CASE state WHEN 'locked' THEN 'published' ELSE state END, created FROM emcalign_tags"),
          std::string("DROP TABLE emcalign_tags"),
          std::string("ALTER TABLE emcalign_tags_2 RENAME TO emcalign_tags")}) {
      if (Status s = run(sql); !s) return s;
    }
    auto broken = query("PRAGMA foreign_key_check", {});
    if (!broken) return broken.error();
    if (!broken->empty())
      return Error{fmt::format("{}: {} rows refer to nothing after the upgrade", uri_, broken->size())};
    return {};
  }

  // An existing file must be emcalign's (application_id 0: SQLite's, not yet marked).
  Status checkApplication() {
    auto rows = query("PRAGMA application_id", {});
    if (!rows) {
      if (sqlite3_errcode(db_) == SQLITE_NOTADB) {
        return Error{
            fmt::format("{}: not a database (an SQLite file is expected; create one with: emcalign "
                        "conditions init)",
                        uri_)};
      }
      return rows.error();
    }
    const std::string id = rows->empty() || !(*rows)[0][0] ? "0" : *(*rows)[0][0];
    if (id != "0" && id != std::to_string(kApplicationId)) {
      return Error{fmt::format("{}: an SQLite file of another application (application_id {})", uri_, id)};
    }
    return {};
  }

  Status run(const std::string& sql) {
    char* message = nullptr;
    if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &message) != SQLITE_OK) {
      const std::string text = message != nullptr ? message : sqlite3_errmsg(db_);
      sqlite3_free(message);
      return Error{fmt::format("{}: {}: {}", uri_, sql.substr(0, 40), text)};
    }
    return {};
  }

 private:
  [[nodiscard]] Error failure(std::string_view what) const {
    return Error{fmt::format("{}: SQLite {}: {}", uri_, what, sqlite3_errmsg(db_))};
  }

  sqlite3* db_;
  std::string uri_;
  io::InputGuard guard_;
};

}  // namespace

Result<std::unique_ptr<SqlBackend>> openSqlite(const std::string& path, IfMissing missing, int busyMs) {
  const bool create = missing == IfMissing::Create;
  const std::string uri = "sqlite:" + path;
  struct stat st {};
  const bool exists = ::stat(path.c_str(), &st) == 0;
  if (!exists && !create) {
    return Error{
        fmt::format("{}: no such database (create one with: emcalign conditions init {})", uri, shellArgument(uri))};
  }
  if (exists && !S_ISREG(st.st_mode)) return Error{fmt::format("{}: not a regular file", uri)};
  // A file of another kind is named by what it is, before SQLite reads it.
  if (exists && st.st_size > 0) {
    char head[16] = {};
    if (std::FILE* f = std::fopen(path.c_str(), "rb")) {
      const std::size_t got = std::fread(head, 1, sizeof head, f);
      std::fclose(f);
      if (got < sizeof head || std::memcmp(head, "SQLite format 3", 16) != 0) {
        const std::string kind = io::describeFileAt(path);
        return Error{fmt::format("{}: {}{}", uri,
                                 kind.empty()
                                     ? std::string("not a conditions database (not an SQLite file)")
                                     : fmt::format("this is {}, not a conditions database (an SQLite file)", kind),
                                 create ? ": conditions init creates a new one, give it a new file name" : "")};
      }
    }
  }
  // SQLite opens its journals itself, next to the file a link points to: one that is a FIFO or
  // a device would block it or take the database's writes.
  std::error_code ec;
  const std::string real = exists ? std::filesystem::canonical(path, ec).string() : path;
  const std::vector<std::string> bases =
      ec || real == path ? std::vector<std::string>{path} : std::vector<std::string>{path, real};
  for (const std::string& base : bases) {
    for (const char* suffix : {"-wal", "-shm", "-journal"}) {
      struct stat companion {};
      if (::lstat((base + suffix).c_str(), &companion) == 0 && !S_ISREG(companion.st_mode)) {
        return Error{
            fmt::format("{}: {}{} is not a regular file (a journal SQLite writes): remove it", uri, base, suffix)};
      }
    }
  }
  sqlite3* db = nullptr;
  const int flags = SQLITE_OPEN_READWRITE | (create ? SQLITE_OPEN_CREATE : 0) | SQLITE_OPEN_FULLMUTEX;
  if (sqlite3_open_v2(path.c_str(), &db, flags, nullptr) != SQLITE_OK) {
    const std::string why = db != nullptr ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close_v2(db);
    return Error{fmt::format("{}: cannot open: {}", uri, why)};
  }
  auto s = std::make_unique<Sqlite>(db, uri, bases);
  sqlite3_busy_timeout(db, busyMs > 0 ? busyMs : kBusyTimeoutMs);
  if (Status st2 = s->checkApplication(); !st2) return st2.error();
  if (Status st2 = s->run("PRAGMA journal_mode = WAL"); !st2) return st2.error();
  if (Status st2 = s->run("PRAGMA synchronous = FULL"); !st2) return st2.error();
  if (Status st2 = s->run("PRAGMA foreign_keys = ON"); !st2) return st2.error();
  return std::unique_ptr<SqlBackend>(std::move(s));
}

}  // namespace emcalign::conddb::detail
