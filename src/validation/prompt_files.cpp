// The prompt loop's watched directory (validation/prompt.hpp): its settled files read and their
// runs taken, or quarantined; a taken file rewritten is said once and never taken again.

#include <sys/stat.h>

#include <algorithm>
#include <chrono>
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

std::int64_t nowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

std::optional<Seen> seen(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    if (::lstat(path.c_str(), &st) != 0) return std::nullopt;  // vanished
    Seen link{false, true, static_cast<std::int64_t>(st.st_size),
              static_cast<std::int64_t>(st.st_mtim.tv_sec) * 1'000'000'000 + st.st_mtim.tv_nsec,
              static_cast<std::uint64_t>(st.st_ino)};
    return link;
  }
  return Seen{S_ISREG(st.st_mode), false, static_cast<std::int64_t>(st.st_size),
              static_cast<std::int64_t>(st.st_mtim.tv_sec) * 1'000'000'000 + st.st_mtim.tv_nsec,
              static_cast<std::uint64_t>(st.st_ino)};
}

Status Loop::writeQuarantine() {
  Json list = Json::array();
  for (const auto& [name, f] : state_.files) {
    if (f.status == "quarantined") list.push_back({{"file", name}, {"reason", f.reason}});
  }
  return io::writeFileIn(o_.stateDir, "quarantine.json", list.dump(1) + "\n");
}

void Loop::quarantine(const std::string& name, const Seen& s, const std::string& sha, const std::string& reason,
                      PromptSummary& summary) {
  FileEntry& f = state_.files[name];
  f = {s.size, s.mtimeNs, s.inode, sha, "quarantined", {}, core::withoutAnyPassword(printable(reason))};
  ++summary.quarantined;
  say(fmt::format("{}: quarantined: {}", printable(name), f.reason));
}

// The settled files of the watched directory, taken in the order of their runs.
Status Loop::takeFiles(PromptSummary& summary) {
  auto names = watchedNames();
  if (!names) return names.error();
  std::vector<Read> read;
  bool changed = false;
  for (const std::string& rawName : *names) {
    if (o_.stop != nullptr && o_.stop->load()) break;  // SIGTERM: the rest at the next start
    look(rawName, read, changed, summary);
  }
  // In the order of their runs: a group is formed the same whatever batch a file came in.
  std::sort(read.begin(), read.end(), [](const Read& a, const Read& b) {
    const std::int32_t ra = a.runs.empty() ? 0 : a.runs.begin()->first;
    const std::int32_t rb = b.runs.empty() ? 0 : b.runs.begin()->first;
    return ra != rb ? ra < rb : a.name < b.name;
  });
  for (Read& r : read) {
    if (Status s = take(r.name, r.seen, r.sha, r.runs, summary); !s) return s;
    changed = true;
  }
  std::error_code ec;
  const std::string page = (fs::path(o_.stateDir) / "status.html").string();
  if (!changed && fs::exists(page, ec)) return {};
  if (Status s = saveState(); !s) return s;
  if (Status s = writeQuarantine(); !s) return s;
  return writeStatus();
}

Result<std::vector<std::string>> Loop::watchedNames() const {
  std::error_code ec;
  std::vector<std::string> names;
  for (fs::directory_iterator it(o_.watchDir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!isPromptTemporary(name) && !io::isTemporaryName(name)) names.push_back(name);
  }
  if (ec) return Error{fmt::format("{}: cannot list the directory: {}", o_.watchDir, ec.message())};
  std::sort(names.begin(), names.end());
  return names;
}

void Loop::look(const std::string& rawName, std::vector<Read>& read, bool& changed, PromptSummary& summary) {
  const std::string path = (fs::path(o_.watchDir) / rawName).string();
  const auto before = seen(path);
  if (!before) return;  // vanished
  // Named in JSON (state, decisions, quarantine): a name that is not UTF-8 is never read.
  const bool utf8 = isValidUtf8(rawName);
  const std::string name = utf8 ? rawName : printable(rawName) + " (a name that is not UTF-8)";
  const auto known = state_.files.find(name);
  if (known != state_.files.end() && known->second.size == before->size && known->second.mtimeNs == before->mtimeNs &&
      known->second.inode == before->inode) {
    return;  // as it was taken or quarantined
  }
  if (!before->regular || !utf8) {
    if (known == state_.files.end()) {
      quarantine(name, *before, "",
                 !utf8              ? "its name is not UTF-8 text (the decisions name files in JSON): rename it"
                 : before->dangling ? "a symbolic link to nothing: never read"
                                    : "not a regular file (a directory, a FIFO, a device): never read",
                 summary);
      changed = true;
    }
    return;
  }
  if (!settled(name, *before)) return;
  if (rewrittenSeen_.contains(before->key(name))) {
    return;  // a rewrite said already
  }
  if (known != state_.files.end() && known->second.status == "taken") {
    if (retaken(name, known->second, *before, path)) changed = true;
    return;
  }
  // Read first (a file that is no event file is refused at its first bytes), then its digest.
  auto runs = calib::fillProfilesByRun(path, model_.depthAtEnergy(), model_.selection, model_.profile);
  auto sha = runs ? sha256OfFile(path) : Result<std::string>(std::string());
  const auto after = seen(path);
  if (!after || !(*after == *before)) return;  // written meanwhile: not settled
  if (!runs || !sha) {
    quarantine(name, *before, sha && !sha->empty() ? *sha : std::string(),
               !runs ? runs.error().message : sha.error().message, summary);
    changed = true;
    return;
  }
  read.push_back({name, *before, *sha, std::move(*runs)});
}

