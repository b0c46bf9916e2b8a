#pragma once
// A conditions database a command stores into, created only when there is something to
// store, and the files of a database as a command's inputs (docs/campaign.md, "Where the
// database is, and its password").

#include <memory>
#include <string>
#include <vector>

#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::conddb {

/// Created only when there is something to store: a command refused for its inputs leaves no
/// new, empty database behind.
///   DatabaseToWrite target(uri);
///   target.prepare();   // before the work: an existing database (a server's) opened, so
///                       // that a wrong address is refused at once; for a new SQLite file,
///                       // its directory checked
///   …                   // read and check the inputs, fit
///   target.create();    // the database, its SQLite file created now when new
/// With IfLeftEmpty::Remove, a file this object created is removed again when it is destroyed
/// without a tag in it (a campaign whose every group failed). Not for jobs that may create the
/// same file at once (campaign --group): another one may be storing into it.
class DatabaseToWrite {
 public:
  enum class IfLeftEmpty { Remove, Keep };
  explicit DatabaseToWrite(std::string uri, IfLeftEmpty ifLeftEmpty = IfLeftEmpty::Remove);
  DatabaseToWrite(const DatabaseToWrite&) = delete;
  DatabaseToWrite& operator=(const DatabaseToWrite&) = delete;
  ~DatabaseToWrite();

  Status prepare();
  /// The database when it exists (after prepare or create), else null: nothing stored in it yet.
  Database* existing() { return db_.get(); }
  Result<Database*> create();

 private:
  std::string uri_;
  IfLeftEmpty ifLeftEmpty_;
  std::unique_ptr<Database> db_;
  bool created_ = false;  // the SQLite file did not exist before create()
};

/// The files of a conditions database (an SQLite file and its journals; none for a server,
/// nor for an address refused, which is refused with its reason when opened), as inputs of a
/// command named by `option`: no output may replace them.
std::vector<io::NamedPath> databaseFiles(const std::string& uri, const std::string& option = "--conditions");

/// The address as a plan or a record keeps it: an SQLite file by its absolute path
/// (`sqlite:/abs/path`), a server without a password (DatabaseAddress::shown).
std::string storedAddress(const std::string& uri);

}  // namespace emcalign::conddb
