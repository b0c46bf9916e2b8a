// Database addresses (conddb/address.hpp): what is taken, what is refused, and that no form of
// a password ever reaches a message.

#include "emcalign/conddb/address.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

namespace emcalign::conddb {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

TEST(DatabaseAddress, SqliteFilesInEveryAcceptedForm) {
  for (const auto& [uri, file] : {std::pair{"c.db", "c.db"},
                                  {"sqlite:c.db", "c.db"},
                                  {"sqlite:dir/c.db", "dir/c.db"},
                                  {"sqlite://c.db", "c.db"},
                                  {"sqlite:///abs/c.db", "/abs/c.db"},
                                  {"/abs/run:1.db", "/abs/run:1.db"},
                                  {"sqlite:a=b.db", "a=b.db"}}) {
    auto a = DatabaseAddress::parse(uri);
    ASSERT_TRUE(a) << uri << ": " << a.error().message;
    EXPECT_EQ(a->kind, DatabaseAddress::Kind::Sqlite) << uri;
    EXPECT_EQ(a->file, file) << uri;
    EXPECT_EQ(a->shown, std::string("sqlite:") + file);
    EXPECT_FALSE(a->hasPassword());
    EXPECT_EQ(a->files(),
              (std::vector<std::string>{a->file, a->file + "-wal", a->file + "-shm", a->file + "-journal"}));
  }
}

TEST(DatabaseAddress, RefusesDatabasesThatLoseWhatIsStored) {
  for (const char* uri : {":memory:", "sqlite::memory:", "sqlite:", "", "sqlite:file:x.db?mode=memory",
                          "sqlite:file:c.db?vfs=unix-none", "sqlite:file::memory:?cache=shared"}) {
    auto a = DatabaseAddress::parse(uri);
    ASSERT_FALSE(a) << uri;
    EXPECT_FALSE(a.error().message.empty());
  }
  EXPECT_THAT(DatabaseAddress::parse(":memory:").error().message, HasSubstr("in-memory"));
  // A journal's name: SQLite would delete the database as a stale journal of c.db.
  for (const char* journal : {"c.db-wal", "sqlite:c.db-shm", "sqlite:/data/c.db-journal"}) {
    auto refused = DatabaseAddress::parse(journal);
    ASSERT_FALSE(refused) << journal;
    EXPECT_THAT(refused.error().message, HasSubstr("the name of a journal SQLite keeps beside"));
  }
  EXPECT_TRUE(DatabaseAddress::parse("sqlite:c-wal.db"));
  EXPECT_THAT(DatabaseAddress::parse("sqlite:file:x.db?mode=memory").error().message, HasSubstr("URI filenames"));
}

TEST(DatabaseAddress, RefusesOtherSchemesAndKeywordStringsWithoutEchoingThem) {
  auto scheme = DatabaseAddress::parse("mysql://me:hunter2@host/db");
  ASSERT_FALSE(scheme);
  EXPECT_THAT(scheme.error().message, HasSubstr("unknown database scheme 'mysql'"));
  EXPECT_THAT(scheme.error().message, Not(HasSubstr("hunter2")));
  auto almost = DatabaseAddress::parse("postgresql:/me:hunter2@host/db");
  ASSERT_FALSE(almost);
  EXPECT_THAT(almost.error().message, HasSubstr("postgresql://"));
  EXPECT_THAT(almost.error().message, Not(HasSubstr("hunter2")));
  auto keywords = DatabaseAddress::parse("host=db.lab password=hunter2 dbname=snd");
  ASSERT_FALSE(keywords);
  EXPECT_THAT(keywords.error().message, HasSubstr("keyword string"));
  EXPECT_THAT(keywords.error().message, Not(HasSubstr("hunter2")));
  EXPECT_THAT(keywords.error().message, HasSubstr("PGPASSFILE"));
}

TEST(DatabaseAddress, ShowsAServerWithoutItsPassword) {
  struct Case {
    const char* uri;
    const char* shown;
    bool password;
  };
  for (const Case& c : {Case{"postgresql://calib@host:5432/snd", "postgresql://calib@host:5432/snd", false},
                        Case{"postgres://calib:hunter2@host/snd", "postgres://calib@host/snd", true},
                        Case{"postgresql://calib@host/snd?password=hunter2", "postgresql://calib@host/snd", true},
                        Case{"postgresql://calib@host/snd?sslmode=require&password=hunter2&application_name=x",
                             "postgresql://calib@host/snd?sslmode=require&application_name=x", true},
                        Case{"postgresql://calib@host/snd?pass%77ord=hunter2", "postgresql://calib@host/snd", true},
                        Case{"postgresql://calib@host/snd?PASSWORD=hunter2", "postgresql://calib@host/snd", true},
                        Case{"postgresql://calib:hun%2Fter2@host/snd", "postgresql://calib@host/snd", true},
                        Case{"postgresql://calib:pa?ss@host/snd", "postgresql://calib@host/snd", true},
                        Case{"postgresql:///snd", "postgresql:///snd", false},
                        Case{"postgresql://calib@host/snd?sslpassword=keyPass9&sslmode=require",
                             "postgresql://calib@host/snd?sslmode=require", true},
                        Case{"postgresql://calib@host/snd?password%3Dhunter2", "postgresql://calib@host/snd", true},
                        Case{"postgresql://calib@host/snd?passwd=hunter2&sslmode=require",
                             "postgresql://calib@host/snd?passwd=…&sslmode=require", true}}) {
    auto a = DatabaseAddress::parse(c.uri);
    ASSERT_TRUE(a) << c.uri << ": " << a.error().message;
    EXPECT_EQ(a->kind, DatabaseAddress::Kind::Postgres);
    EXPECT_EQ(a->shown, c.shown) << c.uri;
    EXPECT_EQ(a->hasPassword(), c.password) << c.uri;
    EXPECT_THAT(a->connection, HasSubstr("connect_timeout=")) << "a silent server is an error, not a hang";
  }
}

TEST(DatabaseAddress, RefusesAPasswordThatLibpqWouldSplit) {
  // A raw '/' or '@' in the password: libpq takes part of it for the host or the port.
  for (const char* uri : {"postgresql://calib:hunt/er2@host/snd", "postgresql://calib:hunt@er2@host/snd",
                          "postgresql://calib@host/snd?application_name=a@b"}) {
    auto a = DatabaseAddress::parse(uri);
    ASSERT_FALSE(a) << uri;
    EXPECT_THAT(a.error().message, HasSubstr("percent-encoded"));
    EXPECT_THAT(a.error().message, Not(HasSubstr("hunt")));
    EXPECT_THAT(a.error().message, Not(HasSubstr("er2")));
  }
}

TEST(DatabaseAddress, RedactsEveryFormOfThePasswordInAMessage) {
  const std::string uri = "postgresql://calib:s%65cret99@host/snd?password=other77pw";
  auto a = DatabaseAddress::parse(uri);
  ASSERT_TRUE(a) << a.error().message;
  const std::string message = "invalid URI \"" + a->connection + "\" near s%65cret99, secret99 and other77pw; also " +
                              uri + " and calib:s%65cret99";
  const std::string redacted = a->redact(message);
  for (const char* secret : {"s%65cret99", "secret99", "other77pw", "calib:s"}) {
    EXPECT_THAT(redacted, Not(HasSubstr(secret))) << redacted;
  }
  EXPECT_THAT(redacted, HasSubstr(a->shown));
  // Text without a password is left alone.
  auto plain = DatabaseAddress::parse("postgresql://calib@host/snd");
  ASSERT_TRUE(plain);
  EXPECT_EQ(plain->redact("could not connect to server"), "could not connect to server");
}

TEST(DatabaseAddress, RefusesANul) {
  EXPECT_FALSE(DatabaseAddress::parse(std::string_view("c.db\0postgresql://x", 20)));
  EXPECT_FALSE(DatabaseAddress::parse(std::string_view("new\0.db", 7)));
}

TEST(DatabaseAddress, ShownAddressOfWhatDoesNotParse) {
  EXPECT_EQ(shownAddress("postgresql://calib:hunt/er2@host/snd"), "postgresql://…");
  EXPECT_EQ(shownAddress("host=x password=hunter2"), "(a database address, not shown)");
  EXPECT_EQ(shownAddress("postgresql://calib:hunter2@host/snd"), "postgresql://calib@host/snd");
  EXPECT_EQ(shownAddress("c.db"), "sqlite:c.db");
}

}  // namespace
}  // namespace emcalign::conddb
