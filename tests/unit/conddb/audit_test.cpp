// Conditions you can audit (docs/contract.md §13), on both back ends: the tag states and their transitions,
// writes by state, promotion into a running tag, history, snapshots, and the upgrade of a
// database made by schema 1 (tests/fixtures/conditions-schema1.db, made by the release before).

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <map>
#include <thread>

#include <fmt/ranges.h>

#include <pqxx/pqxx>

#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/conddb/tag_tables.hpp"
#include "emcalign/core/clock.hpp"
#include "emcalign/geometry/detector.hpp"
#include "postgres_support.hpp"
#include "test_support.hpp"

namespace emcalign::conddb {
namespace {

namespace fs = std::filesystem;
using io::Json;

Payload payloadOf(double alpha) {
  auto eta = geometry::testing::paperLike();
  eta[Param::Alpha] = alpha * units::deg;
  auto p = makePayload(io::alignmentToJson(eta), geometry::DetectorDescription::sndDefault().r1(), "test",
                       Json{{"note", "audit test"}});
  EXPECT_TRUE(p) << p.error().message;
  return *p;
}

class Audit : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam() == "sqlite") {
      dir_ = fs::temp_directory_path() / fmt::format("emcalign-audit-{}-{}", ::getpid(), counter_++);
      fs::create_directories(dir_);
      uri_ = "sqlite:" + (dir_ / "c.db").string();
    } else {
      uri_ = testing::freshPostgresDatabase();
    }
    auto db = Database::open(uri_, IfMissing::Create);
    ASSERT_TRUE(db) << db.error().message;
    db_ = std::move(*db);
  }
  void TearDown() override {
    db_.reset();
    if (!dir_.empty()) fs::remove_all(dir_);
  }

  // A tag with runs 1-10 and 11-20, brought to `state` along allowed transitions.
  void makeTag(const std::string& name, TagState state) {
    ASSERT_TRUE(db_->put(name, {{1, 10, a_}, {11, 20, b_}}, IfMissing::Create, "audit"));
    std::vector<TagState> path;
    if (state == TagState::Testing || state == TagState::Validated) path.push_back(TagState::Testing);
    if (state != TagState::Open && state != TagState::Testing) path.push_back(state);
    for (TagState s : path) ASSERT_TRUE(db_->setState(name, s, "on the way")) << name;
    ASSERT_EQ((*db_->tag(name))->state, state);
  }

  // Everything a refusal must leave as it was: the state, the IOVs, the history.
  std::string fingerprint(const std::string& tag) {
    auto t = db_->tag(tag);
    auto iovs = db_->iovs(tag);
    auto history = db_->history(tag);
    EXPECT_TRUE(t && iovs && history);
    std::string out = std::string(name((*t)->state));
    for (const Iov& i : *iovs) out += fmt::format(" {}-{}:{}@{}", i.firstRun, i.lastRun, i.payload, i.inserted);
    for (const Change& c : *history) {
      out.push_back(' ');
      out.append(c.json().dump());
    }
    return out;
  }

  static inline int counter_ = 0;
  fs::path dir_;
  std::string uri_;
  std::unique_ptr<Database> db_;
  const Payload a_ = payloadOf(2.8), b_ = payloadOf(2.9), c_ = payloadOf(3.0);
};

