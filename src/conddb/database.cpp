// Opening a conditions database by its address (conditions.hpp, address.hpp).

#include <fmt/format.h>

#include "emcalign/conddb/address.hpp"
#include "sql_backend.hpp"

namespace emcalign::conddb {

std::string sqliteFileOf(const std::string& uri) {
  auto address = DatabaseAddress::parse(uri);
  return address && address->kind == DatabaseAddress::Kind::Sqlite ? address->file : std::string();
}

Result<std::unique_ptr<Database>> Database::open(const std::string& uri, IfMissing missing, int busyMs) {
  auto address = DatabaseAddress::parse(uri);
  if (!address) return address.error();
  auto backend = address->kind == DatabaseAddress::Kind::Postgres ? detail::openPostgres(*address)
                                                                  : detail::openSqlite(address->file, missing, busyMs);
  if (!backend) return backend.error();
  std::unique_ptr<Database> db = detail::makeSqlDatabase(std::move(*backend));
  if (missing == IfMissing::Create) {
    if (Status s = db->init(); !s) return s.error();
  } else if (Status s = detail::checkSchemaOf(*db); !s) {
    return s.error();
  }
  return db;
}

}  // namespace emcalign::conddb
