// The conditions database on both back ends: the same tests against an SQLite file and a
// fresh database on the test suite's PostgreSQL server (tests/common/postgres_support.hpp).

#include "emcalign/conddb/conditions.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/geometry/detector.hpp"
#include "postgres_support.hpp"
#include "test_support.hpp"

namespace emcalign::conddb {
namespace {

namespace fs = std::filesystem;
using io::Json;

double r1() { return geometry::DetectorDescription::sndDefault().r1(); }

// A parameter file with α = `alpha` degrees and dx = `dx` cm.
Payload payloadOf(double alpha, double dx = 0.3) {
  auto eta = geometry::testing::paperLike();
  eta[Param::Alpha] = alpha * units::deg;
  eta[Param::Dx] = dx;
  auto p = makePayload(io::alignmentToJson(eta), r1(), "test", Json{{"note", "unit test"}});
  EXPECT_TRUE(p) << p.error().message;
  return *p;
}

class Conditions : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam() == "sqlite") {
      dir_ = fs::temp_directory_path() / fmt::format("emcalign-conddb-{}-{}", ::getpid(), counter_++);
      fs::create_directories(dir_);
      uri_ = "sqlite:" + (dir_ / "conditions.db").string();
    } else {
      uri_ = testing::freshPostgresDatabase();
    }
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  std::unique_ptr<Database> create() {
    auto db = Database::open(uri_, IfMissing::Create);
    EXPECT_TRUE(db) << db.error().message;
    return std::move(*db);
  }
  std::unique_ptr<Database> open() {
    auto db = Database::open(uri_);
    EXPECT_TRUE(db) << db.error().message;
    return std::move(*db);
  }

  static inline int counter_ = 0;
  fs::path dir_;
  std::string uri_;
};

TEST_P(Conditions, StoresAndFindsByRun) {
  auto db = create();
  const Payload a = payloadOf(2.8), b = payloadOf(2.9);
  ASSERT_TRUE(db->put("align", 1, 40, a, IfMissing::Create, "test tag"));
  ASSERT_TRUE(db->put("align", 41, 100, b, IfMissing::Refuse));
  // One payload stored once, however many IOVs hold it.
  ASSERT_TRUE(db->put("align", 200, 210, a, IfMissing::Refuse));

  auto iovs = db->iovs("align");
  ASSERT_TRUE(iovs);
  ASSERT_EQ(iovs->size(), 3U);
  EXPECT_EQ((*iovs)[0].firstRun, 1);
  EXPECT_EQ((*iovs)[0].lastRun, 40);
  EXPECT_EQ((*iovs)[0].payload, a.hash());
  EXPECT_EQ((*iovs)[2].payload, a.hash());
  EXPECT_EQ((*iovs)[1].firstRun, 41);

  for (auto [run, expected] : {std::pair{1, 2.8}, {40, 2.8}, {41, 2.9}, {100, 2.9}, {205, 2.8}}) {
    auto got = db->get("align", run);
    ASSERT_TRUE(got) << got.error().message;
    ASSERT_TRUE(got->has_value()) << "run " << run;
    auto eta = io::parseAlignment((*got)->second.parameterFile(), r1(), "payload");
    ASSERT_TRUE(eta) << eta.error().message;
    EXPECT_NEAR((*eta)[Param::Alpha] / units::deg, expected, 1e-12) << "run " << run;
    EXPECT_EQ((*got)->second.hash(), (*got)->first.payload);
  }
  for (int run : {0, 101, 199, 211, -5}) {
    auto got = db->get("align", run);
    ASSERT_TRUE(got);
    EXPECT_FALSE(got->has_value()) << "run " << run;
  }
  auto none = db->get("other", 5);
  ASSERT_TRUE(none);
  EXPECT_FALSE(none->has_value());

  auto tag = db->tag("align");
  ASSERT_TRUE(tag);
  ASSERT_TRUE(tag->has_value());
  EXPECT_EQ((*tag)->description, "test tag");
  EXPECT_EQ((*tag)->state, TagState::Open);
  auto stored = db->payload(a.hash());
  ASSERT_TRUE(stored);
  EXPECT_EQ(stored->content, a.content);
  EXPECT_FALSE(db->payload(std::string(64, '0')));
}