// Every pair of states: allowed exactly as the table says; a refusal writes nothing.
TEST_P(Audit, TransitionsAreTheTablesAndARefusalWritesNothing) {
  int tag = 0;
  for (TagState from : kAllTagStates) {
    for (TagState to : kAllTagStates) {
      const std::string name = fmt::format("t{}", tag++);
      makeTag(name, from);
      const std::string before = fingerprint(name);
      auto r = db_->setState(name, to, "why");
      if (from == to) {
        // The same state again: nothing changes (a retry); invalid with another reason is refused.
        EXPECT_TRUE(r || to == TagState::Invalid) << conddb::name(from);
        EXPECT_EQ(fingerprint(name), before);
        continue;
      }
      const bool allowed = transitionAllowed(from, to);
      EXPECT_EQ(static_cast<bool>(r), allowed) << conddb::name(from) << " -> " << conddb::name(to);
      if (allowed) {
        EXPECT_EQ(*r, Database::StateChange::Changed);
        EXPECT_EQ((*db_->tag(name))->state, to);
        auto h = db_->history(name);
        ASSERT_TRUE(h);
        EXPECT_EQ(h->back().change, "state");
        EXPECT_EQ(h->back().details["from"], conddb::name(from));
        EXPECT_EQ(h->back().details["to"], conddb::name(to));
        EXPECT_EQ(h->back().details["reason"], "why");
      } else {
        EXPECT_NE(r.error().message.find("cannot become"), std::string::npos) << r.error().message;
        EXPECT_EQ(fingerprint(name), before) << conddb::name(from) << " -> " << conddb::name(to);
      }
    }
  }
  // docs/contract.md §13's table, spelt out once more against tag_states.cpp.
  const auto allowed = [](TagState f) {
    std::string out;
    for (TagState t : transitionsFrom(f)) out += std::string(name(t)) + " ";
    return out;
  };
  EXPECT_EQ(allowed(TagState::Open), "testing running published invalid ");
  EXPECT_EQ(allowed(TagState::Testing), "open validated invalid ");
  EXPECT_EQ(allowed(TagState::Validated), "published running invalid ");
  EXPECT_EQ(allowed(TagState::Running), "published invalid ");
  EXPECT_EQ(allowed(TagState::Published), "");
  EXPECT_EQ(allowed(TagState::Invalid), "");
}

TEST_P(Audit, WritesFollowTheState) {
  for (TagState s : kAllTagStates) {
    const std::string name = fmt::format("w-{}", conddb::name(s));
    makeTag(name, s);
    const std::string before = fingerprint(name);
    const Status after = db_->put(name, 21, 30, c_, IfMissing::Refuse);
    const Status inside = db_->put(name, 5, 5, c_, IfMissing::Refuse);  // overlaps in any case
    EXPECT_FALSE(inside);
    EXPECT_EQ(static_cast<bool>(after), s == TagState::Open || s == TagState::Running) << conddb::name(s);
    if (!after) {
      EXPECT_NE(after.error().message.find(fmt::format("is {}", conddb::name(s))), std::string::npos)
          << after.error().message;
      EXPECT_EQ(fingerprint(name), before);
    }
  }
  // Running: only after the last IOV, even into a gap before it.
  ASSERT_TRUE(db_->put("w-running", 40, 50, c_, IfMissing::Refuse));
  EXPECT_FALSE(db_->put("w-running", 31, 35, c_, IfMissing::Refuse));
  EXPECT_TRUE(db_->put("w-open", 31, 35, c_, IfMissing::Refuse));
  // Invalid: never served, whatever the snapshot.
  auto then = db_->lastChange("w-invalid");
  ASSERT_TRUE(then);
  EXPECT_FALSE(db_->get("w-invalid", 5));
  EXPECT_FALSE(db_->get("w-invalid", 5, *then));
  EXPECT_FALSE(calibrationAt(*db_, "w-invalid", 5, "2000-01-01T00:00:00.000000Z"));
  EXPECT_FALSE(TagSnapshot::load(*db_, "w-invalid", false, *then));
}

