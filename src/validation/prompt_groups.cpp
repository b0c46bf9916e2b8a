// The prompt loop's groups (validation/prompt.hpp): the runs taken closed into groups
// (docs/contract.md §13), each fitted, decided against the calibration in force and stored.

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/secrets.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/utf8.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/validation/prompt.hpp"
#include "prompt_loop.hpp"

namespace emcalign::validation::prompt {

namespace fs = std::filesystem;

namespace {

bool sameEnergy(double a, double b) { return std::isnan(a) || std::isnan(b) || a == b; }

}  // namespace

std::vector<ClosedGroup> closedGroups(const std::vector<TakenRun>& runs, std::int64_t minEvents) {
  std::vector<ClosedGroup> closed;
  ClosedGroup current;
  for (const TakenRun& r : runs) {
    if (!current.runs.empty() && !sameEnergy(current.beamEnergy, r.beamEnergy)) {
      closed.push_back(std::move(current));
      current = {};
    }
    current.runs.push_back(r);
    if (std::isnan(current.beamEnergy)) current.beamEnergy = r.beamEnergy;
    current.selected += r.selected;
    if (current.selected >= minEvents) {
      closed.push_back(std::move(current));
      current = {};
    }
  }
  return closed;
}

Status Loop::decideClosed(PromptSummary& summary) {
  for (;;) {
    const auto groups = closedGroups(state_.open, o_.minEvents);
    if (groups.empty()) return {};
    if (Status s = decide(groups.front(), summary); !s) return s;
  }
}

Result<Loop::InForce> Loop::inForce(std::int64_t first) {
  auto iovs = db_->iovs(o_.tag);
  if (!iovs) return iovs.error();
  InForce f;
  for (const conddb::Iov& i : *iovs) {
    if (i.firstRun <= first) f.iov = i;
  }
  if (!iovs->empty()) f.lastRun = iovs->back().lastRun;
  return f;
}

Status Loop::decide(const ClosedGroup& g, PromptSummary& summary) {
  const auto group = static_cast<std::int64_t>(records_.size());
  const std::int32_t first = g.runs.front().run, last = g.runs.back().run;
  auto force = inForce(first);
  if (!force) return force.error();
  std::optional<conddb::Payload> forcePayload;
  if (force->iov) {
    auto p = db_->payload(force->iov->payload);
    if (!p) return p.error();
    forcePayload = std::move(*p);
  }
  GroupOutcome outcome;
  outcome.selected = g.selected;
  outcome.minEvents = o_.minEvents;
  if (forcePayload) outcome.inForce = forcePayload->values();
  std::optional<GroupFit> fit;
  if (Status s = fitForDecision(g, group, outcome, fit); !s) return s;
  const DecisionResult d = validation::decide(thresholds_, outcome);
  conddb::Database::PromptRecord record;
  record.group = group;
  record.thresholdsSha256 = thresholds_.sha256;
  record.thresholds = thresholds_.json.dump();
  const conddb::Payload* payload = d.decision == Decision::Update ? &fit->payload
                                   : forcePayload                 ? &*forcePayload
                                                                  : nullptr;
  std::optional<RunRange> iov;
  // From the run after the tag's last IOV: none when a promotion covered the group's runs.
  if (payload != nullptr && (!force->lastRun || last > *force->lastRun)) {
    iov = {force->lastRun ? *force->lastRun + 1 : first, last};
    record.iov = conddb::Database::NewIov{iov->first, iov->second, *payload};
  }
  const Json j = decisionJson(g, group, d, payload, iov, fit);
  record.decision = j.dump();
  if (Status s = db_->appendPrompt(o_.tag, record); !s) return s;
  return recordDecided(g, group, d, record, j, iov, summary);
}

Status Loop::fitForDecision(const ClosedGroup& g, std::int64_t group, GroupOutcome& outcome,
                            std::optional<GroupFit>& fit) {
  std::vector<std::string> files;
  // By name, as found in the watched directory, with their SHA-256: the same payload wherever
  // that directory is (an interrupted season against one run through elsewhere).
  for (const TakenRun& r : g.runs) {
    if (std::find(files.begin(), files.end(), r.file) == files.end()) files.push_back(r.file);
  }
  if (g.selected == 0 || std::isnan(g.beamEnergy)) {
    outcome.fitProblem = "no selected event";
    return {};
  }
  // A fill that cannot be had is this step's problem (tried again), never the group's veto.
  auto gm = model_.at(g.beamEnergy);
  auto fill = gm ? groupFill(g, gm->profile) : Result<calib::ProfileFill>(gm.error());
  if (!fill && gm) return fill.error();
  auto f = fill ? fitOf(g, group, files, *gm, *fill) : Result<GroupFit>(fill.error());
  if (f) {
    outcome.status = f->result.status;
    outcome.pValue = f->result.pValue;
    outcome.fitted = f->payload.values();
    fit = std::move(*f);
  } else {
    outcome.fitProblem = f.error().message;
  }
  return {};
}

Json Loop::decisionJson(const ClosedGroup& g, std::int64_t group, const DecisionResult& d,
                        const conddb::Payload* payload, const std::optional<RunRange>& iov,
                        const std::optional<GroupFit>& fit) {
  Json parameters = Json::object();
  for (const ParameterDecision& p : d.parameters) {
    parameters[std::string(name(p.parameter))] = {{"fitted", io::numberOrNull(p.fitted)},
                                                  {"error", io::numberOrNull(p.error)},
                                                  {"in_force", io::numberOrNull(p.inForce)},
                                                  {"change", io::numberOrNull(p.change)},
                                                  {"significance", io::numberOrNull(p.significance)}};
  }
  Json names = Json::object();  // the files of its runs, with their SHA-256
  for (const TakenRun& r : g.runs) names[r.file] = state_.files[r.file].sha256;
  return {{"group", group},
          {"runs", {g.runs.front().run, g.runs.back().run}},
          {"beam_energy_mev", energyJson(g.beamEnergy)},
          {"selected_events", g.selected},
          {"decision", name(d.decision)},
          {"reasons", d.reasons},
          {"parameters", parameters},
          {"payload", payload != nullptr ? Json(payload->hash()) : Json(nullptr)},
          {"iov", iov ? Json{iov->first, iov->second} : Json(nullptr)},
          {"fit_status", fit ? Json(std::string(emcalign::name(fit->result.status))) : Json(nullptr)},
          {"thresholds_sha256", thresholds_.sha256},
          {"min_events", o_.minEvents},
          {"files", names}};
}

Status Loop::recordDecided(const ClosedGroup& g, std::int64_t group, const DecisionResult& d,
                           const conddb::Database::PromptRecord& record, const Json& j,
                           const std::optional<RunRange>& iov, PromptSummary& summary) {
  const std::int32_t first = g.runs.front().run, last = g.runs.back().run;
  records_.push_back(record.decision);
  state_.decided = static_cast<std::int64_t>(records_.size());
  state_.decidedSha256 = decisionsDigest();
  lastDecidedRun_ = last;
  if (iov) lastIovRun_ = iov->second;
  ++summary.decided;
  say(fmt::format("group {} (runs {}-{}, {}, {} selected events): {} — {}", group, first, last,
                  std::isnan(g.beamEnergy) ? std::string("no beam energy") : fmt::format("{:g} MeV", g.beamEnergy),
                  g.selected, name(d.decision), fmt::join(d.reasons, "; ")));
  if (d.decision == Decision::Veto) pendingAlerts_.push_back({fmt::format("group {}", group), j});
  // The state after the database: a kill between finds the group decided there (catchUp).
  std::erase_if(state_.open, [&](const TakenRun& r) { return r.run <= last; });
  if (Status s = saveState(); !s) return s;
  for (const TakenRun& r : g.runs) {
    std::error_code ec;
    fs::remove(fillPath(r.run), ec);
  }
  if (Status s = writeDecisions(); !s) return s;
  return writeStatus();
}

// The merged fill of a group's runs, in run order: each run's kept fill, or — lost (removed,
// damaged) — its file read again when it still has the content taken.
Result<calib::ProfileFill> Loop::groupFill(const ClosedGroup& g, const calib::ProfileOptions& profile) {
  calib::ProfileFill fill = calib::ProfileFill::empty(profile);
  for (const TakenRun& r : g.runs) {
    auto text = io::readOwnOutput(fillPath(r.run));
    auto j = text ? io::parseJson(*text, fillPath(r.run)) : Result<Json>(text.error());
    auto f = j ? calib::ProfileFill::restore(*j, profile, fillPath(r.run)) : Result<calib::ProfileFill>(j.error());
    if (!f) {
      const std::string path = (fs::path(o_.watchDir) / r.file).string();
      auto sha = sha256OfFile(path);
      if (!sha || *sha != state_.files[r.file].sha256) {
        return Error{
            fmt::format("run {}: its kept fill is lost ({}) and its file {} no longer has the content "
                        "taken: restore either, or remove the run from {} (it is then never decided)",
                        r.run, f.error().message, r.file, statePath())};
      }
      auto again = calib::fillProfilesByRun(path, model_.depthAtEnergy(), model_.selection, profile);
      if (!again || !again->contains(r.run)) {
        return Error{fmt::format("run {}: its kept fill is lost and {} cannot be read again", r.run, r.file)};
      }
      say(fmt::format("run {}: its kept fill was lost: read again from {}", r.run, printable(r.file)));
      f = std::move(again->at(r.run));
    }
    fill.merge(*f);
  }
  return fill;
}

Result<GroupFit> Loop::fitOf(const ClosedGroup& g, std::int64_t group, const std::vector<std::string>& files,
                             const CampaignModel& gm, const calib::ProfileFill& fill) {
  std::map<std::string, std::string> digests;
  CampaignGroup cg;
  cg.index = static_cast<int>(group);
  cg.iovFirst = g.runs.front().run;
  cg.iovLast = g.runs.back().run;
  cg.beamEnergy = g.beamEnergy;
  cg.selected = g.selected;
  cg.isShort = g.selected < o_.minEvents;
  cg.files = files;
  for (const TakenRun& r : g.runs) {
    cg.runs.push_back(r.run);
    digests[r.file] = state_.files[r.file].sha256;
  }
  const Json origin = {{"prompt",
                        {{"group", group},
                         {"runs", cg.runs},
                         {"beam_energy_mev", g.beamEnergy},
                         {"selected_events", g.selected},
                         {"min_events", o_.minEvents},
                         {"short", cg.isShort}}}};
  return fitGroup(cg, fill, gm, digests, origin);
}

}  // namespace emcalign::validation::prompt