TEST_P(Conditions, RefusesOverlapsLockedTagsAndBadRanges) {
  auto db = create();
  const Payload a = payloadOf(2.8);
  ASSERT_TRUE(db->put("t", 10, 20, a, IfMissing::Create));
  for (auto [first, last] : {std::pair{5, 10}, {20, 30}, {12, 15}, {1, 100}, {10, 20}}) {
    Status s = db->put("t", first, last, a, IfMissing::Refuse);
    ASSERT_FALSE(s) << first << "-" << last;
    EXPECT_NE(s.error().message.find("overlap its IOV 10-20"), std::string::npos) << s.error().message;
  }
  EXPECT_TRUE(db->put("t", 21, 21, a, IfMissing::Refuse));
  EXPECT_TRUE(db->put("t", 1, 9, a, IfMissing::Refuse));
  Status backwards = db->put("t", 30, 25, a, IfMissing::Refuse);
  ASSERT_FALSE(backwards);
  EXPECT_NE(backwards.error().message.find("first run is after the last"), std::string::npos);
  // A negative run could not be read back (the readers take runs of 0 or more): never stored.
  Status negative = db->put("t", -5, -1, a, IfMissing::Refuse);
  ASSERT_FALSE(negative);
  EXPECT_NE(negative.error().message.find("runs -5--1: a run number is 0 or more"), std::string::npos)
      << negative.error().message;
  Status noTag = db->put("u", 1, 2, a, IfMissing::Refuse);
  ASSERT_FALSE(noTag);
  EXPECT_NE(noTag.error().message.find("no tag 'u'"), std::string::npos);
  EXPECT_FALSE(db->put("bad name", 1, 2, a, IfMissing::Create));
  EXPECT_FALSE(db->put("", 1, 2, a, IfMissing::Create));

  ASSERT_TRUE(db->lock("t"));
  Status locked = db->put("t", 50, 60, a, IfMissing::Refuse);
  ASSERT_FALSE(locked);
  EXPECT_NE(locked.error().message.find("is published"), std::string::npos) << locked.error().message;
  EXPECT_FALSE(db->lock("nope"));
  auto tag = db->tag("t");
  ASSERT_TRUE(tag && tag->has_value());
  EXPECT_EQ((*tag)->state, TagState::Published);
  auto iovs = db->iovs("t");
  ASSERT_TRUE(iovs);
  EXPECT_EQ(iovs->size(), 3U);  // nothing refused was half-written
}

// A tag made by mistake is retired: kept and listed, never served or written to again; a
// locked tag is never retired.
TEST_P(Conditions, ARetiredTagIsKeptListedAndNeverServed) {
  auto db = create();
  const Payload a = payloadOf(2.8);
  ASSERT_TRUE(db->put("wrong", 1, 10, a, IfMissing::Create));
  ASSERT_TRUE(db->put("good", 1, 10, a, IfMissing::Create));
  ASSERT_TRUE(db->lock("good"));
  ASSERT_TRUE(db->get("wrong", 5));
  ASSERT_TRUE(db->retire("wrong", "the wrong corrections"));
  EXPECT_TRUE(db->retire("wrong", "the wrong corrections"));  // a retry: nothing changes
  // Another reason is refused, naming the first (issue 44: it was kept while success was said).
  const Status again = db->retire("wrong", "again");
  ASSERT_FALSE(again);
  EXPECT_NE(again.error().message.find("invalid already"), std::string::npos) << again.error().message;
  EXPECT_NE(again.error().message.find("the wrong corrections"), std::string::npos) << again.error().message;
  auto got = db->get("wrong", 5);
  ASSERT_FALSE(got);
  EXPECT_NE(got.error().message.find("is invalid"), std::string::npos) << got.error().message;
  EXPECT_NE(got.error().message.find("the wrong corrections"), std::string::npos) << got.error().message;
  EXPECT_FALSE(db->put("wrong", 11, 20, a, IfMissing::Refuse));
  EXPECT_FALSE(db->lock("wrong"));
  auto tag = open()->tag("wrong");
  ASSERT_TRUE(tag && tag->has_value());
  EXPECT_EQ((*tag)->state, TagState::Invalid);
  EXPECT_EQ((*tag)->reason, "the wrong corrections");
  EXPECT_FALSE(TagSnapshot::load(*db, "wrong"));
  auto kept = TagSnapshot::load(*db, "wrong", true);
  ASSERT_TRUE(kept);
  EXPECT_EQ(kept->iovs().size(), 1U);
  Status locked = db->retire("good", "no");
  ASSERT_FALSE(locked);
  EXPECT_NE(locked.error().message.find("is published"), std::string::npos) << locked.error().message;
  EXPECT_TRUE(db->get("good", 5));
  EXPECT_FALSE(db->retire("nope", ""));
  auto tags = db->tags();
  ASSERT_TRUE(tags);
  EXPECT_EQ(tags->size(), 2U);
}