TEST_P(Audit, HistoryKeepsEveryChangeWithItsTimeAndWho) {
  ASSERT_TRUE(db_->put("h", 1, 10, a_, IfMissing::Create, "first"));
  ASSERT_TRUE(db_->put("h", {{11, 20, b_}, {21, 30, a_}}, IfMissing::Refuse));
  ASSERT_TRUE(db_->setState("h", TagState::Testing, "to look at"));
  ASSERT_TRUE(db_->setState("h", TagState::Open, ""));
  ASSERT_TRUE(db_->lock("h"));
  auto h = db_->history("h");
  ASSERT_TRUE(h) << h.error().message;
  std::vector<std::string> changes;
  for (const Change& c : *h) changes.push_back(c.change);
  EXPECT_EQ(changes, (std::vector<std::string>{"created", "iov", "iov", "iov", "state", "state", "state"}));
  for (std::size_t k = 0; k < h->size(); ++k) {
    const Change& c = (*h)[k];
    EXPECT_EQ(c.time.size(), 27U) << c.time;  // 2026-12-05T04:45:30.123456Z
    EXPECT_TRUE(utcMicrosOf(c.time)) << c.time;
    EXPECT_FALSE(c.user.empty());
    EXPECT_FALSE(c.host.empty());
    if (k > 0) {
      EXPECT_GE(c.time, (*h)[k - 1].time);
    }
    const Json j = c.json();
    EXPECT_EQ(j["time"], c.time);
    EXPECT_EQ(j["change"], c.change);
  }
  // The changes of one write share its time; the writes' times increase.
  EXPECT_EQ((*h)[2].time, (*h)[3].time);
  EXPECT_LT((*h)[1].time, (*h)[2].time);
  EXPECT_LT((*h)[4].time, (*h)[5].time);
  EXPECT_EQ((*h)[1].details["first_run"], 1);
  EXPECT_EQ((*h)[1].details["payload"], a_.hash());
  EXPECT_EQ((*h)[6].details["to"], "published");
  auto last = db_->lastChange("h");
  ASSERT_TRUE(last);
  EXPECT_EQ(*last, h->back().time);
  EXPECT_FALSE(db_->history("nope"));
  // A refused write adds no entry.
  EXPECT_FALSE(db_->put("h", 31, 40, a_, IfMissing::Refuse));
  EXPECT_FALSE(db_->setState("h", TagState::Open, ""));
  EXPECT_EQ(db_->history("h")->size(), h->size());
}

