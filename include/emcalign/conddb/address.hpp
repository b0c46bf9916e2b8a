#pragma once
// The address of a conditions database, checked before anything is opened, and the form of
// it that may be shown (docs/campaign.md, "Where the database is, and its password").
//
// Accepted:
//   - `sqlite:PATH`, `sqlite://PATH` (as SQLAlchemy writes it) or a plain PATH: an SQLite file.
//     Refused: `:memory:` and SQLite's URI filenames (`file:...?mode=memory`, `vfs=unix-none`):
//     a database that vanishes with the process, or one written without locking, would take
//     a campaign's results with it while it says "stored".
//   - `postgresql://[user[:password]@][host][:port][/dbname][?param=value&...]` (also
//     `postgres://`), libpq's URI. A password belongs in libpq's own PGPASSFILE (~/.pgpass)
//     or PGPASSWORD, never on a command line that `ps` shows and a batch log keeps; one
//     given in the URI (as `user:password@` or `?password=`) still works, and is never shown.
// Refused, without echoing the text (it may hold a password): a libpq keyword string
// (`host=... password=...`), another scheme, and a URI whose '@' or '/' in the user name or
// password is not percent-encoded (%40, %2F): libpq would read part of the password as the
// host or the port, and print it in its messages.
//
// `shown` is what every message, file and database record says instead of the URI: the
// user, host, port, database and parameters, without any password. Messages from libpq
// pass through `redact`, which removes the password in every form it was written.

#include <string>
#include <string_view>
#include <vector>

#include "emcalign/core/result.hpp"

namespace emcalign::conddb {

struct DatabaseAddress {
  enum class Kind { Sqlite, Postgres };
  Kind kind = Kind::Sqlite;
  std::string file;        ///< Sqlite: the database file
  std::string connection;  ///< Postgres: the URI given to libpq
  std::string shown;       ///< the address without any password, for messages and records

  /// Parses and checks an address; the error never repeats a password.
  static Result<DatabaseAddress> parse(std::string_view uri);
  /// Whether the address carries a password (a plan or a record must not hold one).
  [[nodiscard]] bool hasPassword() const { return !secrets_.empty(); }
  /// `message` with every form of the password replaced by "***" and the URI by `shown`.
  [[nodiscard]] std::string redact(std::string message) const;
  /// Sqlite: the file and its journals (-wal, -shm, -journal), which no output may replace,
  /// also beside the file a link points to; none for a server.
  [[nodiscard]] std::vector<std::string> files() const;

 private:
  friend struct AddressParser;
  std::vector<std::string> secrets_;  ///< the password as written and decoded, user:password
  std::string raw_;                   ///< the address as given
};

/// The form of `uri` that may be shown: `shown` when it parses, else as much of it as
/// cannot hold a password (a PostgreSQL URI's scheme only; a path as it is).
std::string shownAddress(std::string_view uri);

}  // namespace emcalign::conddb