TEST_P(Conditions, ARunningTagIsOnlyAppendedAndKeepsItsDecisions) {
  auto db = create();
  const Payload a = payloadOf(2.8), b = payloadOf(2.9);
  ASSERT_TRUE(db->makeRunning("prompt", "the prompt loop's"));
  ASSERT_TRUE(db->makeRunning("prompt", "again"));  // a restart
  auto tag = db->tag("prompt");
  ASSERT_TRUE(tag && tag->has_value());
  EXPECT_EQ((*tag)->state, TagState::Running);
  EXPECT_EQ((*tag)->description, "the prompt loop's");
  // Another state is refused.
  ASSERT_TRUE(db->put("offline", 1, 10, a, IfMissing::Create));
  const Status notRunning = db->makeRunning("offline", "");
  ASSERT_FALSE(notRunning);
  EXPECT_NE(notRunning.error().message.find("is open, not running"), std::string::npos) << notRunning.error().message;

  const auto record = [&](std::int64_t group, std::optional<Database::NewIov> iov) {
    return Database::PromptRecord{group, Json{{"group", group}}.dump(), std::move(iov), "abc", R"({"t":1})"};
  };
  // A vetoed first group: a record, no IOV.
  ASSERT_TRUE(db->appendPrompt("prompt", record(0, std::nullopt)));
  ASSERT_TRUE(db->appendPrompt("prompt", record(0, std::nullopt))) << "a retry changes nothing";
  const Status otherwise = db->appendPrompt("prompt", Database::PromptRecord{0, "{}", std::nullopt, "abc", "{}"});
  ASSERT_FALSE(otherwise);
  EXPECT_NE(otherwise.error().message.find("decided already"), std::string::npos) << otherwise.error().message;
  EXPECT_FALSE(db->appendPrompt("prompt", record(2, Database::NewIov{5, 9, a}))) << "group 1 is next";
  ASSERT_TRUE(db->appendPrompt("prompt", record(1, Database::NewIov{5, 9, a})));
  const Status gap = db->appendPrompt("prompt", record(2, Database::NewIov{11, 20, b}));
  ASSERT_FALSE(gap);
  EXPECT_NE(gap.error().message.find("right after its last IOV"), std::string::npos) << gap.error().message;
  ASSERT_TRUE(db->appendPrompt("prompt", record(2, Database::NewIov{10, 20, b})));
  auto records = open()->promptRecords("prompt");
  ASSERT_TRUE(records) << records.error().message;
  ASSERT_EQ(records->size(), 3U);
  EXPECT_EQ((*records)[2], R"({"group":2})");
  auto kept = db->thresholds("abc");
  ASSERT_TRUE(kept && kept->has_value());
  EXPECT_EQ(**kept, R"({"t":1})");
  EXPECT_FALSE(db->appendPrompt("offline", record(0, std::nullopt))) << "not a running tag";

  // put: only after the last IOV.
  const Status before = db->put("prompt", 15, 30, a, IfMissing::Refuse);
  ASSERT_FALSE(before);
  EXPECT_NE(before.error().message.find("only appended"), std::string::npos) << before.error().message;
  EXPECT_TRUE(db->put("prompt", 25, 30, a, IfMissing::Refuse));
  auto iovs = db->iovs("prompt");
  ASSERT_TRUE(iovs);
  EXPECT_EQ(iovs->size(), 3U);
  // Locked, it is published: nothing appended any more.
  ASSERT_TRUE(db->lock("prompt"));
  EXPECT_EQ((*db->tag("prompt"))->state, TagState::Published);
  EXPECT_FALSE(db->appendPrompt("prompt", record(3, Database::NewIov{31, 40, a})));
}

