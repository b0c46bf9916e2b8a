// A small period end to end through the command line: simulate --period, campaign into a
// tag (resumed when run again, refused into a tag of another plan), the same campaign fanned
// out as a batch system would (--plan, then --group K in parallel processes) against the
// test suite's PostgreSQL server, giving the very same payloads, and trend: the step found
// at its run, no false step or drift, and --refit writing fewer IOVs.

#include <filesystem>
#include <fstream>
#include <string>
#include <tuple>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"
#include "postgres_support.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;

// 24 runs at two beam energies, run 5 missing; dx steps from 0.3 to 0.8 cm at run 9.
constexpr const char* kScenario = R"({"format": "emcalign-period/1", "first_run": 1, "runs": 24,
  "events_per_run": [2500, 3500], "seed": 5, "theta_range_deg": [40, 140],
  "beam_energy_mev": [{"from_run": 1, "value": 612.5}, {"from_run": 13, "value": 700}],
  "segments": [{"from_run": 1, "parameters": {"alpha": 2.8, "dx": 0.3, "dp1": 0.5}},
               {"from_run": 9, "parameters": {"dx": 0.8}}],
  "missing_runs": [5]})";

class CampaignCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    period_ = new fs::path(fs::temp_directory_path() / fmt::format("emcalign_campaign_period_{}", ::getpid()));
    fs::remove_all(*period_);
    fs::create_directories(*period_);
    std::ofstream(*period_ / "s.json") << kScenario;
    const auto r = emcalign::testing::runEmcalign(
        *period_,
        fmt::format("simulate --period {} -o {} --no-hits", (*period_ / "s.json").string(), (*period_ / "p").string()));
    ASSERT_EQ(r.exitCode, 0) << r.err;
  }
  static void TearDownTestSuite() {
    fs::remove_all(*period_);
    delete period_;
  }
  void SetUp() override { dir_ = emcalign::testing::freshTestDirectory("emcalign_campaign_cli"); }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& n) const { return (dir_ / n).string(); }
  static std::string events() { return (*period_ / "p").string(); }
  emcalign::testing::CommandResult run(const std::string& args) const {
    return emcalign::testing::runEmcalign(dir_, args);
  }
  json list(const std::string& uri, const std::string& tag) const {
    const auto r = run(fmt::format("conditions list {} --tag {} --json", uri, tag));
    EXPECT_EQ(r.exitCode, 0) << r.err;
    return json::parse(r.out);
  }

  static fs::path* period_;
  fs::path dir_;
};
fs::path* CampaignCli::period_ = nullptr;