// docs/contract.md §13: S validated, R running, both with IOVs, S tiling the runs from N, N after the first
// run of R's last IOV; R's last IOV then ends at N - 1 (cut, extended or kept).
TEST_P(Audit, PromotionAppendsFromTheFirstSafeRunOrWritesNothing) {
  makeTag("R", TagState::Running);  // 1-10 a, 11-20 b
  ASSERT_TRUE(db_->put("S", {{15, 24, c_}, {25, 40, a_}}, IfMissing::Create));
  const std::string r0 = fingerprint("R");
  // Not validated yet.
  auto notValidated = db_->promote("S", "R", 15, false);
  ASSERT_FALSE(notValidated);
  EXPECT_NE(notValidated.error().message.find("only a validated tag is promoted"), std::string::npos);
  ASSERT_TRUE(db_->setState("S", TagState::Testing, ""));
  ASSERT_TRUE(db_->setState("S", TagState::Validated, ""));
  const std::string s0 = fingerprint("S");
  struct Refused {
    std::string from, to;
    std::int64_t n;
    std::string why;
  };
  makeTag("O", TagState::Open);
  makeTag("V2", TagState::Validated);  // 1-10, 11-20
  ASSERT_TRUE(db_->createTag({.name = "E", .description = "empty", .state = TagState::Running}).value());
  ASSERT_TRUE(db_->put("G", {{15, 20, c_}, {22, 30, a_}}, IfMissing::Create));
  ASSERT_TRUE(db_->setState("G", TagState::Testing, ""));
  ASSERT_TRUE(db_->setState("G", TagState::Validated, ""));
  const std::vector<Refused> refused = {
      {"S", "O", 15, "a promotion goes into a running tag"},
      {"S", "E", 15, "'E' has no IOV"},
      {"S", "R", 16, "not at the first safe run 16"},
      {"S", "R", 14, "not at the first safe run 14"},
      {"V2", "R", 1, "starts at or after it"},
      {"G", "R", 15, "leave a gap (runs 21-21)"},
      {"S", "S", 15, "not promoted into itself"},
      {"S", "nope", 15, "there is no tag 'nope'"},
  };
  for (const Refused& x : refused) {
    for (bool dry : {false, true}) {
      auto p = db_->promote(x.from, x.to, x.n, dry);
      ASSERT_FALSE(p) << x.why;
      EXPECT_NE(p.error().message.find(x.why), std::string::npos) << p.error().message;
      EXPECT_NE(p.error().message.find("nothing written"), std::string::npos);
    }
  }
  EXPECT_EQ(fingerprint("R"), r0);
  EXPECT_EQ(fingerprint("S"), s0);

  // A dry run answers and writes nothing.
  auto dry = db_->promote("S", "R", 15, true);
  ASSERT_TRUE(dry) << dry.error().message;
  EXPECT_EQ(dry->lastIovFate(), "cut");
  EXPECT_EQ(dry->appended.size(), 2U);
  EXPECT_TRUE(dry->time.empty());
  EXPECT_EQ(fingerprint("R"), r0);
  const std::string before = *db_->lastChange("R");

  auto p = db_->promote("S", "R", 15, false);
  ASSERT_TRUE(p) << p.error().message;
  EXPECT_EQ(p->lastBefore.firstRun, 11);
  EXPECT_EQ(p->lastBefore.lastRun, 20);
  auto iovs = db_->iovs("R");
  ASSERT_TRUE(iovs);
  ASSERT_EQ(iovs->size(), 4U);
  EXPECT_EQ((*iovs)[1].firstRun, 11);
  EXPECT_EQ((*iovs)[1].lastRun, 14);  // cut
  EXPECT_EQ((*iovs)[1].payload, b_.hash());
  EXPECT_EQ((*iovs)[2].firstRun, 15);
  EXPECT_EQ((*iovs)[3].lastRun, 40);
  EXPECT_EQ((*db_->tag("S"))->state, TagState::Validated);  // S keeps its state
  EXPECT_EQ(fingerprint("S"), s0);
  auto h = db_->history("R");
  ASSERT_TRUE(h);
  EXPECT_EQ(h->back().change, "promotion");
  EXPECT_EQ(h->back().details["from"], "S");
  EXPECT_EQ(h->back().details["first_safe_run"], 15);
  EXPECT_EQ(h->back().time, p->time);
  // The IOV cut is seen as it was before.
  auto then = db_->iovs("R", before);
  ASSERT_TRUE(then);
  ASSERT_EQ(then->size(), 2U);
  EXPECT_EQ((*then)[1].lastRun, 20);
  auto was = db_->get("R", 18, before);
  ASSERT_TRUE(was && was->has_value());
  EXPECT_EQ((*was)->first.payload, b_.hash());
  auto now = db_->get("R", 18);
  ASSERT_TRUE(now && now->has_value());
  EXPECT_EQ((*now)->first.payload, c_.hash());

  // Extended: a validated tag starting after a gap; the running tag's last IOV reaches it.
  ASSERT_TRUE(db_->put("S2", 50, 60, b_, IfMissing::Create));
  ASSERT_TRUE(db_->setState("S2", TagState::Testing, ""));
  ASSERT_TRUE(db_->setState("S2", TagState::Validated, ""));
  auto e = db_->promote("S2", "R", 50, false);
  ASSERT_TRUE(e) << e.error().message;
  EXPECT_EQ(e->lastIovFate(), "extended");
  iovs = db_->iovs("R");
  EXPECT_EQ((*iovs)[3].firstRun, 25);
  EXPECT_EQ((*iovs)[3].lastRun, 49);
  // Appended after: a prompt loop's next IOV starts after the promoted ones.
  EXPECT_FALSE(db_->put("R", 55, 70, a_, IfMissing::Refuse));
  EXPECT_TRUE(db_->put("R", 61, 70, a_, IfMissing::Refuse));
}