TEST_P(Conditions, OpenChecksTheSchema) {
  auto fresh = Database::open(uri_);  // no emcalign tables yet (PostgreSQL) or no file (SQLite)
  ASSERT_FALSE(fresh);
  EXPECT_NE(fresh.error().message.find("conditions init"), std::string::npos) << fresh.error().message;
  {
    auto db = create();
    ASSERT_TRUE(db->init());  // idempotent
  }
  auto again = Database::open(uri_);
  ASSERT_TRUE(again) << again.error().message;
  // A database of another schema version is refused, not misread.
  auto db = create();
  {
    // Reach into the table the way a future emcalign would have changed it.
    if (GetParam() == "sqlite") {
      const std::string cmd = fmt::format(
          "sqlite3 '{}' \"UPDATE emcalign_meta SET value = '99' WHERE key = "
          "'schema_version'\"",
          uri_.substr(7));
      ASSERT_EQ(std::system(cmd.c_str()), 0);
    } else {
      pqxx::connection c(uri_);
      pqxx::work w(c);
      w.exec("UPDATE emcalign_meta SET value = '99' WHERE key = 'schema_version'");
      w.commit();
    }
  }
  auto future = Database::open(uri_);
  ASSERT_FALSE(future);
  EXPECT_NE(future.error().message.find("schema version 99"), std::string::npos) << future.error().message;
}

// Writers in parallel, each with its own connection: none is lost, and of writers racing for
// the same runs exactly one wins.
TEST_P(Conditions, ConcurrentWritersLoseNothing) {
  create();
  constexpr int kWriters = 6, kEach = 10;
  std::vector<std::thread> threads;
  std::atomic<int> failures{0}, raceWins{0};
  for (int w = 0; w < kWriters; ++w) {
    threads.emplace_back([&, w] {
      auto db = Database::open(uri_);
      if (!db) {
        ++failures;
        return;
      }
      for (int k = 0; k < kEach; ++k) {
        const int first = 1000 * w + 10 * k;
        // Each writer creates the tag if it is first; payloads shared between writers.
        if (!(*db)->put("shared", first, first + 9, payloadOf(2.0 + 0.1 * k), IfMissing::Create)) ++failures;
        if ((*db)->put("race", k * 10, k * 10 + 5, payloadOf(3.0 + w), IfMissing::Create)) ++raceWins;
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(raceWins.load(), kEach);  // each contested range went to exactly one writer
  auto db = open();
  auto iovs = db->iovs("shared");
  ASSERT_TRUE(iovs);
  EXPECT_EQ(iovs->size(), static_cast<std::size_t>(kWriters * kEach));
  auto race = db->iovs("race");
  ASSERT_TRUE(race);
  EXPECT_EQ(race->size(), static_cast<std::size_t>(kEach));
}

// A writer killed with SIGKILL in the middle of its transaction (everything written, nothing
// committed): the database stays readable, the write is absent, the next writer gets through.
TEST_P(Conditions, KillDuringWriteLeavesItConsistent) {
  create();
  {
    auto db = open();
    ASSERT_TRUE(db->put("k", 1, 10, payloadOf(2.8), IfMissing::Create));
  }
  const fs::path marker = fs::temp_directory_path() / fmt::format("emcalign-hold-{}-{}", ::getpid(), counter_++);
  fs::remove(marker);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::setenv("EMCALIGN_FAULT_HOLD_WRITE", marker.c_str(), 1);
    auto db = Database::open(uri_);
    if (!db) ::_exit(10);
    (void)(*db)->put("k", 11, 20, payloadOf(3.3), IfMissing::Refuse);
    ::_exit(11);  // not reached: killed while holding the write
  }
  const auto start = std::chrono::steady_clock::now();
  while (!fs::exists(marker) && std::chrono::steady_clock::now() - start < std::chrono::seconds(30)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(fs::exists(marker)) << "the writer never reached its commit";
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status));
  fs::remove(marker);

  auto db = open();
  auto iovs = db->iovs("k");
  ASSERT_TRUE(iovs) << iovs.error().message;
  ASSERT_EQ(iovs->size(), 1U);
  EXPECT_FALSE(db->payload(payloadOf(3.3).hash()));                      // its payload went with it
  ASSERT_TRUE(db->put("k", 11, 20, payloadOf(3.4), IfMissing::Refuse));  // no lock left behind
  auto got = db->get("k", 15);
  ASSERT_TRUE(got && got->has_value());
}

// Raw SQL on the database behind the tool's back (a hand edit, a hostile one).
void editByHand(const std::string& uri, const std::string& sql) {
  if (uri.rfind("sqlite:", 0) == 0) {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(uri.substr(7).c_str(), &db), SQLITE_OK);
    char* message = nullptr;
    const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &message);
    EXPECT_EQ(rc, SQLITE_OK) << (message != nullptr ? message : "");
    sqlite3_free(message);
    sqlite3_close(db);
  } else {
    pqxx::connection c(uri);
    pqxx::work tx(c);
    tx.exec(sql);
    tx.commit();
  }
}

