// PostgreSQL back end of the conditions database, through libpqxx: a collaboration's shared
// database. Each transaction is a pqxx::work (READ COMMITTED); a write locks its tag's row
// (SELECT … FOR UPDATE) before it reads the tag's IOVs, so writers of one tag take turns and
// writers of different tags do not wait for each other. A client killed mid-write loses its
// connection, and the server rolls its transaction back.

#include <memory>
#include <optional>

#include <fmt/format.h>
#include <pqxx/pqxx>

#include "sql_backend.hpp"

namespace emcalign::conddb::detail {

namespace {

// How long a write waits for a tag another client is writing (SELECT … FOR UPDATE), unless
// the user set lock_timeout (PGOPTIONS='-c lock_timeout=10s', or the server's default).
constexpr std::string_view kLockTimeout = "60s";
// SQLSTATE lock_not_available: the lock_timeout ran out.
constexpr std::string_view kLockNotAvailable = "55P03";

// One line of a server message.
std::string firstLine(std::string_view text) {
  std::string s(text.substr(0, text.find('\n')));
  while (!s.empty() && (s.back() == ' ' || s.back() == '\r')) s.pop_back();
  if (s.rfind("ERROR:", 0) == 0) s = s.substr(6);
  while (!s.empty() && s.front() == ' ') s.erase(s.begin());
  return s;
}

class Postgres final : public SqlBackend {
 public:
  Postgres(std::unique_ptr<pqxx::connection> c, std::string uri) : c_(std::move(c)), uri_(std::move(uri)) {}
  ~Postgres() override { rollback(); }

  Status beginWrite() override { return begin(); }
  Status beginRead() override { return begin(); }

  Status commit() override {
    if (!tx_) return Error{fmt::format("{}: commit without a transaction", uri_)};
    try {
      tx_->commit();
      tx_.reset();
      return {};
    } catch (const std::exception& e) {
      tx_.reset();
      return Error{fmt::format("{}: commit failed: {}", uri_, firstLine(e.what()))};
    }
  }

  void rollback() noexcept override {
    if (!tx_) return;
    try {
      tx_->abort();
    } catch (...) {
    }
    tx_.reset();
  }

  Result<std::vector<Row>> query(std::string_view sql, const std::vector<Param>& params) override {
    if (Status s = checkParams(params, uri_); !s) return s.error();
    std::vector<std::string> values;
    values.reserve(params.size());
    for (const Param& p : params) {
      values.push_back(std::holds_alternative<std::int64_t>(p) ? std::to_string(std::get<std::int64_t>(p))
                                                               : std::get<std::string>(p));
    }
    try {
      std::optional<pqxx::nontransaction> single;
      pqxx::transaction_base* t = tx_.get();
      if (t == nullptr) t = &single.emplace(*c_);
      const pqxx::result r = t->exec_params(std::string(sql), pqxx::prepare::make_dynamic_params(values));
      std::vector<Row> rows;
      rows.reserve(r.size());
      for (const auto& row : r) {
        Row out;
        for (const auto& field : row) {
          out.push_back(field.is_null() ? std::nullopt : std::optional<std::string>(field.c_str()));
        }
        rows.push_back(std::move(out));
      }
      return rows;
    } catch (const pqxx::sql_error& e) {
      if (e.sqlstate() == kLockNotAvailable) {
        return Error{
            fmt::format("{}: busy: another client has held what this write needs for longer than "
                        "lock_timeout ({}; PGOPTIONS='-c lock_timeout=...' sets it): try again later",
                        uri_, lockTimeout_)};
      }
      return Error{fmt::format("{}: {}", uri_, firstLine(e.what()))};
    } catch (const std::exception& e) {
      return Error{fmt::format("{}: {}", uri_, firstLine(e.what()))};
    }
  }

  // A lock wait that ends: the user's lock_timeout, or kLockTimeout when there is none.
  Status boundLockWaits() {
    auto shown = query("SHOW lock_timeout", {});
    if (!shown) return shown.error();
    lockTimeout_ = !shown->empty() && (*shown)[0][0] ? *(*shown)[0][0] : std::string("0");
    if (lockTimeout_ != "0") return {};
    if (auto set = query(fmt::format("SET lock_timeout = '{}'", kLockTimeout), {}); !set) return set.error();
    lockTimeout_ = std::string(kLockTimeout);
    return {};
  }

  [[nodiscard]] std::string_view forUpdate() const override { return " FOR UPDATE"; }

  Status serializeSchemaChanges() override {
    // Two `init`s at once would both create the tables; one waits for the other instead.
    auto r = query("SELECT pg_advisory_xact_lock(4542243441)", {});
    if (!r) return r.error();
    return {};
  }

  Result<bool> hasSchema() override {
    auto rows = query("SELECT to_regclass('emcalign_meta') IS NOT NULL", {});
    if (!rows) return rows.error();
    return !rows->empty() && (*rows)[0][0] && *(*rows)[0][0] == "t";
  }

  Status afterInit() override { return {}; }
  Status beforeSchemaUpgrade() override { return {}; }
  void afterSchemaUpgrade() noexcept override {}

  Status widenTagStates(std::string_view createTags) override {
    // The CHECK of the state, named by PostgreSQL's rule (table_column_check), made again.
    const std::string_view check = createTags.substr(createTags.find("CHECK ("));
    const std::string condition(check.substr(0, check.find("), created") + 1));
    for (const std::string& sql :
         {std::string("ALTER TABLE emcalign_tags DROP CONSTRAINT IF EXISTS emcalign_tags_state_check"),
          std::string("UPDATE emcalign_tags SET state = 'published' WHERE state = 'locked'"),
          "ALTER TABLE emcalign_tags ADD CONSTRAINT emcalign_tags_state_check " + condition}) {
      if (auto r = query(sql, {}); !r) return r.error();
    }
    return {};
  }
  [[nodiscard]] const std::string& uri() const override { return uri_; }

 private:
  Status begin() {
    rollback();
    try {
      tx_ = std::make_unique<pqxx::work>(*c_);
      return {};
    } catch (const std::exception& e) {
      return Error{fmt::format("{}: cannot begin a transaction: {}", uri_, firstLine(e.what()))};
    }
  }

  std::unique_ptr<pqxx::connection> c_;
  std::unique_ptr<pqxx::work> tx_;
  std::string uri_;
  std::string lockTimeout_;
};

}  // namespace

Result<std::unique_ptr<SqlBackend>> openPostgres(const DatabaseAddress& address) {
  std::unique_ptr<Postgres> db;
  try {
    db = std::make_unique<Postgres>(std::make_unique<pqxx::connection>(address.connection), address.shown);
  } catch (const std::exception& e) {
    // libpq quotes parts of a malformed URI: its message loses the password first.
    const std::string why = address.redact(firstLine(e.what()));
    const bool authentication = why.find("password") != std::string::npos;
    return Error{fmt::format("{}: cannot connect: {}{}", address.shown, why,
                             authentication ? " (the password comes from libpq's PGPASSFILE, ~/.pgpass, or "
                                              "PGPASSWORD)"
                                            : "")};
  }
  if (Status s = db->boundLockWaits(); !s) return Error{address.redact(s.error().message)};
  return std::unique_ptr<SqlBackend>(std::move(db));
}

}  // namespace emcalign::conddb::detail