// A promotion and a prompt loop appending to the same running tag at the same time: each waits
// for the other; the tag's IOVs tile the runs in the end, nothing lost.
TEST_P(Audit, PromotionIsSerialisedAgainstPromptAppends) {
  ASSERT_TRUE(db_->makeRunning("R", "prompt"));
  std::atomic<bool> done{false};
  std::atomic<int> appended{0};
  std::thread prompt([&] {
    auto opened = Database::open(uri_);
    ASSERT_TRUE(opened) << opened.error().message;
    Database& db = **opened;
    for (int g = 0; g < 60; ++g) {
      const std::int64_t first = 10LL * g, last = first + 9;
      // As the loop does: the IOV from the run after the tag's last one, if the group's runs
      // go beyond it.
      for (int attempt = 0; attempt < 100; ++attempt) {
        auto iovs = db.iovs("R");
        ASSERT_TRUE(iovs);
        const std::int64_t from = iovs->empty() ? first : iovs->back().lastRun + 1;
        std::optional<Database::NewIov> iov;
        if (last >= from) iov = Database::NewIov{from, last, g % 2 == 0 ? a_ : b_};
        if (db.appendPrompt("R", {g, Json{{"group", g}}.dump(), iov, "t", "{}"})) {
          ++appended;
          break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(3));  // runs arriving
    }
    done = true;
  });
  int promoted = 0;
  for (int k = 0; !done && k < 2000; ++k) {
    auto iovs = db_->iovs("R");
    ASSERT_TRUE(iovs);
    if (iovs->empty()) continue;
    const std::int64_t n = iovs->back().firstRun + 3;
    const std::string s = fmt::format("S{}", k);
    ASSERT_TRUE(db_->put(s, n, n + 4, c_, IfMissing::Create));
    ASSERT_TRUE(db_->setState(s, TagState::Testing, ""));
    ASSERT_TRUE(db_->setState(s, TagState::Validated, ""));
    if (db_->promote(s, "R", n, false)) ++promoted;
  }
  prompt.join();
  EXPECT_EQ(appended.load(), 60);
  EXPECT_GT(promoted, 0);
  auto iovs = db_->iovs("R");
  ASSERT_TRUE(iovs) << iovs.error().message;  // iovs() refuses overlaps
  for (std::size_t k = 1; k < iovs->size(); ++k) EXPECT_EQ((*iovs)[k].firstRun, (*iovs)[k - 1].lastRun + 1);
  EXPECT_EQ(iovs->front().firstRun, 0);
  auto records = db_->promptRecords("R");
  ASSERT_TRUE(records);
  EXPECT_EQ(records->size(), 60U);
  auto h = db_->history("R");
  ASSERT_TRUE(h);
  for (std::size_t k = 1; k < h->size(); ++k) EXPECT_GE((*h)[k].time, (*h)[k - 1].time);
}

TEST_P(Audit, SnapshotsAnswerAsTheDatabaseWas) {
  ASSERT_TRUE(db_->put("x", 1, 10, a_, IfMissing::Create, "x"));
  const std::string t1 = *db_->lastChange("x");
  ASSERT_TRUE(db_->put("x", 11, 20, b_, IfMissing::Refuse));
  ASSERT_TRUE(db_->setState("x", TagState::Published, ""));
  const std::string t2 = *db_->lastChange("x");
  ASSERT_TRUE(db_->put("y", 1, 5, c_, IfMissing::Create));

  auto tags1 = db_->tags(t1);
  ASSERT_TRUE(tags1);
  ASSERT_EQ(tags1->size(), 1U);  // y came later
  EXPECT_EQ(tags1->front().state, TagState::Open);
  EXPECT_EQ((*db_->tag("x", t2))->state, TagState::Published);
  EXPECT_FALSE(db_->tag("y", t2)->has_value());
  EXPECT_FALSE(db_->tag("x", "2000-01-01T00:00:00.000000Z")->has_value());
  EXPECT_EQ(db_->iovs("x", t1)->size(), 1U);
  EXPECT_EQ(db_->iovs("x", t2)->size(), 2U);
  EXPECT_FALSE(db_->get("x", 15, t1)->has_value());
  EXPECT_TRUE(db_->get("x", 15, t2)->has_value());
  auto listed = listTags(*db_, "", t1);
  ASSERT_TRUE(listed);
  EXPECT_EQ(tagJson(listed->front())["iovs"].size(), 1U);
  auto missing = listTags(*db_, "y", t1);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("did not exist at"), std::string::npos) << missing.error().message;
  auto csv = tagCsv(*db_, "x", t1);
  ASSERT_TRUE(csv);
  EXPECT_NE(csv->find("as it was at " + t1), std::string::npos);
  auto got = calibrationAt(*db_, "x", 5, t1);
  ASSERT_TRUE(got) << got.error().message;
  EXPECT_EQ(got->parameterFile["input"]["snapshot"], t1);
  // A snapshot is parsed from what people write, and rewritten to the microsecond.
  EXPECT_EQ(*parseSnapshot("2026-12-05T04:45:30Z"), "2026-12-05T04:45:30.000000Z");
  EXPECT_EQ(*parseSnapshot("2026-12-05 04:45:30.1234567+00:00"), "2026-12-05T04:45:30.123456Z");
  EXPECT_EQ(*parseSnapshot("2026-12-05T05:45:30+01:00"), "2026-12-05T04:45:30.000000Z");
  EXPECT_EQ(*parseSnapshot("2026-12-04T23:15:30-0530"), "2026-12-05T04:45:30.000000Z");
  EXPECT_FALSE(parseSnapshot("2026-12-05"));
  EXPECT_FALSE(parseSnapshot("2026-02-30T00:00:00Z"));
  EXPECT_EQ(*parseSnapshot("2026-12-05T04:45:30"), "2026-12-05T04:45:30.000000Z");  // no zone: UTC
  EXPECT_FALSE(parseSnapshot("2026-12-05T04:45:30+25:00"));

  // The database reads a snapshot as an instant, not as text: t1 written another way (no
  // fraction, an offset) gives the same answer; the second of t1, without its fraction,
  // comes before t1 (text comparison put "…SSZ" after "…SS.ffffffZ").
  const auto micros = utcMicrosOf(t1);
  ASSERT_TRUE(micros);
  if (*micros % 1000000 != 0) {
    std::string before = t1.substr(0, 19);  // the second t1 falls in, at .000000
    before.push_back('Z');
    EXPECT_FALSE(db_->tag("x", before)->has_value()) << "a snapshot at " << before << " saw the tag made at " << t1;
  }
  const std::string shifted = [&] {
    const UtcMicros t = *micros + std::int64_t{3600} * 1000000;  // t1 an hour later, written at +01:00
    std::string text = utcMicrosText(t);
    text.pop_back();  // its Z
    text.append("+01:00");
    return text;
  }();
  EXPECT_EQ(db_->iovs("x", shifted)->size(), 1U) << shifted;
  EXPECT_EQ((*db_->tag("x", shifted))->state, TagState::Open);
  EXPECT_FALSE(db_->iovs("x", "2026-12-05T04:45"));  // refused, not compared
}