TEST_P(Conditions, AnEditedPayloadIsNeverServed) {
  auto db = create();
  const Payload a = payloadOf(2.8);
  ASSERT_TRUE(db->put("t", 1, 10, a, IfMissing::Create));
  editByHand(uri_, "UPDATE emcalign_payloads SET content = replace(content, '\"alpha\":', '\"alpha\":1')");
  auto got = db->get("t", 5);
  ASSERT_FALSE(got);
  EXPECT_THAT(got.error().message, ::testing::HasSubstr("no longer has that hash"));
  EXPECT_FALSE(db->payload(a.hash()));
  auto snapshot = TagSnapshot::load(*db, "t");
  ASSERT_TRUE(snapshot);
  EXPECT_FALSE(snapshot->at(5));
}

TEST_P(Conditions, TextWithNulIsRefusedNotCut) {
  auto db = create();
  ASSERT_TRUE(db->put("base", 1, 10, payloadOf(2.8), IfMissing::Create));
  const std::string nul("base\0x", 6);
  EXPECT_FALSE(db->lock(nul));
  auto tag = db->tag("base");
  ASSERT_TRUE(tag && tag->has_value());
  EXPECT_EQ((*tag)->state, TagState::Open) << "a lock of 'base\\0x' locked 'base'";
  EXPECT_FALSE(db->tag(nul));
  EXPECT_FALSE(db->iovs(nul));
  EXPECT_FALSE(db->get(nul, 1));
  Status described = db->put("other", 1, 10, payloadOf(2.8), IfMissing::Create, std::string("before\0after", 12));
  ASSERT_FALSE(described);
  EXPECT_THAT(described.error().message, ::testing::HasSubstr("NUL"));
}

