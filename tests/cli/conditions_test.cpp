// emcalign conditions, and --conditions of correct and simulate, against an SQLite file and
// the test suite's PostgreSQL server: the commands of docs/contract.md §11, writers in parallel
// processes, a writer killed with SIGKILL mid-write, copies between back ends.

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"
#include "emcalign/io/event_file.hpp"
#include "postgres_support.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kParams = R"({"format": "emcalign-alignment/1", "parameters": {"alpha": ALPHA, "beta1": 0.2,
  "beta2": -0.1, "dx": DX, "dy": -0.1, "dz": 0.2, "dp1": 0.6, "dp2": 0.2, "dp3": 0.4, "dy_rel": 0.05,
  "dz_rel": -0.05, "beta_rel": 0.1}})";

class ConditionsCli : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    dir_ = emcalign::testing::freshTestDirectory("emcalign_conditions_" + GetParam());
    uri_ = GetParam() == "sqlite" ? "sqlite:" + path("c.db") : emcalign::testing::freshPostgresDatabase();
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  emcalign::testing::CommandResult run(const std::string& args) const {
    return emcalign::testing::runEmcalign(dir_, args);
  }
  // A parameter file with these α (deg) and dx (cm).
  std::string params(const std::string& name, double alpha, double dx) const {
    std::string text = kParams;
    text.replace(text.find("ALPHA"), 5, fmt::format("{}", alpha));
    text.replace(text.find("DX"), 2, fmt::format("{}", dx));
    std::ofstream(path(name)) << text;
    return path(name);
  }
  fs::path dir_;
  std::string uri_;
};

TEST_P(ConditionsCli, InitPutGetListLock) {
  ASSERT_EQ(run("conditions init " + uri_).exitCode, 0);
  ASSERT_EQ(run("conditions init " + uri_).exitCode, 0);  // idempotent
  const std::string a = params("a.json", 2.8, 0.3), b = params("b.json", 2.9, 0.5);
  auto put = run(fmt::format("conditions put {} --tag calib.v1 --runs 1-40 {} --description 'period 1'", uri_, a));
  ASSERT_EQ(put.exitCode, 0) << put.err;
  EXPECT_NE(put.out.find("(new)"), std::string::npos) << put.out;
  ASSERT_EQ(run(fmt::format("conditions put {} --tag calib.v1 --runs 41-100 {}", uri_, b)).exitCode, 0);

  auto overlap = run(fmt::format("conditions put {} --tag calib.v1 --runs 100-120 {}", uri_, b));
  EXPECT_EQ(overlap.exitCode, 1);
  EXPECT_NE(overlap.err.find("overlap its IOV 41-100"), std::string::npos) << overlap.err;

  auto get = run(fmt::format("conditions get {} --tag calib.v1 --run 41 -o {}", uri_, path("got.json")));
  ASSERT_EQ(get.exitCode, 0) << get.err;
  const json got = json::parse(emcalign::testing::slurp(path("got.json")));
  EXPECT_DOUBLE_EQ(got["parameters"]["alpha"].get<double>(), 2.9);
  EXPECT_DOUBLE_EQ(got["parameters"]["dx"].get<double>(), 0.5);
  EXPECT_EQ(got["input"]["first_run"], 41);
  EXPECT_EQ(got["input"]["last_run"], 100);
  // The file it writes is an alignment every command reads.
  auto exported = run(fmt::format("export --alignment {} --format json -o {}", path("got.json"), path("p.json")));
  EXPECT_EQ(exported.exitCode, 0) << exported.err;

  auto none = run(fmt::format("conditions get {} --tag calib.v1 --run 101 -o {}", uri_, path("none.json")));
  EXPECT_EQ(none.exitCode, 1);
  EXPECT_NE(none.err.find("no IOV contains run 101"), std::string::npos) << none.err;
  EXPECT_FALSE(fs::exists(path("none.json")));

  auto list = run(fmt::format("conditions list {} --tag calib.v1 --json", uri_));
  ASSERT_EQ(list.exitCode, 0) << list.err;
  const json l = json::parse(list.out);
  EXPECT_EQ(l["tag"], "calib.v1");
  EXPECT_EQ(l["state"], "open");
  ASSERT_EQ(l["iovs"].size(), 2U);
  EXPECT_EQ(l["iovs"][0]["first_run"], 1);
  EXPECT_EQ(l["iovs"][0]["last_run"], 40);
  EXPECT_EQ(l["iovs"][1]["first_run"], 41);
  auto all = run(fmt::format("conditions list {} --json", uri_));
  ASSERT_EQ(all.exitCode, 0);
  EXPECT_EQ(json::parse(all.out).size(), 1U);
  auto text = run(fmt::format("conditions list {}", uri_));
  EXPECT_NE(text.out.find("calib.v1"), std::string::npos);
  EXPECT_NE(text.out.find("period 1"), std::string::npos);

  ASSERT_EQ(run(fmt::format("conditions lock {} --tag calib.v1", uri_)).exitCode, 0);
  auto locked = run(fmt::format("conditions put {} --tag calib.v1 --runs 200-300 {}", uri_, a));
  EXPECT_EQ(locked.exitCode, 1);
  EXPECT_NE(locked.err.find("is published"), std::string::npos) << locked.err;
  EXPECT_EQ(json::parse(run(fmt::format("conditions list {} --tag calib.v1 --json", uri_)).out)["state"], "published");

  // Misuse: a usage error, or a refusal naming the value.
  EXPECT_EQ(run(fmt::format("conditions put {} --tag 'a b' --runs 1-2 {}", uri_, a)).exitCode, 2);
  auto runs = run(fmt::format("conditions put {} --tag t --runs 5-2 {}", uri_, a));
  EXPECT_EQ(runs.exitCode, 1);
  EXPECT_NE(runs.err.find("--runs '5-2'"), std::string::npos) << runs.err;
  EXPECT_EQ(run(fmt::format("conditions put {} --tag t --runs x {}", uri_, a)).exitCode, 1);
  EXPECT_EQ(run(fmt::format("conditions get {} --tag nope --run 1 -o {}", uri_, path("n.json"))).exitCode, 1);
}

