// Opening a conditions database by URI (conditions.hpp).

#include <fmt/format.h>

#include "sql_backend.hpp"

namespace emcalign::conddb {

namespace {
bool isPostgres(const std::string& uri) {
  return uri.rfind("postgresql://", 0) == 0 || uri.rfind("postgres://", 0) == 0;
}
}  // namespace

std::string sqliteFileOf(const std::string& uri) {
  if (isPostgres(uri)) return {};
  std::string path = uri.rfind("sqlite:", 0) == 0 ? uri.substr(7) : uri;
  if (path.rfind("//", 0) == 0) path = path.substr(2);  // sqlite://PATH, as SQLAlchemy writes it
  return path;
}

Result<std::unique_ptr<Database>> Database::open(const std::string& uri, bool create) {
  Result<std::unique_ptr<detail::SqlBackend>> backend = Error{""};
  if (isPostgres(uri)) {
    backend = detail::openPostgres(uri);
  } else {
    const std::string path = sqliteFileOf(uri);
    if (path.empty()) return Error{fmt::format("'{}': no file in this database URI (sqlite:PATH)", uri)};
    if (const auto colon = uri.find("://"); colon != std::string::npos && uri.rfind("sqlite:", 0) != 0) {
      return Error{fmt::format("'{}': unknown database scheme '{}' (sqlite:PATH, a path, or postgresql://…)", uri,
                               uri.substr(0, colon))};
    }
    backend = detail::openSqlite(path, create);
  }
  if (!backend) return backend.error();
  std::unique_ptr<Database> db = detail::makeSqlDatabase(std::move(*backend));
  if (create) {
    if (Status s = db->init(); !s) return s.error();
  } else if (Status s = detail::checkSchemaOf(*db); !s) {
    return s.error();
  }
  return db;
}

}  // namespace emcalign::conddb