// A job that writes a whole tag (trend --refit) and is run again, or twice at once, stores it
// once; a tag of other calibrations is never added to.
TEST_P(Conditions, AWholeTagIsWrittenOnceAndNeverOverAnother) {
  auto db = create();
  const std::vector<Database::NewIov> iovs = {{1, 10, payloadOf(2.8)}, {11, 30, payloadOf(2.9)}};
  auto first = putWholeTag(*db, "refit", iovs, "by period");
  ASSERT_TRUE(first) << first.error().message;
  EXPECT_EQ(*first, WholeTagPut::Stored);
  auto again = putWholeTag(*open(), "refit", iovs, "by period");
  ASSERT_TRUE(again) << again.error().message;
  EXPECT_EQ(*again, WholeTagPut::HeldAlready);
  auto stored = db->iovs("refit");
  ASSERT_TRUE(stored);
  EXPECT_EQ(stored->size(), 2u);

  const std::vector<Database::NewIov> other = {{1, 10, payloadOf(2.8)}, {11, 30, payloadOf(3.0)}};
  auto refused = putWholeTag(*db, "refit", other, "by period");
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("exists already"), std::string::npos) << refused.error().message;
  const std::vector<Database::NewIov> more = {{31, 40, payloadOf(2.8)}};
  EXPECT_FALSE(putWholeTag(*db, "refit", more, "")) << "not appended to a tag that holds other IOVs";
  stored = db->iovs("refit");
  ASSERT_TRUE(stored);
  EXPECT_EQ(stored->size(), 2u) << "nothing added";
}

INSTANTIATE_TEST_SUITE_P(Backends, Conditions, ::testing::Values("sqlite", "postgres"),
                         [](const auto& instance) { return instance.param; });

TEST(ConditionsUri, RefusesWhatIsNotADatabase) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("emcalign-conddb-uri-{}", ::getpid());
  fs::create_directories(dir);
  { std::ofstream(dir / "text.db") << "not a database at all, just text that is long enough to look like a file\n"; }
  auto text = Database::open((dir / "text.db").string());
  ASSERT_FALSE(text);
  EXPECT_NE(text.error().message.find("text.db"), std::string::npos) << text.error().message;
  auto missing = Database::open("sqlite:" + (dir / "missing.db").string());
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("no such database"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "missing.db"));  // opening does not create
  auto directory = Database::open(dir.string(), IfMissing::Create);
  ASSERT_FALSE(directory);
  EXPECT_NE(directory.error().message.find("not a regular file"), std::string::npos);
  auto scheme = Database::open("mysql://me@host/db");
  ASSERT_FALSE(scheme);
  EXPECT_NE(scheme.error().message.find("unknown database scheme"), std::string::npos);
  auto nobody = Database::open("postgresql://nobody:secret@127.0.0.1:1/none");
  ASSERT_FALSE(nobody);
  EXPECT_NE(nobody.error().message.find("cannot connect"), std::string::npos);
  EXPECT_EQ(nobody.error().message.find("secret"), std::string::npos) << "a password in a message";
  fs::remove_all(dir);
}

TEST(ConditionsSqlite, TextThatIsNotUtf8OrHoldsEscapesIsReadPrintable) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("emcalign-conddb-text-{}", ::getpid());
  fs::create_directories(dir);
  const std::string uri = "sqlite:" + (dir / "c.db").string();
  auto db = Database::open(uri, IfMissing::Create);
  ASSERT_TRUE(db) << db.error().message;
  ASSERT_TRUE((*db)->put("t", 1, 10, payloadOf(2.8), IfMissing::Create, "plain"));
  editByHand(uri, "UPDATE emcalign_tags SET description = CAST(X'6E616976E91B5B324A' AS TEXT)");
  auto tag = (*db)->tag("t");
  ASSERT_TRUE(tag && tag->has_value());
  EXPECT_EQ((*tag)->description, "naiv\\xe9\\x1b[2J");
  fs::remove_all(dir);
}

TEST(ConditionsPostgres, ATagAnotherClientHoldsIsBusyAfterTheLockTimeout) {
  const std::string uri = testing::freshPostgresDatabase();
  auto db = Database::open(uri, IfMissing::Create);
  ASSERT_TRUE(db) << db.error().message;
  ASSERT_TRUE((*db)->put("held", 1, 10, payloadOf(2.8), IfMissing::Create));
  // Another client holds the tag's row.
  pqxx::connection other(uri);
  pqxx::work holding(other);
  holding.exec("SELECT state FROM emcalign_tags WHERE name = 'held' FOR UPDATE");
  ::setenv("PGOPTIONS", "-c lock_timeout=1s", 1);
  auto writer = Database::open(uri);
  ::unsetenv("PGOPTIONS");
  ASSERT_TRUE(writer) << writer.error().message;
  const auto started = std::chrono::steady_clock::now();
  Status s = (*writer)->put("held", 11, 20, payloadOf(2.9), IfMissing::Refuse);
  const auto waited = std::chrono::steady_clock::now() - started;
  ASSERT_FALSE(s);
  EXPECT_THAT(s.error().message, ::testing::HasSubstr("tag 'held'"));
  EXPECT_THAT(s.error().message, ::testing::HasSubstr("busy"));
  EXPECT_LT(waited, std::chrono::seconds(10));
  holding.abort();
  // Free again: the same write goes through.
  EXPECT_TRUE((*writer)->put("held", 11, 20, payloadOf(2.9), IfMissing::Refuse));
}