TEST_F(CampaignCli, CalibratesResumesAndRefusesAnotherPlan) {
  const std::string uri = "sqlite:" + path("c.db");
  auto r = run(fmt::format("campaign {} --conditions {} --tag t --min-events 4000", events(), uri));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("11 fitted and stored"));
  const json l = list(uri, "t");
  ASSERT_EQ(l["iovs"].size(), 11u);
  // The IOVs tile runs 1-24; no group mixes the two beam energies (612.5 MeV to run 12).
  EXPECT_EQ(l["iovs"][0]["first_run"], 1);
  EXPECT_EQ(l["iovs"].back()["last_run"], 24);
  for (std::size_t k = 1; k < l["iovs"].size(); ++k) {
    EXPECT_EQ(l["iovs"][k]["first_run"].get<int>(), l["iovs"][k - 1]["last_run"].get<int>() + 1);
    EXPECT_GE(l["iovs"][k]["selected_events"].get<int>(), 4000);
    EXPECT_EQ(l["iovs"][k]["status"], "converged");
    const int first = l["iovs"][k]["first_run"], last = l["iovs"][k]["last_run"];
    EXPECT_TRUE(last <= 12 || first >= 13) << first << "-" << last;
  }
  // A rerun finds everything done.
  r = run(fmt::format("campaign {} --conditions {} --tag t --min-events 4000", events(), uri));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("0 fitted and stored, 11 in tag t already"));
  EXPECT_EQ(list(uri, "t")["iovs"], l["iovs"]);
  // Another grouping into the same tag: refused before any fit.
  r = run(fmt::format("campaign {} --conditions {} --tag t --min-events 9000", events(), uri));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("not one of this campaign's groups"));
  EXPECT_EQ(list(uri, "t")["iovs"], l["iovs"]);

  // Each run's calibration is the one of its IOV.
  r = run(fmt::format("conditions get {} --tag t --run 20 -o {}", uri, path("p20.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json p20 = json::parse(emcalign::testing::slurp(path("p20.json")));
  EXPECT_NEAR(p20["parameters"]["dx"].get<double>(), 0.8, 0.1);
  EXPECT_NEAR(p20["parameters"]["alpha"].get<double>(), 2.8, 0.15);
}

// The batch fan-out: the plan, then every group in its own process at once against
// PostgreSQL; the payloads are those of the campaign run in one process.
// Run numbers below 0 are no conditions database's: refused when asked for, and a file holding
// them is refused before any database is made (its IOV could never be read back).
TEST_F(CampaignCli, ANegativeRunIsRefusedBeforeAnythingIsStored) {
  const std::string truth = std::string(EMCALIGN_SOURCE_DIR) + "/data/examples/paper-like.json";
  const auto asked = run(fmt::format("simulate --events 3000 --params {} --run -5 -o {}", truth, path("neg.csv")));
  EXPECT_EQ(asked.exitCode, 2) << asked.err;
  ASSERT_FALSE(fs::exists(path("neg.csv")));
  const auto made = run(fmt::format("simulate --events 3000 --params {} --run 5 -o {}", truth, path("five.csv")));
  ASSERT_EQ(made.exitCode, 0) << made.err;
  std::ifstream in(path("five.csv"));
  std::ofstream out(path("neg.csv"));
  for (std::string line; std::getline(in, line);) out << (line.rfind("5,", 0) == 0 ? "-" + line : line) << "\n";
  out.close();
  const auto refused = run(fmt::format("campaign {} --conditions sqlite:{} --tag n", path("neg.csv"), path("n.db")));
  EXPECT_EQ(refused.exitCode, 1) << refused.err;
  EXPECT_THAT(refused.err, HasSubstr("neg.csv: run -5: a run number is 0 or more"));
  EXPECT_FALSE(fs::exists(path("n.db"))) << "nothing is made for a campaign refused for its inputs";
}

TEST_F(CampaignCli, PlanFannedOutToParallelProcessesAgainstPostgres) {
  const std::string pg = emcalign::testing::freshPostgresDatabase();
  auto r = run(fmt::format("campaign {} --plan {} --min-events 4000", events(), path("plan.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json plan = json::parse(emcalign::testing::slurp(path("plan.json")));
  ASSERT_EQ(plan["format"], "emcalign-plan/1");
  ASSERT_EQ(plan["command"], "campaign");
  const std::size_t groups = plan["data"]["groups"].size();
  ASSERT_EQ(groups, 11u);
  std::string script = "set -u\n";
  for (std::size_t k = 0; k < groups; ++k) {
    script += fmt::format(
        "({} campaign --plan {} --group {} --conditions {} --tag fan >/dev/null 2>{}; echo $? > {}) &\n",
        EMCALIGN_BINARY, path("plan.json"), k, pg, path(fmt::format("err{}", k)), path(fmt::format("rc{}", k)));
  }
  script += "wait\n";
  std::ofstream(path("array.sh")) << script;
  ASSERT_EQ(std::system(("bash " + path("array.sh")).c_str()), 0);
  for (std::size_t k = 0; k < groups; ++k) {
    EXPECT_EQ(emcalign::testing::slurp(path(fmt::format("rc{}", k))), "0\n")
        << k << ": " << emcalign::testing::slurp(path(fmt::format("err{}", k)));
  }
  // A job run twice (a batch system's retry) does nothing the second time.
  r = run(fmt::format("campaign --plan {} --group 3 --conditions {} --tag fan", path("plan.json"), pg));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("already"));
  r = run(fmt::format("campaign --plan {} --group 11 --conditions {} --tag fan", path("plan.json"), pg));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("groups 0 to 10"));

  const json fan = list(pg, "fan");
  ASSERT_EQ(fan["iovs"].size(), groups);
  const std::string local = "sqlite:" + path("local.db");
  r = run(fmt::format("campaign {} --conditions {} --tag fan --min-events 4000 --threads 1", events(), local));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json one = list(local, "fan");
  ASSERT_EQ(one["iovs"].size(), groups);
  for (std::size_t k = 0; k < groups; ++k) {
    EXPECT_EQ(fan["iovs"][k]["first_run"], one["iovs"][k]["first_run"]);
    EXPECT_EQ(fan["iovs"][k]["last_run"], one["iovs"][k]["last_run"]);
    EXPECT_EQ(fan["iovs"][k]["payload"], one["iovs"][k]["payload"]) << k;  // content-addressed: the same fit
  }
}

TEST_F(CampaignCli, SigmaSysIsEveryGroupsAndThePlansAndTheRefitsToo) {
  const std::string uri = "sqlite:" + path("c.db");
  auto r = run(fmt::format("campaign {} --conditions {} --tag a --min-events 4000 --sigma-sys auto", events(), uri));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  r = run(fmt::format("conditions get {} --tag a --run 20 -o {}", uri, path("p20.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json p20 = json::parse(emcalign::testing::slurp(path("p20.json")));
  EXPECT_EQ(p20["sigma_sys"]["method"], "auto");
  EXPECT_LT(p20["sigma_sys"]["value_deg"].get<double>(), 0.2);
  EXPECT_NEAR(p20["chi2"].get<double>(), p20["ndf"].get<double>(), 1e-6 * p20["ndf"].get<double>());
  // The refit fits its periods the same way.
  r = run(fmt::format("trend --conditions {} --tag a -o {} --refit {} --tag-out a.seg", uri, path("tr"), events()));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  r = run(fmt::format("conditions get {} --tag a.seg --run 20 -o {}", uri, path("s20.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(json::parse(emcalign::testing::slurp(path("s20.json")))["sigma_sys"]["method"], "auto");
  // A refit is written under test (docs/contract.md §13): validated by someone before it is promoted.
  r = run(fmt::format("conditions state {} --tag a.seg", uri));
  EXPECT_EQ(r.out, "testing\n") << r.err;

  // A plan records it, and its jobs keep to it.
  r = run(fmt::format("campaign {} --plan {} --min-events 4000 --sigma-sys 0.1", events(), path("plan.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json plan = json::parse(emcalign::testing::slurp(path("plan.json")));
  EXPECT_EQ(plan["data"]["sigma_sys"], json::parse(R"({"method": "fixed", "value_deg": 0.1})"));
  r = run(fmt::format("campaign --plan {} --group 0 --conditions {} --tag f --sigma-sys auto", path("plan.json"), uri));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("the plan"));
  r = run(fmt::format("campaign --plan {} --group 0 --conditions {} --tag f", path("plan.json"), uri));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  r = run(fmt::format("conditions get {} --tag f --run 1 -o {}", uri, path("f1.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json f1 = json::parse(emcalign::testing::slurp(path("f1.json")));
  EXPECT_EQ(f1["sigma_sys"]["method"], "fixed");
  EXPECT_DOUBLE_EQ(f1["sigma_sys"]["value_deg"].get<double>(), 0.1);
}

// The systematic errors the corrections carry (docs/systematics.md) are stored with every
// group's calibration, as a fit writes them.
TEST_F(CampaignCli, EveryGroupCarriesTheSystematicErrorsOfItsCorrections) {
  const std::string corrections = std::string(EMCALIGN_SOURCE_DIR) + "/data/corrections/ee-612.5MeV-40-140deg.json";
  const json file = json::parse(emcalign::testing::slurp(corrections));
  const std::string uri = "sqlite:" + path("s.db");
  auto r = run(fmt::format("campaign {} --conditions {} --tag s --min-events 4000 --corrections {}", events(), uri,
                           corrections));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  r = run(fmt::format("conditions get {} --tag s --run 1 -o {}", uri, path("s1.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json p = json::parse(emcalign::testing::slurp(path("s1.json")));
  ASSERT_TRUE(p.contains("systematic_errors"));
  EXPECT_EQ(p["systematic_errors"]["dx"], file["systematic_errors"]["errors"]["dx"]);
  EXPECT_EQ(p["derived"]["mu"]["systematic_error"], file["systematic_errors"]["errors"]["mu"]);
}

TEST_F(CampaignCli, ACorrectionsGridFitsEveryGroupAtItsOwnEnergy) {
  // A small idealised grid over 500-750 MeV (the period's runs are at 612.5 and 700 MeV),
  // its 750 MeV point moved 2 cm deeper so that every energy has a depth offset of its own.
  auto r =
      run("derive-corrections --ideal --events 20000 --response-samples 50 --response-events 5000 --seed 4 "
          "--beam-energy 500,750 -o " +
          path("grid"));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  json deeper = json::parse(emcalign::testing::slurp(path("grid/ee-750MeV.json")));
  deeper["depth_offset_cm"] = deeper["depth_offset_cm"].get<double>() + 2.0;
  std::ofstream(path("grid/ee-750MeV.json")) << deeper.dump();
  const double d500 =
      json::parse(emcalign::testing::slurp(path("grid/ee-500MeV.json")))["depth_offset_cm"].get<double>();
  const double d750 = deeper["depth_offset_cm"].get<double>();
  const std::string uri = "sqlite:" + path("c.db");
  r = run(fmt::format("campaign {} --conditions {} --tag g --min-events 4000 --corrections {}", events(), uri,
                      path("grid")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  for (const auto& [run_, energy, w750] : {std::tuple{1, 612.5, 0.45}, std::tuple{20, 700.0, 0.8}}) {
    r = run(fmt::format("conditions get {} --tag g --run {} -o {}", uri, run_, path("p.json")));
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const json p = json::parse(emcalign::testing::slurp(path("p.json")));
    const json& corrections = p["input"]["provenance"]["model_corrections"];
    EXPECT_NEAR(corrections["depth_offset_cm"].get<double>(), (1.0 - w750) * d500 + w750 * d750, 1e-12) << run_;
    const json& interpolation = corrections["interpolation"];
    EXPECT_EQ(interpolation["beam_energy_mev"], energy) << run_;
    EXPECT_EQ(interpolation["directory"], path("grid"));
    EXPECT_NEAR(interpolation["points"][1]["weight"].get<double>(), w750, 1e-12) << run_;
    EXPECT_EQ(p["input"]["provenance"]["campaign"]["beam_energy_mev"], energy) << run_;
  }
  // The refit takes the same grid (the tag's by its digest), and refuses other corrections;
  // without --corrections it takes those the payloads name, still there and unchanged, and
  // refuses them once they have changed.
  r = run(fmt::format("trend --conditions {} --tag g -o {} --refit {} --tag-out g.seg --corrections {}", uri,
                      path("tr"), events(), path("grid")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  r = run(fmt::format("trend --conditions {} --tag g -o {} --refit {} --tag-out g.seg2", uri, path("tr2"), events()));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("refit with the corrections the payloads name, unchanged since: " + path("grid")));
  r = run(fmt::format("trend --conditions {} --tag g -o {} --refit {} --tag-out g.seg3 --corrections {}", uri,
                      path("tr3"), events(),
                      std::string(EMCALIGN_SOURCE_DIR) + "/data/corrections/ee-612.5MeV-40-140deg.json"));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("give the same --corrections"));
  const fs::path point = fs::directory_iterator(path("grid"))->path();
  const std::string original = emcalign::testing::slurp(point);
  std::ofstream(point, std::ios::app) << " ";
  r = run(fmt::format("trend --conditions {} --tag g -o {} --refit {} --tag-out g.seg4", uri, path("tr4"), events()));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("which have changed since"));
  std::ofstream(point, std::ios::trunc) << original;
  // A plan's job checks the grid by its digest, and stores the very payload of the campaign.
  r = run(fmt::format("campaign {} --plan {} --min-events 4000 --corrections {}", events(), path("plan.json"),
                      path("grid")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  for (int group : {0, 9}) {
    r = run(fmt::format("campaign --plan {} --group {} --conditions {} --tag j --corrections {}", path("plan.json"),
                        group, uri, path("grid")));
    ASSERT_EQ(r.exitCode, 0) << r.err;
  }
  const json all = list(uri, "g"), jobs = list(uri, "j");
  ASSERT_EQ(jobs["iovs"].size(), 2u);
  for (const auto& iov : jobs["iovs"]) {
    bool found = false;
    for (const auto& other : all["iovs"]) {
      if (other["first_run"] != iov["first_run"]) continue;
      EXPECT_EQ(other["payload"], iov["payload"]) << iov["first_run"];  // content-addressed: the same fit
      found = true;
    }
    EXPECT_TRUE(found) << iov["first_run"];
  }
  r = run(fmt::format("campaign --plan {} --group 1 --conditions {} --tag j --corrections {}", path("plan.json"), uri,
                      path("grid/ee-500MeV.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("with other ones"));
  // A grid that does not reach the first runs' energy is refused before any fit.
  fs::create_directories(path("high"));
  fs::copy_file(path("grid/ee-750MeV.json"), path("high/ee-750MeV.json"));
  json moved = deeper;
  moved["beam_energy_mev"] = 650.0;
  std::ofstream(path("high/ee-650MeV.json")) << moved.dump();
  r = run(fmt::format("campaign {} --conditions {} --tag h --min-events 4000 --corrections {}", events(), uri,
                      path("high")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("run 1 (612.5 MeV): beam energy 612.5 MeV is outside the corrections grid"));
}

TEST_F(CampaignCli, TrendFindsTheStepAndRefitsTheStablePeriods) {
  const std::string uri = "sqlite:" + path("c.db");
  auto r = run(fmt::format("campaign {} --conditions {} --tag t --min-events 4000", events(), uri));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  // dx = 0.8 cm after run 9 lies beyond the validated ±0.5 cm: each such group is warned of.
  EXPECT_THAT(r.err, HasSubstr("groups fitted outside the ranges over which the model and its corrections were "
                               "validated"));
  EXPECT_THAT(r.err, HasSubstr("; group 10 (runs 23-24): dx = 0.7"));
  // The model each IOV was fitted with is listed, and its notes travel in the payload.
  EXPECT_EQ(list(uri, "t")["iovs"][0]["model"], "the paper's model");
  EXPECT_THAT(run(fmt::format("conditions list {}", uri)).out, HasSubstr("paper's model"));
  EXPECT_THAT(run(fmt::format("conditions export {} --tag t -o -", uri)).out, HasSubstr(",model,"));
  r = run(fmt::format("trend --conditions {} --tag t -o {} --truth {} --refit {} --tag-out t.seg", uri, path("tr"),
                      (*period_ / "p" / "truth.json").string(), events()));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out + r.err, HasSubstr("The IOVs were fitted with the paper's model."));
  EXPECT_THAT(emcalign::testing::slurp(path("tr/trend.md")), HasSubstr("| true size |"));
  const json t = json::parse(emcalign::testing::slurp(path("tr/trend.json")));
  EXPECT_EQ(t["format"], "emcalign-trend/1");
  ASSERT_EQ(t["steps"].size(), 1u) << t["steps"].dump();
  EXPECT_EQ(t["steps"][0]["parameter"], "dx");
  // The true step is at run 9, inside the IOV 8-9: found there, and its size is 0.5 cm — to the
  // 10 % scale of the paper's model without corrections (docs/validation.md), several of the
  // statistical errors the trend weighs the IOVs with.
  EXPECT_NEAR(t["steps"][0]["first_run_after"].get<double>(), 9.0, 1.0);
  EXPECT_NEAR(t["steps"][0]["size"].get<double>(), 0.5, 0.06);
  EXPECT_TRUE(t["drifts"].empty()) << t["drifts"].dump();
  // (no trend_psi.png: β = 0 in this period, so its tilt has no direction)
  for (const char* f : {"trend.md", "fig7.png", "trend_all.png", "trend_dx.png", "trend_beta.png"}) {
    EXPECT_GT(fs::file_size(dir_ / "tr" / f), 1000u) << f;
  }
  EXPECT_THAT(emcalign::testing::slurp(path("tr/trend.md")), HasSubstr("## Refit"));
  // The logbook's boundaries: at run 9 the step is found as a known one; at run 17 nothing
  // changed, and the trend says so rather than keeping quiet.
  r = run(fmt::format("trend --conditions {} --tag t -o {} --boundaries 9,17", uri, path("known")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out + r.err, HasSubstr("known boundary at run 17: nothing changed"));
  const json known = json::parse(emcalign::testing::slurp(path("known/trend.json")));
  EXPECT_EQ(known["method"]["known_boundaries"], json::array({9, 17}));
  ASSERT_EQ(known["known_boundaries"].size(), 2u) << known["known_boundaries"].dump();
  EXPECT_EQ(known["known_boundaries"][0]["changed"], json::array({"dx"})) << known["known_boundaries"].dump();
  EXPECT_TRUE(known["known_boundaries"][1]["changed"].empty()) << known["known_boundaries"].dump();
  ASSERT_EQ(known["steps"].size(), 1u) << known["steps"].dump();
  EXPECT_TRUE(known["steps"][0]["known_boundary"].get<bool>());
  EXPECT_NEAR(known["steps"][0]["size"].get<double>(), 0.5, 0.06);
  // The refit: one IOV per stable period (and the IOV straddling the step kept), tiling 1-24.
  const json seg = list(uri, "t.seg");
  ASSERT_LT(seg["iovs"].size(), 11u);
  ASSERT_GE(seg["iovs"].size(), 2u);
  EXPECT_EQ(seg["iovs"][0]["first_run"], 1);
  EXPECT_EQ(seg["iovs"].back()["last_run"], 24);
  for (std::size_t k = 1; k < seg["iovs"].size(); ++k) {
    EXPECT_EQ(seg["iovs"][k]["first_run"].get<int>(), seg["iovs"][k - 1]["last_run"].get<int>() + 1);
  }
  EXPECT_GT(seg["iovs"].back()["selected_events"].get<int>(), 20000);
  // Statistical errors shrink with the events of a whole period.
  for (const auto& s : t["refit"]["segments"]) {
    if (s["kept"].get<bool>()) continue;
    const auto& dx = s["precision"]["dx"];
    EXPECT_LT(dx["statistical_error_after"].get<double>(), 0.8 * dx["statistical_error_before"].get<double>());
    // Without model corrections the fit's dx is ~10 % low (docs/validation.md).
    const double truth = dx["truth"].get<double>();
    EXPECT_NEAR(dx["value"].get<double>(), truth, 0.15 * truth + 0.02);
  }
  // Run again (a batch system's retry), the refit finds itself stored and exits 0; into a tag
  // that holds anything else, it is refused.
  r = run(fmt::format("trend --conditions {} --tag t -o {} --refit {} --tag-out t.seg", uri, path("tr2"), events()));
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out + r.err, HasSubstr("tag t.seg holds this refit already"));
  r = run(fmt::format("trend --conditions {} --tag t -o {} --refit {} --tag-out t", uri, path("tr3"), events()));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("tag 't' exists already"));
}

}  // namespace
