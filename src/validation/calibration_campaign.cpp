#include "emcalign/validation/calibration_campaign.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <limits>
#include <mutex>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "emcalign/calib/fit_notes.hpp"
#include "emcalign/conddb/address.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/data_directory.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/io/strict_json.hpp"

namespace emcalign::validation {

namespace fs = std::filesystem;
using io::Json;

namespace {

constexpr double kNoEnergy = std::numeric_limits<double>::quiet_NaN();

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif

bool sameEnergy(double a, double b) { return std::isnan(a) || std::isnan(b) || a == b; }

bool isSha256(const std::string& s) {
  return s.size() == 64 &&
         std::all_of(s.begin(), s.end(), [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

// Every event in one file only, as one reader of all the files demands (io/event_file.hpp):
// a copy of a file is named by its digest, another file holding the same events (a corrected
// copy, another version) by the first event the two share.
Status eachEventOnce(const std::vector<std::string>& files, const std::vector<std::string>& digests,
                     const std::vector<std::map<std::int32_t, io::EventNumbers>>& eventsOf) {
  std::map<std::string, std::size_t> byDigest;
  for (std::size_t k = 0; k < files.size(); ++k) {
    if (digests[k].empty()) continue;
    auto [it, fresh] = byDigest.emplace(digests[k], k);
    if (!fresh) {
      return Error{fmt::format("{}: has the same content as {} (SHA-256 {}…): a copy, whose events would count twice",
                               files[k], files[it->second], digests[k].substr(0, 12))};
    }
  }
  std::map<std::int32_t, std::vector<std::size_t>> filesOfRun;
  for (std::size_t k = 0; k < files.size(); ++k) {
    for (const auto& [run, numbers] : eventsOf[k]) filesOfRun[run].push_back(k);
  }
  for (const auto& [run, ks] : filesOfRun) {
    for (std::size_t a = 0; a < ks.size(); ++a) {
      for (std::size_t b = a + 1; b < ks.size(); ++b) {
        const auto common = eventsOf[ks[a]].at(run).firstCommon(eventsOf[ks[b]].at(run));
        if (!common) continue;
        return Error{fmt::format(
            "run {} event {} is in {} and in {}: each event must appear once (a copy, a corrected copy or another "
            "version of a file beside it?)",
            run, *common, files[ks[a]], files[ks[b]])};
      }
    }
  }
  return {};
}

}  // namespace

Result<std::vector<std::string>> eventFilesIn(const std::vector<std::string>& inputs) {
  std::vector<std::string> files;
  for (const auto& in : inputs) {
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      auto listed = io::dataFilesIn(in, {".h5", ".hdf5", ".csv"}, "an event file");
      if (!listed) return listed.error();
      if (listed->empty()) return Error{fmt::format("{}: no event files (*.h5, *.hdf5, *.csv) in this directory", in)};
      files.insert(files.end(), listed->begin(), listed->end());
    } else {
      if (io::isTemporaryName(fs::path(in).filename().string())) {
        return Error{
            fmt::format("{}: a temporary file of an emcalign command (being written, or left by one that "
                        "was killed), not event data",
                        in)};
      }
      files.push_back(in);
    }
  }
  for (auto& f : files) f = fs::absolute(f).lexically_normal().string();
  // A file given twice (by two names, or as a file and inside its directory) counts once.
  std::vector<std::pair<std::pair<dev_t, ino_t>, std::size_t>> ids;
  for (std::size_t k = 0; k < files.size(); ++k) {
    struct stat st {};
    if (::stat(files[k].c_str(), &st) != 0) continue;  // the reader says why
    for (const auto& [id, j] : ids) {
      if (id == std::pair{st.st_dev, st.st_ino}) {
        return Error{files[k] == files[j]
                         ? fmt::format("{}: given twice (by name, and inside a directory given?): its events would "
                                       "count twice",
                                       files[k])
                         : fmt::format("{}: is the same file as {} (given twice?): its events would count twice",
                                       files[k], files[j])};
      }
    }
    ids.push_back({{st.st_dev, st.st_ino}, k});
  }
  return files;
}

Result<CampaignModel> campaignModel(const std::string& corrections, const std::string& detector,
                                    const geometry::Calorimeter& calo) {
  CampaignModel m;
  m.geometry = calib::FitGeometry::of(calo.description());
  m.profile.eventPairs = true;  // the statistical errors take the event pairs' correlation along
  m.detector = io::detectorName(detector);
  if (!corrections.empty()) {
    auto grid = calib::CorrectionsGrid::read(corrections);
    if (!grid) return grid.error();
    m.grid = std::make_shared<const calib::CorrectionsGrid>(std::move(*grid));
    if (!m.grid->isGrid()) {  // a grid's corrections depend on the energy: at()
      m.geometry.apply(m.grid->points().front().corrections);
      m.profile.apply(m.grid->points().front().corrections);
      m.systematics = m.grid->points().front().corrections.systematics;
    }
    m.corrections = corrections;
    m.correctionsSha256 = m.grid->sha256();
  }
  if (Status s = m.profile.validate(); !s) {
    return Error{corrections.empty() ? s.error().message : fmt::format("{}: {}", corrections, s.error().message)};
  }
  return m;
}

Result<CampaignModel> CampaignModel::at(double beamEnergy) const {
  if (!grid) return *this;
  if (std::isnan(beamEnergy) && grid->isGrid()) {
    return Error{
        fmt::format("no selected event, so no beam energy to take the corrections of the grid {} at", grid->path())};
  }
  auto c = grid->at(beamEnergy);
  if (!c) return c.error();
  CampaignModel m = *this;
  m.correctionsWarning = c->warning;
  if (!grid->isGrid()) return m;
  m.geometry.apply(c->corrections);
  m.profile.apply(c->corrections);
  m.interpolation = c->interpolation;
  m.systematics = c->corrections.systematics;
  return m;
}

geometry::DepthAtEnergy CampaignModel::depthAtEnergy() const {
  if (!grid || !grid->isGrid()) return geometry::atEveryEnergy(geometry.depth);
  return calib::depthAtEnergy(grid, geometry.depth);
}

Result<CampaignScan> scanRuns(const std::vector<std::string>& files, const CampaignModel& model, const ScanOptions& o) {
  if (files.empty()) return Error{"no event files to calibrate"};
  CampaignScan scan;
  scan.files = files;
  scan.digests.assign(files.size(), "");
  std::vector<std::optional<Result<std::map<std::int32_t, calib::ProfileFill>>>> perFile(files.size());
  std::vector<std::map<std::int32_t, io::EventNumbers>> eventsOf(files.size());
  std::vector<std::string> digestErrors(files.size());
  // Each file is decoded by a child process (io/event_file.hpp) while its reader selects:
  // one reader per core keeps the cores busy (measured on the SND-like period: 15 s with two
  // readers, 24 s with one, 21 s with four). Under a sanitizer there is one reader: a child
  // forked while another thread holds the sanitizer's allocator lock (gcc 12's libsanitizer
  // does not take it at fork, unlike glibc's malloc) would wait for it for ever.
  std::atomic<std::size_t> done{0};
  std::mutex progressMutex;
  const int threads = o.threads > 0 ? o.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(kSanitized ? 1 : threads);
  arena.execute([&] {
    tbb::parallel_for(
        std::size_t{0}, files.size(),
        [&](std::size_t k) {
          perFile[k] =
              calib::fillProfilesByRun(files[k], model.depthAtEnergy(), model.selection, model.profile, &eventsOf[k]);
          const std::size_t n = ++done;
          if (o.progress) {
            std::lock_guard lock(progressMutex);
            o.progress(n, files.size());
          }
        },
        tbb::simple_partitioner());
  });
  for (std::size_t k = 0; k < files.size(); ++k) {
    if (!perFile[k]->ok()) return perFile[k]->error();
  }
  // The digests, in parallel once no child is started any more.
  if (o.digests) {
    tbb::task_arena digestArena(threads);
    digestArena.execute([&] {
      tbb::parallel_for(std::size_t{0}, files.size(), [&](std::size_t k) {
        auto d = sha256OfFile(files[k]);
        if (d) {
          scan.digests[k] = *d;
        } else {
          digestErrors[k] = d.error().message;
        }
      });
    });
  }
  if (Status s = eachEventOnce(files, scan.digests, eventsOf); !s) return s.error();
  // Merged in the order of the files: the same result on any number of threads.
  std::map<std::int32_t, CampaignRun> runs;
  for (std::size_t k = 0; k < files.size(); ++k) {
    if (!perFile[k]->ok()) return perFile[k]->error();
    if (!digestErrors[k].empty()) return Error{digestErrors[k]};
    for (auto& [run, fill] : **perFile[k]) {
      auto [it, fresh] = runs.try_emplace(run);
      CampaignRun& r = it->second;
      if (fresh) {
        r.run = run;
        r.fill = std::move(fill);
      } else {
        r.fill.merge(fill);
      }
      r.files.push_back(k);
    }
  }
  if (runs.empty()) {
    return Error{files.size() == 1 ? fmt::format("{}: no events", files[0])
                                   : fmt::format("no events in the {} files ({}, ...)", files.size(), files[0])};
  }
  for (auto& [run, r] : runs) {
    if (r.fill.beamEnergies.size() > 1) {
      std::vector<std::string> names;
      for (std::size_t f : r.files) names.push_back(files[f]);
      return Error{
          fmt::format("run {}: selected events of {} beam energies ({:.3f} ... {:.3f} MeV) in {}: a run has "
                      "one (files of two runs with one number?)",
                      run, r.fill.beamEnergies.size(), *r.fill.beamEnergies.begin(), *r.fill.beamEnergies.rbegin(),
                      fmt::join(names, ", "))};
    }
    r.beamEnergy = r.fill.beamEnergies.empty() ? kNoEnergy : *r.fill.beamEnergies.begin();
    r.selected = r.fill.cutFlow.events.back();
    scan.runs.push_back(std::move(r));
  }
  return scan;
}

std::vector<std::string> CampaignScan::filesOf(std::int64_t first, std::int64_t last) const {
  std::vector<std::size_t> indices;
  for (const CampaignRun& r : runs) {
    if (r.run >= first && r.run <= last) indices.insert(indices.end(), r.files.begin(), r.files.end());
  }
  std::sort(indices.begin(), indices.end());
  indices.erase(std::unique(indices.begin(), indices.end()), indices.end());
  std::vector<std::string> out;
  out.reserve(indices.size());
  for (std::size_t f : indices) out.push_back(files[f]);
  return out;
}

double CampaignScan::meanBeamEnergy(std::int64_t first, std::int64_t last) const {
  double sum = 0.0;
  std::int64_t n = 0;
  for (const CampaignRun& r : runs) {
    if (r.run < first || r.run > last || r.selected == 0) continue;
    sum += r.beamEnergy * static_cast<double>(r.selected);
    n += r.selected;
  }
  return n > 0 ? sum / static_cast<double>(n) : kNoEnergy;
}

calib::ProfileFill CampaignScan::fillOf(std::int64_t first, std::int64_t last, const calib::ProfileOptions& options,
                                        std::vector<std::int32_t>* runsFound) const {
  calib::ProfileFill fill = calib::ProfileFill::empty(options);
  for (const CampaignRun& r : runs) {
    if (r.run < first || r.run > last) continue;
    fill.merge(r.fill);
    if (runsFound != nullptr) runsFound->push_back(r.run);
  }
  return fill;
}

std::vector<CampaignGroup> planGroups(const CampaignScan& scan, std::int64_t minEvents) {
  // Groups of consecutive runs of one energy, closed when they reach minEvents.
  struct Draft {
    std::size_t begin = 0, end = 0;  // runs [begin, end)
    double energy = kNoEnergy;
    std::int64_t selected = 0;
  };
  std::vector<Draft> drafts;
  const auto& runs = scan.runs;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const CampaignRun& r = runs[i];
    const bool open = !drafts.empty() && drafts.back().end == i && drafts.back().selected < minEvents &&
                      sameEnergy(drafts.back().energy, r.beamEnergy);
    if (!open) drafts.push_back({i, i, kNoEnergy, 0});
    Draft& d = drafts.back();
    d.end = i + 1;
    d.selected += r.selected;
    if (std::isnan(d.energy)) d.energy = r.beamEnergy;
  }
  // A short group joins a neighbour of its energy: the previous one, else the next one.
  for (std::size_t k = 0; k < drafts.size();) {
    if (drafts[k].selected >= minEvents || drafts.size() == 1) {
      ++k;
      continue;
    }
    const bool prev = k > 0 && sameEnergy(drafts[k - 1].energy, drafts[k].energy);
    const bool next = k + 1 < drafts.size() && sameEnergy(drafts[k + 1].energy, drafts[k].energy);
    if (!prev && !next) {
      ++k;
      continue;
    }
    const std::size_t into = prev ? k - 1 : k + 1;
    Draft& d = drafts[into];
    d.begin = std::min(d.begin, drafts[k].begin);
    d.end = std::max(d.end, drafts[k].end);
    d.selected += drafts[k].selected;
    if (std::isnan(d.energy)) d.energy = drafts[k].energy;
    drafts.erase(drafts.begin() + static_cast<std::ptrdiff_t>(k));
    if (prev) continue;  // the merged group may now be long enough; look at the next
  }
  std::vector<CampaignGroup> groups;
  for (std::size_t k = 0; k < drafts.size(); ++k) {
    const Draft& d = drafts[k];
    CampaignGroup g;
    g.index = static_cast<int>(k);
    g.iovFirst = runs[d.begin].run;
    g.iovLast = k + 1 < drafts.size() ? std::int64_t{runs[drafts[k + 1].begin].run} - 1 : runs[d.end - 1].run;
    g.beamEnergy = d.energy;
    g.selected = d.selected;
    g.isShort = d.selected < minEvents;
    for (std::size_t i = d.begin; i < d.end; ++i) g.runs.push_back(runs[i].run);
    g.files = scan.filesOf(runs[d.begin].run, runs[d.end - 1].run);
    groups.push_back(std::move(g));
  }
  return groups;
}

Json planJson(const CampaignScan& scan, const std::vector<CampaignGroup>& groups, std::int64_t minEvents,
              const CampaignModel& model) {
  Json inputs = Json::array();
  for (std::size_t k = 0; k < scan.files.size(); ++k) {
    inputs.push_back({{"file", scan.files[k]}, {"sha256", scan.digests[k]}});
  }
  Json list = Json::array();
  for (const CampaignGroup& g : groups) {
    list.push_back({{"group", g.index},
                    {"iov", {g.iovFirst, g.iovLast}},
                    {"runs", g.runs},
                    {"files", g.files},
                    {"beam_energy_mev", std::isnan(g.beamEnergy) ? Json(nullptr) : Json(g.beamEnergy)},
                    {"selected_events", g.selected},
                    {"short", g.isShort}});
  }
  return {{"format", kCampaignPlanFormat},
          {"software", fmt::format("emcalign {}", kVersion)},
          {"min_events", minEvents},
          {"corrections", model.corrections},
          {"corrections_sha256", model.correctionsSha256},
          {"detector", model.detector},
          {"sigma_sys", calib::sigmaSysChoiceJson(model.sigmaSys)},
          {"inputs", inputs},
          {"groups", list}};
}

Result<CampaignPlan> parseCampaignPlan(const Json& data, const std::string& path) {
  const Json* j = &data;
  try {
    using io::strict::StrictObject;
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
    if (top.has("sigma_sys")) {
      StrictObject s(top.at("sigma_sys"), "sigma_sys", path);
      s.allowOnly({"method", "value_deg"});
      const bool fixed = s.string("method") == "fixed";
      if (fixed) (void)s.number("value_deg");  // checked to be a number; the value read below
      auto choice = calib::sigmaSysChoiceFromJson(top.at("sigma_sys"));
      if (!choice) s.fail(s.pathOf(fixed ? "value_deg" : "method"), choice.error().message);
      plan.sigmaSys = *choice;
    }
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
    const Json& groups = top.at("groups");
    if (!groups.is_array() || groups.empty()) top.fail("groups", "expected a non-empty list");
    for (std::size_t i = 0; i < groups.size(); ++i) {
      const std::string where = fmt::format("groups[{}]", i);
      StrictObject g(groups[i], where, path);
      g.allowOnly({"group", "iov", "runs", "files", "beam_energy_mev", "selected_events", "short"});
      CampaignGroup group;
      auto index = io::integerIn(g.at("group"), 0, 10'000'000, path, where + ".group");
      if (!index) return index.error();
      if (*index != static_cast<std::int64_t>(i)) g.fail(g.pathOf("group"), fmt::format("expected {}", i));
      group.index = static_cast<int>(*index);
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
      plan.groups.push_back(std::move(group));
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

Result<StoredGroup> storePlannedGroup(const CampaignPlan& plan, const CampaignModel& model, int index,
                                      const std::string& uri, const std::string& tag, const std::string& description) {
  if (index < 0 || index >= static_cast<int>(plan.groups.size())) {
    return Error{fmt::format("group {}: the plan has groups 0 to {}", index, plan.groups.size() - 1)};
  }
  const CampaignGroup& g = plan.groups[static_cast<std::size_t>(index)];
  // A new SQLite file is created when the group is fitted, to store it; kept even if the put
  // fails: the plan's other tasks may be storing into it at the same time.
  std::unique_ptr<conddb::Database> db;
  const std::string file = conddb::sqliteFileOf(uri);
  std::error_code ec;
  if (file.empty() || fs::exists(fs::symlink_status(file, ec))) {
    auto opened = conddb::Database::open(uri, conddb::IfMissing::Create);
    if (!opened) return opened.error();
    db = std::move(*opened);
    auto done = groupsInTag(*db, tag, plan.groups);
    if (!done) return done.error();
    if ((*done)[static_cast<std::size_t>(index)]) {
      // A retried task: done, if the tag holds this group from the same data.
      auto same = groupStored(*db, tag, g, plan.digests, model);
      if (!same) return same.error();
      return StoredGroup{fmt::format("group {} (runs {}-{}) is in tag {} already, from the same data: nothing to do",
                                     g.index, g.iovFirst, g.iovLast, tag),
                         {}};
    }
  }
  // The files must be those the plan was made from (the plan has a digest of each).
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
  if (fit->result.status == FitStatus::PoorFit) {
    stored.warnings.push_back(
        fmt::format("{}: poor fit (chi2/ndf {:.1f}/{})", group, fit->result.chi2, fit->result.ndf));
  }
  if (auto outside = calib::outsideValidatedRanges(fit->result); !outside.empty()) {
    stored.warnings.push_back(fmt::format(
        "{}: fitted outside the ranges over which the model and its corrections were validated (its biases there "
        "are not known, docs/validation.md; a simulated truth in mm under a cm header is the usual mistake): {}",
        group, fmt::join(outside, ", ")));
  }
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

  std::mutex dbMutex;                                   // one connection, one transaction at a time
  std::set<std::string> corrWarnings;                   // a single corrections file away from its energy
  std::map<int, std::vector<std::string>> fitWarnings;  // by group: in group order, whatever the threads
  std::map<int, std::string> outsideRanges;             // groups fitted outside the validated ranges
  int finished = 0;
  const int threads = o.threads > 0 ? o.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  arena.execute([&] {
    tbb::parallel_for(
        std::size_t{0}, todo.size(),
        [&](std::size_t t) {
          const CampaignGroup& g = groups[todo[t]];
          // The group's IOV holds exactly its runs (the IOVs tile the scanned runs), of one energy.
          std::string warning;
          auto fit = [&]() -> Result<GroupFit> {
            auto groupModel = model.at(g.beamEnergy);
            if (!groupModel)
              return Error{
                  fmt::format("group {} (runs {}-{}): {}", g.index, g.iovFirst, g.iovLast, groupModel.error().message)};
            warning = groupModel->correctionsWarning;
            const calib::ProfileFill fill = scan.fillOf(g.iovFirst, g.iovLast, groupModel->profile);
            return fitGroup(g, fill, *groupModel, digests,
                            campaignOrigin(g, o.minEvents, static_cast<int>(groups.size())));
          }();
          std::lock_guard lock(dbMutex);
          if (!warning.empty()) corrWarnings.insert(warning);
          std::string status;
          if (!fit) {
            report.failures.push_back(fit.error().message);
            status = "failed";
          } else if (!usable(fit->result.status)) {
            report.failures.push_back(fmt::format("group {} (runs {}-{}): the fit's status is '{}': not stored",
                                                  g.index, g.iovFirst, g.iovLast, name(fit->result.status)));
            status = std::string(name(fit->result.status));
          } else if (Status s =
                         db.put(tag, g.iovFirst, g.iovLast, fit->payload, conddb::IfMissing::Create, o.description);
                     !s) {
            // Another process may have stored this very group meanwhile (a batch retry).
            if (auto same = groupStored(db, tag, g, digests, model); same && *same) {
              ++report.resumed;
              status = "stored by another process";
            } else {
              report.failures.push_back(
                  fmt::format("group {} (runs {}-{}): {}", g.index, g.iovFirst, g.iovLast, s.error().message));
              status = "not stored";
            }
          } else {
            ++report.fitted;
            status = std::string(name(fit->result.status));
            if (fit->result.status == FitStatus::PoorFit) {
              fitWarnings[g.index].push_back(fmt::format("group {} (runs {}-{}): poor fit (chi2/ndf {:.1f}/{})",
                                                         g.index, g.iovFirst, g.iovLast, fit->result.chi2,
                                                         fit->result.ndf));
            }
            if (auto outside = calib::outsideValidatedRanges(fit->result); !outside.empty()) {
              outsideRanges[g.index] =
                  fmt::format("group {} (runs {}-{}): {}", g.index, g.iovFirst, g.iovLast, fmt::join(outside, ", "));
            }
          }
          ++finished;
          if (o.progress) o.progress(finished, static_cast<int>(todo.size()), g, status);
        },
        tbb::simple_partitioner());
  });
  for (auto& [index, warnings] : fitWarnings)
    report.warnings.insert(report.warnings.end(), warnings.begin(), warnings.end());
  if (!outsideRanges.empty()) {
    std::vector<std::string> groupsOutside;
    groupsOutside.reserve(outsideRanges.size());
    for (const auto& [index, text] : outsideRanges) groupsOutside.push_back(text);
    report.warnings.push_back(fmt::format(
        "{} of the groups fitted outside the ranges over which the model and its corrections were validated "
        "(their biases there are not known, docs/validation.md; a simulated truth in mm under a cm header is "
        "the usual mistake): {}",
        groupsOutside.size(), fmt::join(groupsOutside, "; ")));
  }
  report.warnings.insert(report.warnings.end(), corrWarnings.begin(), corrWarnings.end());
  for (const CampaignGroup& g : groups) {
    if (g.isShort) {
      report.warnings.push_back(fmt::format(
          "group {} (runs {}-{}{}): {} selected events, fewer than {} ({})", g.index, g.iovFirst, g.iovLast,
          std::isnan(g.beamEnergy) ? "" : fmt::format(", {:.1f} MeV", g.beamEnergy), g.selected, o.minEvents,
          std::isnan(g.beamEnergy) ? "none of its events is selected" : "its energy point has no more"));
    }
  }
  std::sort(report.failures.begin(), report.failures.end());
  return report;
}

}  // namespace emcalign::validation
