// A calibration campaign's groups fitted and stored into a tag (validation/calibration_campaign.hpp):
// each group's fit and payload, what a tag holds already, and the campaign run in one process.

#include <algorithm>
#include <cmath>
#include <mutex>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "emcalign/calib/fit_notes.hpp"
#include "emcalign/validation/calibration_campaign.hpp"

namespace emcalign::validation {

using io::Json;

Json campaignOrigin(const CampaignGroup& g, std::int64_t minEvents, int groups) {
  return {{"campaign",
           {{"group", g.index},
            {"groups", groups},
            {"min_events", minEvents},
            {"runs", g.runs},
            {"beam_energy_mev", std::isnan(g.beamEnergy) ? Json(nullptr) : Json(g.beamEnergy)},
            {"short", g.isShort}}}};
}

Result<GroupFit> fitGroup(const CampaignGroup& g, const calib::ProfileFill& fill, const CampaignModel& model,
                          const std::map<std::string, std::string>& digests, const Json& origin) {
  if (fill.cutFlow.events.back() == 0) {
    return Error{fmt::format("group {} (runs {}-{}): no selected event", g.index, g.iovFirst, g.iovLast)};
  }
  auto result = calib::fitProfiles(fill.profiles, model.geometry, model.sigmaSys);
  if (!result)
    return Error{fmt::format("group {} (runs {}-{}): {}", g.index, g.iovFirst, g.iovLast, result.error().message)};
  calib::FitInput input;
  input.files = g.files;
  input.fill = &fill;
  input.detector = model.detector;
  input.depthOffset = model.geometry.depth.offset;
  if (model.profile.partingPlane) input.partingPlane = model.corrections;
  if (model.profile.nominalProfile) input.nominalProfile = model.corrections;
  if (model.geometry.response) input.response = model.corrections;
  input.correctionsInterpolation = model.interpolation;
  input.systematics = model.systematics;
  input.systematicsSource = model.corrections;
  Json resultJson = calib::fitResultJson(*result, input);
  // What a physicist must know of the fit travels with it (as emcalign fit's result).
  std::vector<std::string> notes = calib::fitNotes(
      *result, {.corrected = !model.corrections.empty(), .corrections = model.corrections, .depthOffset = 0.0});
  if (auto w = calib::rangeWarning(*result)) notes.push_back(*w);
  resultJson["notes"] = notes;
  Json sha = Json::object();
  for (const auto& f : g.files) {
    if (auto it = digests.find(f); it != digests.end() && !it->second.empty()) sha[f] = it->second;
  }
  Json provenance = origin;
  provenance["input_sha256"] = sha;
  if (!model.corrections.empty()) {
    provenance["corrections"] = model.corrections;
    provenance["corrections_sha256"] = model.correctionsSha256;
  }
  auto payload =
      conddb::makePayload(resultJson, model.geometry.radii.r1, fmt::format("group {}", g.index), std::move(provenance));
  if (!payload)
    return Error{fmt::format("group {} (runs {}-{}): {}", g.index, g.iovFirst, g.iovLast, payload.error().message)};
  return GroupFit{std::move(*result), std::move(resultJson), std::move(*payload)};
}

Result<bool> groupStored(conddb::Database& db, const std::string& tag, const CampaignGroup& g,
                         const std::map<std::string, std::string>& digests, const CampaignModel& model) {
  auto got = db.get(tag, g.iovFirst);
  if (!got) return got.error();
  if (!got->has_value()) return false;
  const auto& [iov, payload] = **got;
  const std::string group = fmt::format("group {} (runs {}-{})", g.index, g.iovFirst, g.iovLast);
  if (iov.firstRun != g.iovFirst || iov.lastRun != g.iovLast) {
    return Error{
        fmt::format("{}: tag '{}' holds the IOV {}-{} over its runs: not this campaign's grouping (write to a "
                    "new tag)",
                    group, tag, iov.firstRun, iov.lastRun)};
  }
  std::multiset<std::string> expected, stored;
  for (const auto& f : g.files) {
    auto it = digests.find(f);
    if (it == digests.end() || it->second.empty()) {
      return Error{fmt::format("{}: no SHA-256 of its file {} to compare with what tag '{}' holds", group, f, tag)};
    }
    expected.insert(it->second);
  }
  for (const auto& [file, sha] : payload.inputDigests()) stored.insert(sha);
  if (stored.empty()) {
    return Error{
        fmt::format("{}: tag '{}' holds its IOV from data whose digests it does not record (put by hand?): "
                    "cannot tell it is the same data; write to a new tag",
                    group, tag)};
  }
  if (stored != expected) {
    return Error{
        fmt::format("{}: tag '{}' holds its runs from other data (the SHA-256 of the files it was made from "
                    "differ from those of {}): the same run numbers, another data set; write to a new tag",
                    group, tag, g.files.size() == 1 ? g.files.front() : fmt::format("its {} files", g.files.size()))};
  }
  // One tag, one model: the same corrections (by digest) and the same choice of σ_sys.
  const std::string usedCorrections = payload.correctionsSha256();
  if (usedCorrections != model.correctionsSha256) {
    auto what = [](const std::string& sha) {
      return sha.empty() ? std::string("without corrections") : fmt::format("with corrections {}…", sha.substr(0, 12));
    };
    return Error{
        fmt::format("{}: tag '{}' holds it fitted {}, this campaign fits {}: one tag holds one model; write "
                    "to a new tag",
                    group, tag, what(usedCorrections), what(model.correctionsSha256))};
  }
  auto usedSigma = payload.sigmaSysChoice();
  if (!usedSigma) return Error{fmt::format("{}: tag '{}': {}", group, tag, usedSigma.error().message)};
  if (!calib::sameChoice(*usedSigma, model.sigmaSys)) {
    return Error{fmt::format(
        "{}: tag '{}' holds it fitted with sigma_sys {}, this campaign with {}: one tag holds "
        "one model; write to a new tag",
        group, tag, calib::sigmaSysChoiceJson(*usedSigma).dump(), calib::sigmaSysChoiceJson(model.sigmaSys).dump())};
  }
  return true;
}

Result<std::vector<bool>> groupsInTag(conddb::Database& db, const std::string& tag,
                                      const std::vector<CampaignGroup>& groups) {
  std::vector<bool> done(groups.size(), false);
  auto iovs = db.iovs(tag);
  if (!iovs) return iovs.error();
  for (const conddb::Iov& iov : *iovs) {
    auto it = std::lower_bound(groups.begin(), groups.end(), iov.firstRun,
                               [](const CampaignGroup& g, std::int64_t r) { return g.iovFirst < r; });
    if (it == groups.end() || it->iovFirst != iov.firstRun || it->iovLast != iov.lastRun) {
      return Error{
          fmt::format("{}: tag '{}' holds the IOV {}-{}, which is not one of this campaign's groups (another "
                      "--min-events, other files, another plan): write to a new tag",
                      db.uri(), tag, iov.firstRun, iov.lastRun)};
    }
    done[static_cast<std::size_t>(it - groups.begin())] = true;
  }
  return done;
}

Result<std::vector<bool>> checkCampaignTag(const CampaignScan& scan, const CampaignModel& model, conddb::Database& db,
                                           const std::string& tag, const std::vector<CampaignGroup>& groups) {
  if (auto t = db.tag(tag); !t) {
    return t.error();
  } else if (t->has_value() && (*t)->state == conddb::TagState::Running) {
    return Error{
        fmt::format("{}: tag '{}' is running (a prompt loop's: IOVs only appended by it): a campaign writes "
                    "a tag of its own",
                    db.uri(), tag)};
  } else if (t->has_value() && conddb::iovWrites((*t)->state) == conddb::IovWrites::None) {
    return Error{
        fmt::format("{}: tag '{}' is {}: {}", db.uri(), tag, name((*t)->state), conddb::whyNoIovs((*t)->state))};
  }
  auto done = groupsInTag(db, tag, groups);
  if (!done) return done.error();
  std::map<std::string, std::string> digests;
  for (std::size_t k = 0; k < scan.files.size(); ++k) digests[scan.files[k]] = scan.digests[k];
  // The groups stored already must be from this data (before any fit).
  for (std::size_t k = 0; k < groups.size(); ++k) {
    if (!(*done)[k]) continue;
    auto same = groupStored(db, tag, groups[k], digests, model);
    if (!same) return same.error();
  }
  return done;
}

namespace {

// What the groups fitted in parallel report, kept under one lock (one connection, one
// transaction at a time): in group order, whatever the threads.
struct CampaignTally {
  std::mutex mutex;
  std::set<std::string> corrWarnings;                   // a single corrections file away from its energy
  std::map<int, std::vector<std::string>> fitWarnings;  // by group
  std::map<int, std::string> outsideRanges;             // groups fitted outside the validated ranges
  int finished = 0;
};

// Group g fitted with the model at its energy; `warning`: the corrections' word on that energy.
Result<GroupFit> fitCampaignGroup(const CampaignGroup& g, const CampaignScan& scan, const CampaignModel& model,
                                  const std::map<std::string, std::string>& digests, std::int64_t minEvents, int groups,
                                  std::string& warning) {
  auto groupModel = model.at(g.beamEnergy);
  if (!groupModel)
    return Error{fmt::format("group {} (runs {}-{}): {}", g.index, g.iovFirst, g.iovLast, groupModel.error().message)};
  warning = groupModel->correctionsWarning;
  const calib::ProfileFill fill = scan.fillOf(g.iovFirst, g.iovLast, groupModel->profile);
  return fitGroup(g, fill, *groupModel, digests, campaignOrigin(g, minEvents, groups));
}

// Group g's fit stored into the tag (under the tally's lock): into the report and the tally; its
// status as the progress says it.
std::string storeCampaignGroup(const CampaignGroup& g, const Result<GroupFit>& fit, conddb::Database& db,
                               const std::string& tag, const std::map<std::string, std::string>& digests,
                               const CampaignModel& model, const CalibrationCampaignOptions& o, CampaignReport& report,
                               CampaignTally& tally) {
  if (!fit) {
    report.failures.push_back(fit.error().message);
    return "failed";
  }
  if (!usable(fit->result.status)) {
    report.failures.push_back(fmt::format("group {} (runs {}-{}): the fit's status is '{}': not stored", g.index,
                                          g.iovFirst, g.iovLast, name(fit->result.status)));
    return std::string(name(fit->result.status));
  }
  if (Status s = db.put(tag, g.iovFirst, g.iovLast, fit->payload, conddb::IfMissing::Create, o.description); !s) {
    // Another process may have stored this very group meanwhile (a batch retry).
    if (auto same = groupStored(db, tag, g, digests, model); same && *same) {
      ++report.resumed;
      return "stored by another process";
    }
    report.failures.push_back(
        fmt::format("group {} (runs {}-{}): {}", g.index, g.iovFirst, g.iovLast, s.error().message));
    return "not stored";
  }
  ++report.fitted;
  if (fit->result.status == FitStatus::PoorFit) {
    tally.fitWarnings[g.index].push_back(fmt::format("group {} (runs {}-{}): poor fit (chi2/ndf {:.1f}/{})", g.index,
                                                     g.iovFirst, g.iovLast, fit->result.chi2, fit->result.ndf));
  }
  if (auto outside = calib::outsideValidatedRanges(fit->result); !outside.empty()) {
    tally.outsideRanges[g.index] =
        fmt::format("group {} (runs {}-{}): {}", g.index, g.iovFirst, g.iovLast, fmt::join(outside, ", "));
  }
  return std::string(name(fit->result.status));
}

// The report's warnings: the fits', the groups outside the validated ranges, the corrections',
// the short groups'.
void warnOfCampaign(const std::vector<CampaignGroup>& groups, const CampaignTally& tally,
                    const CalibrationCampaignOptions& o, CampaignReport& report) {
  for (const auto& [index, warnings] : tally.fitWarnings)
    report.warnings.insert(report.warnings.end(), warnings.begin(), warnings.end());
  if (!tally.outsideRanges.empty()) {
    std::vector<std::string> groupsOutside;
    groupsOutside.reserve(tally.outsideRanges.size());
    for (const auto& [index, text] : tally.outsideRanges) groupsOutside.push_back(text);
    report.warnings.push_back(fmt::format(
        "{} of the groups fitted outside the ranges over which the model and its corrections were validated "
        "(their biases there are not known, docs/validation.md; a simulated truth in mm under a cm header is "
        "the usual mistake): {}",
        groupsOutside.size(), fmt::join(groupsOutside, "; ")));
  }
  report.warnings.insert(report.warnings.end(), tally.corrWarnings.begin(), tally.corrWarnings.end());
  for (const CampaignGroup& g : groups) {
    if (g.isShort) {
      report.warnings.push_back(fmt::format(
          "group {} (runs {}-{}{}): {} selected events, fewer than {} ({})", g.index, g.iovFirst, g.iovLast,
          std::isnan(g.beamEnergy) ? "" : fmt::format(", {:.1f} MeV", g.beamEnergy), g.selected, o.minEvents,
          std::isnan(g.beamEnergy) ? "none of its events is selected" : "its energy point has no more"));
    }
  }
}

}  // namespace

Result<CampaignReport> runCampaign(const CampaignScan& scan, const CampaignModel& model, conddb::Database& db,
                                   const std::string& tag, const CalibrationCampaignOptions& o) {
  const std::vector<CampaignGroup> groups = planGroups(scan, o.minEvents);
  CampaignReport report;
  report.groups = static_cast<int>(groups.size());
  auto done = checkCampaignTag(scan, model, db, tag, groups);
  if (!done) return done.error();
  std::vector<std::size_t> todo;
  for (std::size_t k = 0; k < groups.size(); ++k) {
    if ((*done)[k]) {
      ++report.resumed;
    } else {
      todo.push_back(k);
    }
  }
  std::map<std::string, std::string> digests;
  for (std::size_t k = 0; k < scan.files.size(); ++k) digests[scan.files[k]] = scan.digests[k];

  CampaignTally tally;
  const int threads = o.threads > 0 ? o.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  arena.execute([&] {
    tbb::parallel_for(
        std::size_t{0}, todo.size(),
        [&](std::size_t t) {
          const CampaignGroup& g = groups[todo[t]];
          // The group's IOV holds exactly its runs (the IOVs tile the scanned runs), of one energy.
          std::string warning;
          const auto fit =
              fitCampaignGroup(g, scan, model, digests, o.minEvents, static_cast<int>(groups.size()), warning);
          std::lock_guard lock(tally.mutex);
          if (!warning.empty()) tally.corrWarnings.insert(warning);
          const std::string status = storeCampaignGroup(g, fit, db, tag, digests, model, o, report, tally);
          ++tally.finished;
          if (o.progress) o.progress(tally.finished, static_cast<int>(todo.size()), g, status);
        },
        tbb::simple_partitioner());
  });
  warnOfCampaign(groups, tally, o, report);
  std::sort(report.failures.begin(), report.failures.end());
  return report;
}

}  // namespace emcalign::validation