// Writers in parallel processes: disjoint ranges are all stored; of four racing for one
// range, one wins and three are refused.
TEST_P(ConditionsCli, ParallelWriters) {
  ASSERT_EQ(run("conditions init " + uri_).exitCode, 0);
  const std::string a = params("a.json", 2.8, 0.3);
  std::string script = "set -u\n";
  for (int i = 0; i < 8; ++i) {
    script += fmt::format("({} conditions put {} --tag par --runs {}-{} {} >/dev/null 2>&1; echo $? > {}) &\n",
                          EMCALIGN_BINARY, uri_, 10 * i + 1, 10 * i + 10,
                          params(fmt::format("p{}.json", i), 2 + i, 0.1), path(fmt::format("rc{}", i)));
  }
  for (int i = 0; i < 4; ++i) {
    script += fmt::format("({} conditions put {} --tag par --runs 500-510 {} >/dev/null 2>&1; echo $? > {}) &\n",
                          EMCALIGN_BINARY, uri_, a, path(fmt::format("race{}", i)));
  }
  script += "wait\n";
  std::ofstream(path("writers.sh")) << script;
  ASSERT_EQ(std::system(("bash " + path("writers.sh")).c_str()), 0);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(emcalign::testing::slurp(path(fmt::format("rc{}", i))), "0\n") << i;
  int wins = 0;
  for (int i = 0; i < 4; ++i) wins += emcalign::testing::slurp(path(fmt::format("race{}", i))) == "0\n";
  EXPECT_EQ(wins, 1);
  const json l = json::parse(run(fmt::format("conditions list {} --tag par --json", uri_)).out);
  ASSERT_EQ(l["iovs"].size(), 9U);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(l["iovs"][i]["first_run"], 10 * i + 1);
}

