// A calibration campaign as a plan (validation/calibration_campaign.hpp): the plan file written
// and read back, and each of its groups fitted and stored by a task of its own.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "calibration_campaign_internal.hpp"
#include "emcalign/calib/fit_notes.hpp"
#include "emcalign/conddb/address.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/data_directory.hpp"
#include "emcalign/io/strict_json.hpp"
#include "emcalign/validation/calibration_campaign.hpp"

namespace emcalign::validation {

namespace fs = std::filesystem;
using io::Json;
using io::strict::StrictObject;

namespace {

constexpr double kNoEnergy = std::numeric_limits<double>::quiet_NaN();

bool isSha256(const std::string& s) {
  return s.size() == 64 &&
         std::all_of(s.begin(), s.end(), [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

}  // namespace

Json campaignPlanJson(const CampaignPlan& plan) {
  Json inputs = Json::array();
  for (const auto& [file, sha] : plan.digests) inputs.push_back({{"file", file}, {"sha256", sha}});
  Json groups = Json::array();
  for (const CampaignGroup& g : plan.groups) {
    groups.push_back({{"group", g.index},
                      {"iov", {g.iovFirst, g.iovLast}},
                      {"runs", g.runs},
                      {"files", g.files},
                      {"beam_energy_mev", std::isnan(g.beamEnergy) ? Json(nullptr) : Json(g.beamEnergy)},
                      {"selected_events", g.selected},
                      {"short", g.isShort}});
  }
  Json out = {{"format", kCampaignPlanFormat},
              {"software", fmt::format("emcalign {}", kVersion)},
              {"min_events", plan.minEvents},
              {"corrections", plan.corrections},
              {"corrections_sha256", plan.correctionsSha256},
              {"detector", plan.detector},
              {"sigma_sys", calib::sigmaSysChoiceJson(plan.sigmaSys)},
              {"inputs", inputs},
              {"groups", groups}};
  if (!plan.conditions.empty()) {
    out["conditions"] = plan.conditions;
    out["tag"] = plan.tag;
    out["description"] = plan.description;
  }
  return out;
}

namespace {

// The plan's σ_sys (none: the contract's).
void parseSigmaSys(const StrictObject& top, const std::string& path, CampaignPlan& plan) {
  if (!top.has("sigma_sys")) return;
  StrictObject s(top.at("sigma_sys"), "sigma_sys", path);
  s.allowOnly({"method", "value_deg"});
  const bool fixed = s.string("method") == "fixed";
  if (fixed) (void)s.number("value_deg");  // checked to be a number; the value read below
  auto choice = calib::sigmaSysChoiceFromJson(top.at("sigma_sys"));
  if (!choice) s.fail(s.pathOf(fixed ? "value_deg" : "method"), choice.error().message);
  plan.sigmaSys = *choice;
}

// The plan's input files, each with its SHA-256: no file twice, no two files of one content.
void parseInputs(const StrictObject& top, const std::string& path, CampaignPlan& plan) {
  const Json& inputs = top.at("inputs");
  if (!inputs.is_array()) top.fail("inputs", "expected a list");
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    StrictObject in(inputs[i], fmt::format("inputs[{}]", i), path);
    in.allowOnly({"file", "sha256"});
    const std::string file = in.string("file"), sha = in.string("sha256");
    if (!isSha256(sha)) in.fail(in.pathOf("sha256"), "expected the file's SHA-256 (64 hexadecimal digits)");
    if (!plan.digests.emplace(file, sha).second) in.fail(in.pathOf("file"), "the file is listed twice");
    for (const auto& [other, otherSha] : plan.digests) {
      if (other != file && otherSha == sha) {
        in.fail(in.pathOf("sha256"),
                fmt::format("the same content as {}: a copy, whose events would count twice", other));
      }
    }
  }
}

// A group's IOV and runs: the IOVs of a plan follow each other, its runs inside its IOV.
Status parseGroupRuns(const StrictObject& g, const std::string& where, const std::string& path,
                      const CampaignPlan& plan, CampaignGroup& group) {
  const Json& iov = g.at("iov");
  if (!iov.is_array() || iov.size() != 2) g.fail(g.pathOf("iov"), "expected [first_run, last_run]");
  constexpr std::int64_t kMinRun = 0;  // run numbers, as the conditions database takes them
  constexpr std::int64_t kMaxRun = std::numeric_limits<std::int32_t>::max();
  auto a = io::integerIn(iov[0], kMinRun, kMaxRun, path, where + ".iov[0]");
  auto b = io::integerIn(iov[1], kMinRun, kMaxRun, path, where + ".iov[1]");
  if (!a) return a.error();
  if (!b) return b.error();
  if (*a > *b) g.fail(g.pathOf("iov"), "the first run is after the last");
  if (!plan.groups.empty() && *a != plan.groups.back().iovLast + 1) {
    g.fail(g.pathOf("iov"), "the IOVs of a plan follow each other without a gap");
  }
  group.iovFirst = *a;
  group.iovLast = *b;
  const Json& runs = g.at("runs");
  if (!runs.is_array() || runs.empty()) g.fail(g.pathOf("runs"), "expected a non-empty list of runs");
  for (std::size_t r = 0; r < runs.size(); ++r) {
    auto run = io::integerIn(runs[r], group.iovFirst, group.iovLast, path, fmt::format("{}.runs[{}]", where, r));
    if (!run) return run.error();
    group.runs.push_back(static_cast<std::int32_t>(*run));
  }
  return {};
}

// Group i of the plan (its files among the plan's inputs, its counts as planGroups says them).
Result<CampaignGroup> parseGroup(const Json& j, std::size_t i, const std::string& path, const CampaignPlan& plan) {
  const std::string where = fmt::format("groups[{}]", i);
  StrictObject g(j, where, path);
  g.allowOnly({"group", "iov", "runs", "files", "beam_energy_mev", "selected_events", "short"});
  CampaignGroup group;
  auto index = io::integerIn(g.at("group"), 0, 10'000'000, path, where + ".group");
  if (!index) return index.error();
  if (*index != static_cast<std::int64_t>(i)) g.fail(g.pathOf("group"), fmt::format("expected {}", i));
  group.index = static_cast<int>(*index);
  if (Status s = parseGroupRuns(g, where, path, plan, group); !s) return s.error();
  const Json& files = g.at("files");
  if (!files.is_array() || files.empty()) g.fail(g.pathOf("files"), "expected a non-empty list of files");
  for (const Json& f : files) {
    if (!f.is_string()) g.fail(g.pathOf("files"), "expected file names");
    const std::string file = f.get<std::string>();
    if (std::find(group.files.begin(), group.files.end(), file) != group.files.end()) {
      g.fail(g.pathOf("files"), fmt::format("{} is listed twice: its events would count twice", file));
    }
    if (!plan.digests.contains(file)) g.fail(g.pathOf("files"), fmt::format("{} is not among the inputs", file));
    group.files.push_back(file);
  }
  const Json& e = g.at("beam_energy_mev");
  group.beamEnergy = e.is_null() ? kNoEnergy : g.number("beam_energy_mev");
  if (!e.is_null() && !(group.beamEnergy > 0.0)) g.fail(g.pathOf("beam_energy_mev"), "expected a positive energy");
  auto selected = io::integerIn(g.at("selected_events"), 0, std::numeric_limits<std::int64_t>::max(), path,
                                where + ".selected_events");
  if (!selected) return selected.error();
  group.selected = *selected;
  if (!g.at("short").is_boolean()) g.fail(g.pathOf("short"), "expected true or false");
  group.isShort = g.at("short").get<bool>();
  // Said by its counts, as planGroups says it: an edited flag would store another payload.
  if (group.isShort != (group.selected < plan.minEvents)) {
    g.fail(g.pathOf("short"), fmt::format("expected {}: {} selected events, min_events {}",
                                          group.selected < plan.minEvents, group.selected, plan.minEvents));
  }
  return group;
}

}  // namespace

Result<CampaignPlan> parseCampaignPlan(const Json& data, const std::string& path) {
  const Json* j = &data;
  try {
    StrictObject top(*j, "data", path);
    top.allowOnly({"format", "software", "min_events", "corrections", "corrections_sha256", "detector", "sigma_sys",
                   "inputs", "groups", "conditions", "tag", "description"});
    if (top.string("format") != kCampaignPlanFormat) {
      top.fail("format", fmt::format("expected \"{}\"", kCampaignPlanFormat));
    }
    if (top.has("software") && top.string("software") != fmt::format("emcalign {}", kVersion)) {
      top.fail("software", fmt::format("expected \"emcalign {}\" (the program that made the plan)", kVersion));
    }
    CampaignPlan plan;
    if (top.has("conditions")) {
      plan.conditions = top.string("conditions");
      plan.tag = top.string("tag");
      plan.description = top.string("description");
    }
    auto n = io::integerIn(top.at("min_events"), 1, std::numeric_limits<std::int64_t>::max(), path, "min_events");
    if (!n) return n.error();
    plan.minEvents = *n;
    plan.corrections = top.string("corrections");
    plan.correctionsSha256 = top.string("corrections_sha256");
    plan.detector = top.string("detector");
    parseSigmaSys(top, path, plan);
    parseInputs(top, path, plan);
    const Json& groups = top.at("groups");
    if (!groups.is_array() || groups.empty()) top.fail("groups", "expected a non-empty list");
    for (std::size_t i = 0; i < groups.size(); ++i) {
      auto group = parseGroup(groups[i], i, path, plan);
      if (!group) return group.error();
      plan.groups.push_back(std::move(*group));
    }
    return plan;
  } catch (const io::strict::BadInput& e) {
    return Error{e.message};
  }
}

Result<CampaignModel> planModel(const CampaignPlan& plan, const geometry::Calorimeter& calo) {
  const std::string detector = io::detectorPath(plan.detector);
  auto model = campaignModel(plan.corrections, detector, calo);
  if (!model) return model.error();
  if (model->correctionsSha256 != plan.correctionsSha256) {
    return Error{fmt::format("{}: its SHA-256 is not the plan's: the corrections changed since the plan was made",
                             plan.corrections)};
  }
  model->setSigmaSys(plan.sigmaSys);
  return model;
}

namespace {

// A group's tag when the group is there already (a retried task: done, if the tag holds it from
// the same data), with the database opened into `db`; a new SQLite file is created only when
// the group is fitted, to store it.
Result<std::optional<StoredGroup>> storedAlready(const CampaignPlan& plan, const CampaignModel& model, int index,
                                                 const std::string& uri, const std::string& tag,
                                                 std::unique_ptr<conddb::Database>& db) {
  const CampaignGroup& g = plan.groups[static_cast<std::size_t>(index)];
  const std::string file = conddb::sqliteFileOf(uri);
  std::error_code ec;
  if (!file.empty() && !fs::exists(fs::symlink_status(file, ec))) return std::optional<StoredGroup>();
  auto opened = conddb::Database::open(uri, conddb::IfMissing::Create);
  if (!opened) return opened.error();
  db = std::move(*opened);
  auto done = groupsInTag(*db, tag, plan.groups);
  if (!done) return done.error();
  if (!(*done)[static_cast<std::size_t>(index)]) return std::optional<StoredGroup>();
  auto same = groupStored(*db, tag, g, plan.digests, model);
  if (!same) return same.error();
  return std::optional<StoredGroup>(
      StoredGroup{fmt::format("group {} (runs {}-{}) is in tag {} already, from the same data: nothing to do", g.index,
                              g.iovFirst, g.iovLast, tag),
                  {}});
}

// The group's files must be those the plan was made from (the plan has a digest of each).
Status sameFilesAsPlanned(const CampaignPlan& plan, const CampaignGroup& g) {
  for (const auto& f : g.files) {
    auto it = plan.digests.find(f);
    if (it == plan.digests.end())
      return Error{fmt::format("group {}: its file {} is not among the plan's inputs", g.index, f)};
    auto digest = sha256OfFile(f);
    if (!digest) return digest.error();
    if (*digest != it->second) {
      return Error{
          fmt::format("{}: its SHA-256 is not the plan's: the file changed since the plan was made (make "
                      "the plan again)",
                      f)};
    }
  }
  return {};
}

// What a physicist must hear of a group's fit: a poor fit, or a fit outside the validated ranges.
void warnOfFit(const GroupFit& fit, const std::string& group, std::vector<std::string>& warnings) {
  if (fit.result.status == FitStatus::PoorFit) {
    warnings.push_back(fmt::format("{}: poor fit (chi2/ndf {:.1f}/{})", group, fit.result.chi2, fit.result.ndf));
  }
  if (auto outside = calib::outsideValidatedRanges(fit.result); !outside.empty()) {
    warnings.push_back(fmt::format(
        "{}: fitted outside the ranges over which the model and its corrections were validated (its biases there "
        "are not known, docs/validation.md; a simulated truth in mm under a cm header is the usual mistake): {}",
        group, fmt::join(outside, ", ")));
  }
}

}  // namespace

Result<StoredGroup> storePlannedGroup(const CampaignPlan& plan, const CampaignModel& model, int index,
                                      const std::string& uri, const std::string& tag, const std::string& description) {
  if (index < 0 || index >= static_cast<int>(plan.groups.size())) {
    return Error{fmt::format("group {}: the plan has groups 0 to {}", index, plan.groups.size() - 1)};
  }
  const CampaignGroup& g = plan.groups[static_cast<std::size_t>(index)];
  // The database is kept even if the put fails: the plan's other tasks may be storing into it.
  std::unique_ptr<conddb::Database> db;
  auto already = storedAlready(plan, model, index, uri, tag, db);
  if (!already) return already.error();
  if (*already) return std::move(**already);
  if (Status s = sameFilesAsPlanned(plan, g); !s) return s.error();
  auto groupModel = model.at(g.beamEnergy);
  if (!groupModel) {
    return Error{fmt::format("group {} (runs {}-{}): {}", g.index, g.iovFirst, g.iovLast, groupModel.error().message)};
  }
  StoredGroup stored;
  if (!groupModel->correctionsWarning.empty()) stored.warnings.push_back(groupModel->correctionsWarning);
  auto fill = fillPlannedGroup(g, *groupModel);
  if (!fill) return fill.error();
  auto fit = fitGroup(g, *fill, *groupModel, plan.digests,
                      campaignOrigin(g, plan.minEvents, static_cast<int>(plan.groups.size())));
  if (!fit) return fit.error();
  if (!usable(fit->result.status)) {
    return Error{fmt::format("group {} (runs {}-{}): the fit's status is '{}': not stored", g.index, g.iovFirst,
                             g.iovLast, name(fit->result.status))};
  }
  const std::string group = fmt::format("group {} (runs {}-{})", g.index, g.iovFirst, g.iovLast);
  warnOfFit(*fit, group, stored.warnings);
  if (!db) {
    auto opened = conddb::Database::open(uri, conddb::IfMissing::Create);
    if (!opened) return opened.error();
    db = std::move(*opened);
  }
  if (Status s = db->put(tag, g.iovFirst, g.iovLast, fit->payload, conddb::IfMissing::Create, description); !s) {
    // The same task run twice at once: the other copy stored the group first.
    auto same = groupStored(*db, tag, g, plan.digests, model);
    if (!same || !*same) return s.error();
    stored.said = fmt::format("{} was stored meanwhile by another task, from the same data: done", group);
    return stored;
  }
  stored.said =
      fmt::format("group {} (runs {}-{}, {} selected events): {}, chi2/ndf {:.1f}/{} -> {} tag {}", g.index, g.iovFirst,
                  g.iovLast, g.selected, name(fit->result.status), fit->result.chi2, fit->result.ndf, db->uri(), tag);
  return stored;
}

Result<calib::ProfileFill> fillPlannedGroup(const CampaignGroup& g, const CampaignModel& model) {
  const std::string group = fmt::format("group {} (runs {}-{})", g.index, g.iovFirst, g.iovLast);
  auto distinct = eventFilesIn(g.files);  // the same file by two names is refused
  if (!distinct) return Error{fmt::format("{}: {}", group, distinct.error().message)};
  calib::ProfileFill fill = calib::ProfileFill::empty(model.profile);
  std::vector<std::map<std::int32_t, io::EventNumbers>> eventsOf(g.files.size());
  for (std::size_t k = 0; k < g.files.size(); ++k) {
    auto byRun =
        calib::fillProfilesByRun(g.files[k], model.depthAtEnergy(), model.selection, model.profile, &eventsOf[k]);
    if (!byRun) return byRun.error();
    for (std::int32_t run : g.runs) {
      if (auto it = byRun->find(run); it != byRun->end()) fill.merge(it->second);
    }
  }
  if (Status s = eachEventOnce(g.files, std::vector<std::string>(g.files.size()), eventsOf); !s) {
    return Error{fmt::format("{}: {}", group, s.error().message)};
  }
  if (!fill.beamEnergies.empty() &&
      (std::isnan(g.beamEnergy) || fill.beamEnergies.size() != 1 || *fill.beamEnergies.begin() != g.beamEnergy)) {
    return Error{fmt::format("{}: the plan says beam energy {}, its events have {:.6g} MeV (the plan was edited?)",
                             group,
                             std::isnan(g.beamEnergy) ? std::string("none") : fmt::format("{:.6g} MeV", g.beamEnergy),
                             fmt::join(fill.beamEnergies, ", "))};
  }
  if (fill.cutFlow.events.back() != g.selected) {
    return Error{
        fmt::format("{}: {} selected events in its files, the plan counted {} (the files changed since the "
                    "plan was made, or the plan was edited?)",
                    group, fill.cutFlow.events.back(), g.selected)};
  }
  return fill;
}

namespace {

// Each group of the plan a task, stored into the plan's tag.
class CalibrationCampaignJob final : public PlannedJob {
 public:
  CalibrationCampaignJob(CampaignPlan plan, CampaignModel model, Json data, std::string key)
      : plan_(std::move(plan)), model_(std::move(model)), data_(std::move(data)), key_(std::move(key)) {}

  [[nodiscard]] std::vector<PlannedTask> tasks() const override {
    std::vector<PlannedTask> t;
    for (const auto& g : plan_.groups) {
      t.push_back({fmt::format("group {} (runs {}-{}, {} selected events)", g.index, g.iovFirst, g.iovLast, g.selected),
                   {plan_.conditions.empty() || plan_.tag.empty()
                        ? fmt::format("the IOV {}-{} of the database and tag given to the task (--conditions, --tag)",
                                      g.iovFirst, g.iovLast)
                        : fmt::format("{} tag {}: the IOV {}-{}", conddb::shownAddress(plan_.conditions), plan_.tag,
                                      g.iovFirst, g.iovLast)},
                   g.files});
    }
    return t;
  }
  Status runTask(std::size_t k, const TaskContext& context) const override {
    const auto& say = context.say;
    if (plan_.conditions.empty() || plan_.tag.empty()) {
      return Error{
          "the plan was made without --conditions and --tag: run its groups with emcalign campaign --plan "
          "PLAN --group K --conditions URI --tag T"};
    }
    auto r = storePlannedGroup(plan_, model_, static_cast<int>(k), plan_.conditions, plan_.tag, plan_.description);
    if (!r) return r.error();
    for (const auto& w : r->warnings) context.warn(w);
    say(r->said);
    return {};
  }
  [[nodiscard]] Json data() const override { return data_; }
  [[nodiscard]] std::string recordKey() const override { return key_; }

 private:
  CampaignPlan plan_;
  CampaignModel model_;
  Json data_;
  std::string key_;
};

}  // namespace

std::unique_ptr<PlannedJob> calibrationCampaignJob(CampaignPlan plan, CampaignModel model, io::Json data,
                                                   std::string recordKey) {
  return std::make_unique<CalibrationCampaignJob>(std::move(plan), std::move(model), std::move(data),
                                                  std::move(recordKey));
}

}  // namespace emcalign::validation
