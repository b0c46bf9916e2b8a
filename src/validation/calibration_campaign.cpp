// A calibration campaign's runs (validation/calibration_campaign.hpp): its event files, the model
// they are fitted with, each run's fill read from them, and the runs grouped into IOVs.

#include "emcalign/validation/calibration_campaign.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <limits>
#include <mutex>
#include <optional>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "calibration_campaign_internal.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/io/data_directory.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::validation {

namespace fs = std::filesystem;

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

}  // namespace

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

Result<std::vector<std::string>> eventFilesIn(const std::vector<std::string>& inputs) {
  std::vector<std::string> files;
  for (const auto& in : inputs) {
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      // simulate --period writes truth.json after its last run: without it, runs are missing.
      if (fs::exists(fs::path(in) / "period.json", ec) && !fs::exists(fs::path(in) / "truth.json", ec)) {
        return Error{fmt::format(
            "{}: a simulated period not finished (period.json, and no truth.json: simulate --period was stopped "
            "before its last run): run the same simulate --period again to complete it",
            in)};
      }
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

namespace {

using RunFills = std::map<std::int32_t, calib::ProfileFill>;

// Each file's runs filled (and the event numbers of each run), the files in parallel; the
// first file that cannot be read, in the files' order, is the error. Each file is decoded by a
// child process (io/event_file.hpp) while its reader selects: one reader per core keeps the
// cores busy (measured on the SND-like period: 15 s with two readers, 24 s with one, 21 s with
// four). Under a sanitizer there is one reader: a child forked while another thread holds the
// sanitizer's allocator lock (gcc 12's libsanitizer does not take it at fork, unlike glibc's
// malloc) would wait for it for ever.
Result<std::vector<RunFills>> fillEachFile(const std::vector<std::string>& files, const CampaignModel& model,
                                           const ScanOptions& o, int threads,
                                           std::vector<std::map<std::int32_t, io::EventNumbers>>& eventsOf) {
  std::vector<std::optional<Result<RunFills>>> perFile(files.size());
  std::atomic<std::size_t> done{0};
  std::mutex progressMutex;
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
  std::vector<RunFills> fills;
  fills.reserve(files.size());
  for (std::size_t k = 0; k < files.size(); ++k) {
    if (!perFile[k]->ok()) return perFile[k]->error();
    fills.push_back(std::move(**perFile[k]));
  }
  return fills;
}

// The files' SHA-256 into `digests`, in parallel once no child is started any more; each file's
// error ("" for none).
std::vector<std::string> digestEachFile(const std::vector<std::string>& files, int threads,
                                        std::vector<std::string>& digests) {
  std::vector<std::string> errors(files.size());
  tbb::task_arena digestArena(threads);
  digestArena.execute([&] {
    tbb::parallel_for(std::size_t{0}, files.size(), [&](std::size_t k) {
      auto d = sha256OfFile(files[k]);
      if (d) {
        digests[k] = *d;
      } else {
        errors[k] = d.error().message;
      }
    });
  });
  return errors;
}

// The files' runs merged into the scan's, in the order of the files (the same result on any
// number of threads); a run of two beam energies is refused.
Status mergeRuns(const std::vector<std::string>& files, std::vector<RunFills> fills, CampaignScan& scan) {
  std::map<std::int32_t, CampaignRun> runs;
  for (std::size_t k = 0; k < files.size(); ++k) {
    for (auto& [run, fill] : fills[k]) {
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
    if (run < 0) {  // an IOV's runs are 0 or more: none could be stored, nor read back
      return Error{
          fmt::format("{}: run {}: a run number is 0 or more (the conditions database stores no other): the "
                      "files' run column is wrong",
                      files[r.files.front()], run)};
    }
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
  return {};
}

}  // namespace

Result<CampaignScan> scanRuns(const std::vector<std::string>& files, const CampaignModel& model, const ScanOptions& o) {
  if (files.empty()) return Error{"no event files to calibrate"};
  CampaignScan scan;
  scan.files = files;
  scan.digests.assign(files.size(), "");
  std::vector<std::map<std::int32_t, io::EventNumbers>> eventsOf(files.size());
  const int threads = o.threads > 0 ? o.threads : tbb::this_task_arena::max_concurrency();
  auto fills = fillEachFile(files, model, o, threads, eventsOf);
  if (!fills) return fills.error();
  std::vector<std::string> digestErrors(files.size());
  if (o.digests) digestErrors = digestEachFile(files, threads, scan.digests);
  if (Status s = eachEventOnce(files, scan.digests, eventsOf); !s) return s.error();
  for (const std::string& e : digestErrors) {
    if (!e.empty()) return Error{e};
  }
  if (Status s = mergeRuns(files, std::move(*fills), scan); !s) return s.error();
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

}  // namespace emcalign::validation