// `conditions put` killed with SIGKILL while it holds its write: nothing of it is stored, and
// the database takes the next write at once.
TEST_P(ConditionsCli, KilledWriter) {
  ASSERT_EQ(run("conditions init " + uri_).exitCode, 0);
  const std::string a = params("a.json", 2.8, 0.3), b = params("b.json", 3.1, 0.2);
  ASSERT_EQ(run(fmt::format("conditions put {} --tag k --runs 1-10 {}", uri_, a)).exitCode, 0);
  const std::string marker = path("holding");
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::setenv("EMCALIGN_FAULT_HOLD_WRITE", marker.c_str(), 1);
    const int devnull = ::open("/dev/null", O_WRONLY);
    ::dup2(devnull, 1);
    ::execl(EMCALIGN_BINARY, EMCALIGN_BINARY, "conditions", "put", uri_.c_str(), "--tag", "k", "--runs", "11-20",
            b.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  const auto start = std::chrono::steady_clock::now();
  while (!fs::exists(marker) && std::chrono::steady_clock::now() - start < std::chrono::seconds(30)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(fs::exists(marker));
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);

  const json l = json::parse(run(fmt::format("conditions list {} --tag k --json", uri_)).out);
  ASSERT_EQ(l["iovs"].size(), 1U);
  EXPECT_EQ(run(fmt::format("conditions get {} --tag k --run 15 -o {}", uri_, path("x.json"))).exitCode, 1);
  auto next = run(fmt::format("conditions put {} --tag k --runs 11-20 {}", uri_, b));
  EXPECT_EQ(next.exitCode, 0) << next.err;
  if (GetParam() == "sqlite") {
    const std::string cmd = fmt::format("sqlite3 {} 'PRAGMA integrity_check' > {}", path("c.db"), path("ic.txt"));
    ASSERT_EQ(std::system(cmd.c_str()), 0);
    EXPECT_EQ(emcalign::testing::slurp(path("ic.txt")), "ok\n");
  }
}

// correct and simulate take each run's alignment from a tag.
TEST_P(ConditionsCli, CorrectAndSimulateByRun) {
  ASSERT_EQ(run("conditions init " + uri_).exitCode, 0);
  const std::string a = params("a.json", 2.8, 0.3), b = params("b.json", 3.4, -0.2);
  ASSERT_EQ(run(fmt::format("conditions put {} --tag t --runs 1-5 {}", uri_, a)).exitCode, 0);
  ASSERT_EQ(run(fmt::format("conditions put {} --tag t --runs 6-9 {}", uri_, b)).exitCode, 0);
  // Run 3 simulated with the truth of IOV 1-5, run 7 with that of 6-9.
  for (int r : {3, 7}) {
    auto sim =
        run(fmt::format("simulate --events 300 --seed {} --run {} --conditions {} --tag t --theta-min 40 "
                        "--theta-max 140 -o {}",
                        r, r, uri_, path(fmt::format("r{}.h5", r))));
    ASSERT_EQ(sim.exitCode, 0) << sim.err;
    auto direct =
        run(fmt::format("simulate --events 300 --seed {} --run {} --params {} --theta-min 40 --theta-max 140 "
                        "-o {}",
                        r, r, r == 3 ? a : b, path(fmt::format("d{}.h5", r))));
    ASSERT_EQ(direct.exitCode, 0);
  }
  auto outside = run(fmt::format("simulate --events 10 --run 12 --conditions {} --tag t -o {}", uri_, path("x.h5")));
  EXPECT_EQ(outside.exitCode, 1);
  EXPECT_NE(outside.err.find("run 12: no IOV of tag 't'"), std::string::npos) << outside.err;

  // Both runs corrected in one go, each by its own IOV, equal the files corrected one by one.
  auto both = run(
      fmt::format("correct {} {} --conditions {} --tag t -o {}", path("r3.h5"), path("r7.h5"), uri_, path("both.h5")));
  ASSERT_EQ(both.exitCode, 0) << both.err;
  EXPECT_NE(both.out.find("with 2 IOVs of tag t"), std::string::npos) << both.out;
  ASSERT_EQ(run(fmt::format("correct {} --alignment {} -o {}", path("r3.h5"), a, path("c3.h5"))).exitCode, 0);
  ASSERT_EQ(run(fmt::format("correct {} --alignment {} -o {}", path("r7.h5"), b, path("c7.h5"))).exitCode, 0);
  auto rows = [](const std::string& f) {
    auto reader = emcalign::io::EventReader::open({f});
    EXPECT_TRUE(reader.ok());
    std::vector<emcalign::ParticleRow> all, block;
    while (*(*reader)->next(block)) all.insert(all.end(), block.begin(), block.end());
    return all;
  };
  auto joined = rows(path("c3.h5"));
  auto c7 = rows(path("c7.h5"));
  joined.insert(joined.end(), c7.begin(), c7.end());
  const auto together = rows(path("both.h5"));
  ASSERT_EQ(together.size(), joined.size());
  ASSERT_GT(together.size(), 500U);
  for (std::size_t i = 0; i < joined.size(); ++i) {
    if (std::isnan(joined[i].phiEmc)) continue;
    ASSERT_EQ(together[i].phiEmc, joined[i].phiEmc) << i;
    ASSERT_EQ(together[i].thetaEmc, joined[i].thetaEmc) << i;
  }
  // A directory of event files, as campaign takes one: every file corrected by its run's IOV,
  // one corrected file per input (it was refused: "File is actually a directory").
  fs::create_directories(path("period"));
  fs::copy_file(path("r3.h5"), path("period/r3.h5"));
  fs::copy_file(path("r7.h5"), path("period/r7.h5"));
  auto directory = run(fmt::format("correct {} --conditions {} --tag t -o {}/", path("period"), uri_, path("PC")));
  ASSERT_EQ(directory.exitCode, 0) << directory.err;
  EXPECT_NE(directory.out.find("(2 files, one per input)"), std::string::npos) << directory.out;
  for (int r : {3, 7}) {
    const auto one = rows(path(fmt::format("c{}.h5", r)));
    const auto fromDirectory = rows(path(fmt::format("PC/r{}.h5", r)));
    ASSERT_EQ(fromDirectory.size(), one.size());
    for (std::size_t i = 0; i < one.size(); ++i) {
      if (std::isnan(one[i].phiEmc)) continue;
      ASSERT_EQ(fromDirectory[i].phiEmc, one[i].phiEmc) << r << " " << i;
    }
  }
  // The same simulation, whichever way the truth was given.
  EXPECT_EQ(rows(path("r3.h5")).size(), rows(path("d3.h5")).size());
  EXPECT_EQ(rows(path("r7.h5"))[5].phiEmc, rows(path("d7.h5"))[5].phiEmc);
  auto run9 = run(fmt::format("correct {} --conditions {} --tag other -o {}", path("r3.h5"), uri_, path("o.h5")));
  EXPECT_EQ(run9.exitCode, 1);
  EXPECT_FALSE(fs::exists(path("o.h5")));
}

// conditions diff shows what it counts: z = -2.996 reads -2.99 and is not among the
// differences of 3 sigma or more (it read "-3.0"); z = +3.02 is, and is marked.
TEST_P(ConditionsCli, DiffCountsWhatItShows) {
  ASSERT_EQ(run("conditions init " + uri_).exitCode, 0);
  const auto withErrors = [&](const std::string& name, double alpha, double dx) {
    json j = json::parse(emcalign::testing::slurp(params(name, alpha, dx)));
    for (const auto& [key, value] : j["parameters"].items()) j["errors"][key] = 0.1;
    std::ofstream(path(name)) << j.dump();
    return path(name);
  };
  const double e = std::sqrt(0.02);  // the error of a difference of two values of error 0.1
  const std::string a = withErrors("a.json", 2.8, 0.3), b = withErrors("b.json", 2.8 + 2.996 * e, 0.3 - 3.02 * e);
  ASSERT_EQ(run(fmt::format("conditions put {} --tag a --runs 1-5 {}", uri_, a)).exitCode, 0);
  ASSERT_EQ(run(fmt::format("conditions put {} --tag b --runs 1-5 {}", uri_, b)).exitCode, 0);
  auto diff = run(fmt::format("conditions diff {} --tag a --tag b", uri_));
  ASSERT_EQ(diff.exitCode, 0) << diff.err;
  EXPECT_NE(diff.out.find("   -2.99 "), std::string::npos) << diff.out;
  EXPECT_NE(diff.out.find("   +3.02*"), std::string::npos) << diff.out;
  EXPECT_EQ(diff.out.find("-3.0"), std::string::npos) << diff.out;
  EXPECT_NE(diff.out.find("1 IOV pair, 1 difference of 3 sigma or more (marked *;"), std::string::npos) << diff.out;
}

INSTANTIATE_TEST_SUITE_P(Backends, ConditionsCli, ::testing::Values("sqlite", "postgres"),
                         [](const auto& instance) { return instance.param; });

// A tag copied SQLite → PostgreSQL → SQLite keeps its IOVs, payloads (hashes) and state.
TEST(ConditionsCopy, BetweenBackEnds) {
  const fs::path dir = emcalign::testing::freshTestDirectory("emcalign_conditions_copy");
  auto run = [&](const std::string& args) { return emcalign::testing::runEmcalign(dir, args); };
  const std::string first = "sqlite:" + (dir / "a.db").string(), back = (dir / "b.db").string();
  const std::string pg = emcalign::testing::freshPostgresDatabase();
  std::string text = kParams;
  text.replace(text.find("ALPHA"), 5, "2.5");
  text.replace(text.find("DX"), 2, "0.1");
  std::ofstream(dir / "p.json") << text;
  ASSERT_EQ(run("conditions init " + first).exitCode, 0);
  for (int k = 0; k < 3; ++k) {
    ASSERT_EQ(run(fmt::format("conditions put {} --tag v --runs {}-{} {}", first, 10 * k, 10 * k + 9,
                              (dir / "p.json").string()))
                  .exitCode,
              0);
  }
  ASSERT_EQ(run(fmt::format("conditions lock {} --tag v", first)).exitCode, 0);
  ASSERT_EQ(run("conditions init " + pg).exitCode, 0);
  auto c1 = run(fmt::format("conditions copy {} {} --tag v", first, pg));
  ASSERT_EQ(c1.exitCode, 0) << c1.err;
  auto c2 = run(fmt::format("conditions copy {} {} --tag v --as w", pg, back));
  ASSERT_EQ(c2.exitCode, 0) << c2.err;
  const json a = json::parse(run(fmt::format("conditions list {} --tag v --json", first)).out);
  const json b = json::parse(run(fmt::format("conditions list {} --tag w --json", back)).out);
  EXPECT_EQ(b["state"], "published");
  ASSERT_EQ(a["iovs"].size(), b["iovs"].size());
  for (std::size_t i = 0; i < a["iovs"].size(); ++i) {
    EXPECT_EQ(a["iovs"][i]["payload"], b["iovs"][i]["payload"]);
    EXPECT_EQ(a["iovs"][i]["last_run"], b["iovs"][i]["last_run"]);
  }
  auto again = run(fmt::format("conditions copy {} {} --tag v", first, pg));
  EXPECT_EQ(again.exitCode, 1);
  EXPECT_NE(again.err.find("exists already"), std::string::npos);
  fs::remove_all(dir);
}

// A password given in the URI (which the test server, trusting local connections, never asks
// for) leaves no trace: not in a message, a file, a corrected event file, a report, or the
// databases themselves (a copied tag's description).
TEST(ConditionsSecrets, APasswordInTheUriIsPrintedWrittenAndStoredNowhere) {
  const fs::path dir = emcalign::testing::freshTestDirectory("emcalign_conditions_secret");
  const std::string secret = "Hunter2Secret", other = "Other9Secret";
  std::string pg = emcalign::testing::freshPostgresDatabase();  // postgresql://user@host:port/db
  const auto at = pg.find('@');
  const std::string withPassword = pg.substr(0, at) + ":" + secret + pg.substr(at) + "?password=" + other;
  const std::string uri = "'" + withPassword + "'";
  std::string said;
  auto run = [&](const std::string& args) {
    auto r = emcalign::testing::runEmcalign(dir, args);
    said += r.out + r.err;
    EXPECT_EQ(r.exitCode, 0) << args << "\n" << r.err;
    return r;
  };
  std::string text = kParams;
  text.replace(text.find("ALPHA"), 5, "2.8");
  text.replace(text.find("DX"), 2, "0.3");
  std::ofstream(dir / "a.json") << text;
  std::ofstream(dir / "period.json") << R"({"format": "emcalign-period/1", "first_run": 1, "runs": 4,
    "events_per_run": 1000, "seed": 1, "theta_range_deg": [40, 140], "beam_energy_mev": [{"from_run": 1, "value": 612.5}],
    "segments": [{"from_run": 1, "parameters": {"alpha": 2.8, "dx": 0.3}}]})";
  const auto p = [&](const char* name) { return (dir / name).string(); };
  run("conditions init " + uri);
  run(fmt::format("conditions put {} --tag t --runs 1-10 {}", uri, p("a.json")));
  run(fmt::format("simulate --period {} -o {} --no-hits", p("period.json"), p("period")));
  run(fmt::format("campaign {} --conditions {} --tag c --min-events 1500", p("period"), uri));
  run(fmt::format("trend --conditions {} --tag c -o {}", uri, p("TD")));
  run(fmt::format("simulate --events 500 --run 3 --conditions {} --tag t -o {}", uri, p("r3.csv")));
  run(fmt::format("correct {} --conditions {} --tag t -o {}", p("r3.csv"), uri, p("c3.csv")));
  run(fmt::format("simulate --process gg --events 3000 --run 3 --params {} -o {}", p("a.json"), p("gg.h5")));
  run(fmt::format("check gg {} --conditions {} --tag t -o {}", p("gg.h5"), uri, p("CK")));
  run(fmt::format("report --conditions {} --tag c --trend {} -o {}", uri, p("TD"), p("report.html")));
  run(fmt::format("conditions copy {} {} --tag t --as t2", uri, uri));
  run(fmt::format("conditions copy {} sqlite:{} --tag t", uri, p("copy.db")));
  run("conditions list " + uri);
  run(fmt::format("conditions get {} --tag t --run 5 -o {}", uri, p("got.json")));
  // The shown form is there, the password nowhere.
  EXPECT_NE(said.find(pg.substr(0, pg.find('?'))), std::string::npos) << said;
  for (const std::string& s : {secret, other}) {
    EXPECT_EQ(said.find(s), std::string::npos) << "printed: " << said;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
      if (!e.is_regular_file()) continue;
      EXPECT_EQ(emcalign::testing::slurp(e.path()).find(s), std::string::npos) << "written into " << e.path();
    }
  }
  const json copied = json::parse(run(fmt::format("conditions list {} --tag t2 --json", uri)).out);
  EXPECT_NE(copied["description"].get<std::string>().find("copy of postgresql://"), std::string::npos);
  EXPECT_EQ(copied.dump().find(secret), std::string::npos) << "stored in the database: " << copied.dump();
  fs::remove_all(dir);
}

}  // namespace