INSTANTIATE_TEST_SUITE_P(Backends, Audit, ::testing::Values("sqlite", "postgres"),
                         [](const auto& instance) { return instance.param; });

// The database of the release before (schema 1) opens and is upgraded, once, in one
// transaction: on SQLite the fixture file itself, on PostgreSQL its rows in schema 1's tables.
class Upgrade : public ::testing::TestWithParam<std::string> {
 protected:
  static std::string fixture() { return std::string(EMCALIGN_SOURCE_DIR) + "/tests/fixtures/conditions-schema1.db"; }

  // Schema 1's tables on the server with the fixture's rows: its DDL as release 1 wrote it.
  static std::string schema1OnPostgres() {
    const std::string uri = testing::freshPostgresDatabase();
    pqxx::connection c(uri);
    pqxx::work tx(c);
    tx.exec("CREATE TABLE emcalign_meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)");
    tx.exec(
        "CREATE TABLE emcalign_tags (name TEXT PRIMARY KEY, description TEXT NOT NULL, state TEXT NOT NULL CHECK "
        "(state IN ('open', 'locked')), created TEXT NOT NULL)");
    tx.exec("CREATE TABLE emcalign_payloads (hash TEXT PRIMARY KEY, content TEXT NOT NULL)");
    tx.exec(
        "CREATE TABLE emcalign_iovs (tag TEXT NOT NULL REFERENCES emcalign_tags (name), first_run BIGINT NOT "
        "NULL, last_run BIGINT NOT NULL, payload TEXT NOT NULL REFERENCES emcalign_payloads (hash), inserted TEXT "
        "NOT NULL, PRIMARY KEY (tag, first_run), CHECK (first_run <= last_run))");
    tx.exec("CREATE INDEX emcalign_iovs_last ON emcalign_iovs (tag, last_run)");
    sqlite3* db = nullptr;
    EXPECT_EQ(sqlite3_open_v2(fixture().c_str(), &db, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
    for (const char* table : {"emcalign_meta", "emcalign_tags", "emcalign_payloads", "emcalign_iovs"}) {
      sqlite3_stmt* stmt = nullptr;
      EXPECT_EQ(sqlite3_prepare_v2(db, fmt::format("SELECT * FROM {}", table).c_str(), -1, &stmt, nullptr), SQLITE_OK);
      while (sqlite3_step(stmt) == SQLITE_ROW) {
        std::vector<std::string> values;
        for (int k = 0; k < sqlite3_column_count(stmt); ++k) {
          const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(stmt, k));
          values.push_back(fmt::format("'{}'", tx.esc(std::string(text != nullptr ? text : ""))));
        }
        tx.exec(fmt::format("INSERT INTO {} VALUES ({})", table, fmt::join(values, ", ")));
      }
      sqlite3_finalize(stmt);
    }
    sqlite3_close(db);
    tx.commit();
    return uri;
  }

  void SetUp() override {
    if (GetParam() == "sqlite") {
      dir_ = fs::temp_directory_path() / fmt::format("emcalign-upgrade-{}", ::getpid());
      fs::create_directories(dir_);
      fs::copy_file(fixture(), dir_ / "old.db", fs::copy_options::overwrite_existing);
      uri_ = "sqlite:" + (dir_ / "old.db").string();
    } else {
      uri_ = schema1OnPostgres();
    }
    Database::setNoticeHandler([this](const std::string& n) { notices_.push_back(n); });
  }
  void TearDown() override {
    Database::setNoticeHandler([](const std::string& n) { fmt::print(stderr, "emcalign: note: {}\n", n); });
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  fs::path dir_;
  std::string uri_;
  std::vector<std::string> notices_;
};

TEST_P(Upgrade, ADatabaseOfSchemaOneIsUpgradedOnceAndKeepsEverything) {
  {
    auto db = Database::open(uri_);
    ASSERT_TRUE(db) << db.error().message;
    ASSERT_EQ(notices_.size(), 1U);
    EXPECT_NE(notices_[0].find("upgraded from schema 1 to 2"), std::string::npos) << notices_[0];
    auto tags = (*db)->tags();
    ASSERT_TRUE(tags) << tags.error().message;
    std::map<std::string, TagState> states;
    for (const Tag& t : *tags) states[t.name] = t.state;
    EXPECT_EQ(states, (std::map<std::string, TagState>{{"locked-tag", TagState::Published},
                                                       {"open-tag", TagState::Open},
                                                       {"prompt-tag", TagState::Running},
                                                       {"retired-tag", TagState::Invalid}}));
    EXPECT_EQ((*(*db)->tag("retired-tag"))->reason, "the wrong runs");
    auto iovs = (*db)->iovs("open-tag");
    ASSERT_TRUE(iovs);
    ASSERT_EQ(iovs->size(), 2U);
    EXPECT_EQ((*iovs)[1].firstRun, 11);
    EXPECT_EQ((*iovs)[1].inserted, "2026-12-05T04:47:58.000000Z");
    EXPECT_FALSE((*db)->get("retired-tag", 5));
    auto got = (*db)->get("locked-tag", 5);
    ASSERT_TRUE(got && got->has_value());
    EXPECT_EQ((*got)->second.hash(), (*got)->first.payload);
    auto history = (*db)->history("prompt-tag");
    ASSERT_TRUE(history);
    std::vector<std::string> changes;
    for (const Change& c : *history) changes.push_back(c.change);
    EXPECT_EQ(changes, (std::vector<std::string>{"created", "state", "iov", "iov"}));
    auto records = (*db)->promptRecords("prompt-tag");
    ASSERT_TRUE(records);
    EXPECT_EQ(records->size(), 2U);  // a prompt loop goes on with its decisions
    // Snapshots of the times schema 1 kept.
    EXPECT_EQ((*db)->iovs("prompt-tag", "2026-12-05T04:47:59Z")->size(), 0U);
    EXPECT_EQ((*db)->iovs("prompt-tag", "2026-12-05T04:48:00.000000Z")->size(), 2U);
    // Written as any database of schema 2.
    EXPECT_TRUE((*db)->put("open-tag", 21, 30, (*got)->second, IfMissing::Refuse));
    EXPECT_FALSE((*db)->put("locked-tag", 21, 30, (*got)->second, IfMissing::Refuse));
  }
  auto again = Database::open(uri_);
  ASSERT_TRUE(again) << again.error().message;
  EXPECT_EQ(notices_.size(), 1U) << "said once";
  EXPECT_EQ((*again)->history("open-tag")->back().change, "iov");
}

INSTANTIATE_TEST_SUITE_P(Backends, Upgrade, ::testing::Values("sqlite", "postgres"),
                         [](const auto& instance) { return instance.param; });

}  // namespace
}  // namespace emcalign::conddb