TEST(ConditionsPayload, KeepsTheFitAndRefusesUnusableOnes) {
  Json fit = io::alignmentToJson(geometry::testing::paperLike());
  fit["status"] = "converged";
  fit["chi2"] = 150.0;
  fit["ndf"] = 148;
  fit["input"] = {{"files", {"run1.h5"}}, {"cut_flow", {{"all", 1000}, {"selected", 800}}}};
  auto p = makePayload(fit, r1(), "fit.json", Json{{"time", "now"}});
  ASSERT_TRUE(p) << p.error().message;
  EXPECT_EQ(p->content["format"], "emcalign-payload/1");
  EXPECT_EQ(p->content["selected_events"], 800);
  EXPECT_EQ(p->content["alignment"]["chi2"], 150.0);
  EXPECT_EQ(p->content["provenance"]["inputs"][0], "run1.h5");
  EXPECT_EQ(p->hash(), sha256(p->content.dump()));
  // The same content is the same hash; any change is another.
  auto q = makePayload(fit, r1(), "fit.json", Json{{"time", "now"}});
  ASSERT_TRUE(q);
  EXPECT_EQ(p->hash(), q->hash());
  fit["chi2"] = 151.0;
  EXPECT_NE(makePayload(fit, r1(), "fit.json", Json{{"time", "now"}})->hash(), p->hash());

  fit["status"] = "not converged";
  auto bad = makePayload(fit, r1(), "fit.json");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("fit.json"), std::string::npos);
}

