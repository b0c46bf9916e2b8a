// A database created only when there is something to store (conddb/database_to_write.hpp).

#include "emcalign/conddb/database_to_write.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/conddb/address.hpp"

namespace emcalign::conddb {

namespace fs = std::filesystem;

DatabaseToWrite::DatabaseToWrite(std::string uri, IfLeftEmpty ifLeftEmpty)
    : uri_(std::move(uri)), ifLeftEmpty_(ifLeftEmpty) {}

Status DatabaseToWrite::prepare() {
  const std::string file = sqliteFileOf(uri_);
  std::error_code ec;
  if (file.empty() || fs::exists(fs::symlink_status(file, ec))) {
    // A server's database, or an existing file, gets the schema if it has none.
    auto db = Database::open(uri_, IfMissing::Create);
    if (!db) return db.error();
    db_ = std::move(*db);
    return {};
  }
  const fs::path dir = fs::path(file).parent_path();
  const std::string shown = dir.empty() ? std::string(".") : dir.string();
  if (!fs::is_directory(dir.empty() ? "." : dir, ec)) {
    return Error{fmt::format("sqlite:{}: cannot create the database: the directory {} does not exist", file, shown)};
  }
  if (::access(shown.c_str(), W_OK | X_OK) != 0) {
    return Error{fmt::format("sqlite:{}: cannot create the database in {}: {}", file, shown, std::strerror(errno))};
  }
  return {};
}

Result<Database*> DatabaseToWrite::create() {
  if (db_) return db_.get();
  const std::string file = sqliteFileOf(uri_);
  std::error_code ec;
  const bool existed = file.empty() || fs::exists(fs::symlink_status(file, ec));
  auto db = Database::open(uri_, IfMissing::Create);
  if (!db) return db.error();
  db_ = std::move(*db);
  created_ = !existed;
  return db_.get();
}

DatabaseToWrite::~DatabaseToWrite() {
  if (!created_ || ifLeftEmpty_ != IfLeftEmpty::Remove || !db_) return;
  auto tags = db_->tags();
  if (!tags || !tags->empty()) return;
  db_.reset();  // closed before its file goes
  const std::string file = sqliteFileOf(uri_);
  std::error_code ec;
  for (const char* suffix : {"", "-wal", "-shm", "-journal"}) fs::remove(file + suffix, ec);
}

std::vector<io::NamedPath> databaseFiles(const std::string& uri, const std::string& option) {
  std::vector<io::NamedPath> out;
  auto address = DatabaseAddress::parse(uri);
  if (!address) return out;
  for (const std::string& f : address->files()) out.push_back({option, f});
  return out;
}

std::string storedAddress(const std::string& uri) {
  auto address = DatabaseAddress::parse(uri);
  if (!address) return shownAddress(uri);
  return address->kind == DatabaseAddress::Kind::Sqlite
             ? "sqlite:" + fs::absolute(address->file).lexically_normal().string()
             : address->shown;
}

}  // namespace emcalign::conddb