bool Loop::retaken(const std::string& name, FileEntry& known, const Seen& now, const std::string& path) {
  auto sha = sha256OfFile(path);
  // Taken already: the content taken is kept; a rewrite is said once (quarantined, alerted).
  if (sha && *sha == known.sha256) {
    known.size = now.size;
    known.mtimeNs = now.mtimeNs;
    known.inode = now.inode;
    return true;
  }
  rewrittenSeen_.insert(now.key(name));
  const std::string rewritten = name + " rewritten";
  if (state_.alerted.contains(rewritten + (sha ? *sha : std::string()))) return false;
  say(
      fmt::format("{}: rewritten after it was taken (runs {}): the content taken is kept; the new one is "
                  "not taken",
                  printable(name), fmt::join(known.runs, ", ")));
  // Kept in the state (saved with this step's files): sent at least once, after a kill too.
  state_.pending[rewritten + (sha ? *sha : std::string())] =
      Json{{"file", name},
           {"reason", fmt::format("rewritten after it was taken (runs {}): the content taken is kept, the new "
                                  "one is not taken",
                                  fmt::join(known.runs, ", "))}};
  return true;
}

// Unchanged for --settle seconds: by its modification time, or — one in the future (a clock
// ahead on the DAQ's machine) — since this loop first saw it as it is.
bool Loop::settled(const std::string& name, const Seen& s) {
  const std::int64_t now = nowNs(), settle = static_cast<std::int64_t>(o_.settleSeconds * 1e9);
  if (s.mtimeNs <= now) return now - s.mtimeNs >= settle;
  const std::string key = s.key(name);
  auto [it, fresh] = futureSeen_.try_emplace(key, now);
  if (fresh) {
    say(
        fmt::format("{}: modified in the future ({:.0f} s ahead: a clock ahead?): taken once unchanged for --settle "
                    "seconds as this loop sees it",
                    printable(name), static_cast<double>(s.mtimeNs - now) / 1e9));
  }
  return now - it->second >= settle;
}

// One file read: refused (quarantined) when it repeats what was taken, holds a run older than
// what is decided or two energies in a run; else its runs' fills are kept and its runs taken.
Status Loop::take(const std::string& name, const Seen& seenAs, const std::string& sha,
                  std::map<std::int32_t, calib::ProfileFill>& runs, PromptSummary& summary) {
  // Decided already (a state directory started afresh on the tag): known, nothing to do.
  if (auto it = decidedFiles_.find(name); it != decidedFiles_.end() && it->second == sha) {
    std::vector<std::int32_t> list;
    list.reserve(runs.size());
    for (const auto& [run, fill] : runs) list.push_back(run);
    state_.files[name] = {seenAs.size, seenAs.mtimeNs, seenAs.inode, sha, "taken", list, ""};
    say(fmt::format("{}: decided already (the tag's decisions name it): not taken again", printable(name)));
    return {};
  }
  for (const auto& [other, f] : state_.files) {
    if (f.status == "taken" && f.sha256 == sha) {
      quarantine(name, seenAs, sha, fmt::format("the same content as {}, taken already", other), summary);
      return {};
    }
  }
  std::map<std::int32_t, std::string> takenFrom;
  for (const auto& [other, f] : state_.files) {
    if (f.status == "taken") {
      for (std::int32_t run : f.runs) takenFrom[run] = other;
    }
  }
  const std::int64_t covered = std::max(lastDecidedRun_, lastIovRun_);
  for (const auto& [run, fill] : runs) {
    std::string why;
    if (auto it = takenFrom.find(run); it != takenFrom.end()) {
      why = fmt::format("run {} was taken already from {}: a run is taken once", run, it->second);
    } else if (run <= covered) {
      why = fmt::format(
          "run {} is not after the runs decided already (up to run {}): it is not inserted into a decided "
          "group (its run is covered by the tag's IOV there)",
          run, covered);
    } else if (fill.beamEnergies.size() > 1) {
      why = fmt::format("run {} holds events of {} beam energies", run, fill.beamEnergies.size());
    }
    if (!why.empty()) {
      quarantine(name, seenAs, sha, why, summary);
      return {};
    }
  }
  if (runs.empty()) {
    quarantine(name, seenAs, sha, "no event", summary);
    return {};
  }
  // The fills first, then the state naming them: a kill between takes the file again.
  std::vector<std::int32_t> list;
  for (const auto& [run, fill] : runs) {
    if (Status s =
            io::writeFileIn((fs::path(o_.stateDir) / "runs").string(), runFillName(run), fill.state().dump() + "\n");
        !s) {
      return s;
    }
    list.push_back(run);
  }
  state_.files[name] = {seenAs.size, seenAs.mtimeNs, seenAs.inode, sha, "taken", list, ""};
  for (const auto& [run, fill] : runs) {
    const double energy = fill.beamEnergies.empty() ? kNaN : *fill.beamEnergies.begin();
    const std::int64_t selected = fill.cutFlow.events.back();
    state_.open.push_back({run, name, energy, selected});
    say(fmt::format("{}: run {} taken ({}, {} selected events{})", printable(name), run,
                    std::isnan(energy) ? std::string("no beam energy") : fmt::format("{:g} MeV", energy), selected,
                    selected == 0 ? fmt::format(" of {} read: covered by its group's IOV, adds nothing to its fit",
                                                fill.cutFlow.events.front())
                                  : std::string()));
  }
  std::sort(state_.open.begin(), state_.open.end(), [](const TakenRun& a, const TakenRun& b) { return a.run < b.run; });
  ++summary.filesTaken;
  return {};
}

}  // namespace emcalign::validation::prompt
