// Opening a conditions database by URI (conditions.hpp).

#include <fmt/format.h>

#include "sql_backend.hpp"

namespace emcalign::conddb {

Result<std::unique_ptr<Database>> Database::open(const std::string& uri, bool create) {
  Result<std::unique_ptr<detail::SqlBackend>> backend = Error{""};
  const bool postgres = uri.rfind("postgresql://", 0) == 0 || uri.rfind("postgres://", 0) == 0;
  if (postgres) {
    backend = detail::openPostgres(uri);
  } else {
    std::string path = uri.rfind("sqlite:", 0) == 0 ? uri.substr(7) : uri;
    if (path.rfind("//", 0) == 0) path = path.substr(2);  // sqlite://PATH, as SQLAlchemy writes it
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