// What a payload says is read back by its own readers, in file units; what it does not say,
// or not as makePayload writes it, reads as absent (NaN, empty, the paper's σ_sys) — never a throw.
TEST(ConditionsPayload, ItsReadersGiveBackWhatWasStoredAndNothingElse) {
  auto eta = geometry::testing::paperLike();
  Json fit = io::alignmentToJson(eta);
  fit["status"] = "converged";
  fit["errors"] = Json::object();
  for (Param p : kAllParams) fit["errors"][std::string(name(p))] = 0.01 * (1.0 + static_cast<double>(index(p)));
  fit["derived"] = {{"beta", {{"value", 0.5}, {"error", 0.1}}}, {"psi", {{"value", 170.0}, {"error", nullptr}}}};
  fit["sigma_sys"] = {{"method", "fixed"}, {"value_deg", 0.4}};
  auto p = makePayload(fit, r1(), "fit.json",
                       Json{{"input_sha256", {{"b.h5", "bb"}, {"a.h5", "aa"}, {"c.h5", 3}}},
                            {"corrections", "grid/"},
                            {"corrections_sha256", "cc"}});
  ASSERT_TRUE(p) << p.error().message;
  const StoredValues v = p->values();
  for (Param q : kAllParams) {
    EXPECT_NEAR(v[index(q)].value, eta[q] / geometry::AlignmentParameters::fileUnit(q), 1e-9) << name(q);
    EXPECT_DOUBLE_EQ(v[index(q)].error, 0.01 * (1.0 + static_cast<double>(index(q)))) << name(q);
  }
  EXPECT_DOUBLE_EQ(v[kNumParams + 0].value, 0.5);  // β
  EXPECT_DOUBLE_EQ(v[kNumParams + 0].error, 0.1);
  EXPECT_DOUBLE_EQ(v[kNumParams + 1].value, 170.0);  // ψ, its error null
  EXPECT_TRUE(std::isnan(v[kNumParams + 1].error));
  EXPECT_TRUE(std::isnan(v[kNumParams + 2].value));  // μ: not stored
  // Digests in the order stored; one that is not text is no digest.
  EXPECT_EQ(p->inputDigests(), (std::vector<std::pair<std::string, std::string>>{{"b.h5", "bb"}, {"a.h5", "aa"}}));
  EXPECT_EQ(p->correctionsFile(), "grid/");
  EXPECT_EQ(p->correctionsSha256(), "cc");
  const calib::ModelIdentity grid = p->modelIdentity();
  EXPECT_EQ(grid.kind, calib::ModelIdentity::Kind::Corrections);
  EXPECT_EQ(grid.correctionsSha256, "cc");
  EXPECT_EQ(grid.text(), "corrections grid/");
  ASSERT_TRUE(grid.sigmaSys);
  EXPECT_EQ(grid.textWithSigmaSys(), "corrections grid/; sigma_sys 0.4 deg");
  EXPECT_FALSE(p->depthOffsetCm());  // its fit's model corrections not recorded
  Payload shifted = *p;
  shifted.content["provenance"].erase("corrections");
  shifted.content["provenance"]["model_corrections"] = {{"depth_offset_cm", 1.5}};
  EXPECT_EQ(shifted.depthOffsetCm(), 1.5);
  EXPECT_EQ(shifted.modelIdentity().text(), "the paper's model, depth offset +1.5 cm");
  EXPECT_EQ(shifted.modelIdentity().brief(), "paper's model");
  EXPECT_FALSE(shifted.modelIdentity().sameModel(grid));
  shifted.content["provenance"]["model_corrections"] = Json::object();
  EXPECT_EQ(shifted.depthOffsetCm(), 0.0);
  EXPECT_EQ(shifted.modelIdentity().text(), "the paper's model");
  EXPECT_TRUE(shifted.modelIdentity().isPaper());
  auto sigma = p->sigmaSysChoice();
  ASSERT_TRUE(sigma) << sigma.error().message;
  EXPECT_EQ(sigma->method, calib::SigmaSysMethod::Fixed);
  EXPECT_NEAR(sigma->value, 0.4 * units::deg, 1e-12);

  // A payload made before σ_sys was recorded was fitted with the paper's; one recording a
  // choice no fit makes is an error naming it.
  Payload old = *p;
  old.content["alignment"].erase("sigma_sys");
  ASSERT_TRUE(old.sigmaSysChoice());
  EXPECT_EQ(old.sigmaSysChoice()->method, calib::SigmaSysMethod::Spec);
  Payload odd = *p;
  odd.content["alignment"]["sigma_sys"] = {{"method", "guess"}};
  ASSERT_FALSE(odd.sigmaSysChoice());
  EXPECT_THAT(odd.sigmaSysChoice().error().message, ::testing::HasSubstr("guess"));

  // Anything else a database may hold reads as nothing said.
  for (const Json& content : {Json(), Json::array(), Json{{"alignment", 3}, {"provenance", "x"}},
                              Json{{"alignment", {{"parameters", {{"alpha", "1"}}}, {"errors", nullptr}}}}}) {
    const Payload junk{content};
    for (const StoredValue& s : junk.values()) {
      EXPECT_TRUE(std::isnan(s.value) && std::isnan(s.error)) << content.dump();
    }
    EXPECT_TRUE(junk.inputDigests().empty());
    EXPECT_EQ(junk.correctionsFile(), "");
    EXPECT_EQ(junk.correctionsSha256(), "");
    EXPECT_FALSE(junk.depthOffsetCm());
    EXPECT_EQ(junk.modelIdentity().kind, calib::ModelIdentity::Kind::Unsaid);
    EXPECT_EQ(junk.modelIdentity().text(), "");
    ASSERT_TRUE(junk.sigmaSysChoice()) << content.dump();
    EXPECT_EQ(junk.sigmaSysChoice()->method, calib::SigmaSysMethod::Spec);
  }
}

}  // namespace
}  // namespace emcalign::conddb
