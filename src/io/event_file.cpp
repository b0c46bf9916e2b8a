#include "emcalign/io/event_file.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <optional>

#include <fmt/format.h>

#include "emcalign/core/regular_file.hpp"
#include "emcalign/io/output_file.hpp"
#include "event_file_internal.hpp"

namespace emcalign::io {

const char* const kCsvHeader =
    "run,event,beam_energy_mev,muon_veto,charged,z0_cm,rho_cm,phi_ts_rad,theta_ts_rad,energy_mev,"
    "phi_emc_rad,theta_emc_rad";

EventFormat formatOf(const std::string& path) {
  if (path == "-") return EventFormat::Csv;
  std::string tail = path.size() >= 4 ? path.substr(path.size() - 4) : path;  // ".csv", also ".CSV"
  for (char& c : tail) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return tail == ".csv" ? EventFormat::Csv : EventFormat::Hdf5;
}

EventFormat outputFormatOf(const std::string& output, const std::string& input) {
  std::string name = std::filesystem::path(output).filename().string();
  for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  // The temporary of a reserved output (NAME.tmp-PID, io/output_file.hpp) is named by NAME.
  if (temporaryWriter(name) > 0 && name.find(".tmp-") != std::string::npos) name.resize(name.find(".tmp-"));
  if (output == "-" || name.ends_with(".csv")) return EventFormat::Csv;
  if (name.ends_with(".h5") || name.ends_with(".hdf5")) return EventFormat::Hdf5;
  return formatOf(input);
}

namespace {

using namespace detail;

// ==================================================================== the events seen so far

// The (run, event) pairs met so far, as 64-bit fingerprints in an open-addressing table
// (16 bytes per event at most): a repeated pair is found at once, in constant time per
// event. A fingerprint can collide; `insert` returning false is confirmed by the caller.
class EventFingerprints {
 public:
  /// False when the fingerprint of (run, event) was met before.
  bool insert(std::int32_t run, std::int64_t event) {
    if (2 * (size_ + 1) > slots_.size()) grow();
    return place(fingerprint(run, event));
  }

 private:
  static std::uint64_t mix(std::uint64_t x) {  // splitmix64's finaliser
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
  }
  static std::uint64_t fingerprint(std::int32_t run, std::int64_t event) {
    const std::uint64_t f = mix(static_cast<std::uint64_t>(event) ^ mix(static_cast<std::uint32_t>(run) + 1));
    return f == 0 ? 1 : f;  // 0 marks an empty slot
  }
  bool place(std::uint64_t f) {
    const std::size_t mask = slots_.size() - 1;
    for (std::size_t i = f & mask;; i = (i + 1) & mask) {
      if (slots_[i] == f) return false;
      if (slots_[i] == 0) {
        slots_[i] = f;
        ++size_;
        return true;
      }
    }
  }
  void grow() {
    std::vector<std::uint64_t> old = std::move(slots_);
    slots_.assign(old.empty() ? std::size_t{4096} : 2 * old.size(), 0);
    size_ = 0;
    for (std::uint64_t f : old) {
      if (f != 0) place(f);
    }
  }

  std::vector<std::uint64_t> slots_;
  std::size_t size_ = 0;
};

// The events met so far, exactly while they come in few increasing sequences — the usual
// case: files are written in event order, one run after the other — as sorted segments of
// intervals of consecutive event numbers. Files numbered without gaps (as emcalign simulate
// writes them) then take a few bytes however many events they hold; each gap in the
// numbering costs one interval (24 bytes). Beyond kMaxSegments segments (events in no
// order), as fingerprints.
class SeenEvents {
 public:
  /// False when (run, event) was met before (or, past the segments, its fingerprint was).
  bool insert(std::int32_t run, std::int64_t event) {
    if (hashed_) return fingerprints_.insert(run, event);
    for (const auto& segment : segments_) {
      if (segment.back().before(run, event)) continue;
      // The last interval starting at or before the key.
      const auto after = std::upper_bound(
          segment.begin(), segment.end(), Interval{run, event, event},
          [](const Interval& a, const Interval& b) { return a.run != b.run ? a.run < b.run : a.first < b.first; });
      if (after != segment.begin() && std::prev(after)->holds(run, event)) return false;
    }
    if (!segments_.empty() && segments_.back().back().before(run, event)) {
      Interval& last = segments_.back().back();
      if (last.run == run && last.last + 1 == event) {
        last.last = event;
      } else {
        segments_.back().push_back({run, event, event});
      }
    } else if (segments_.size() < kMaxSegments) {
      segments_.push_back({{run, event, event}});
    } else {
      for (const auto& segment : segments_) {
        for (const Interval& i : segment) {
          for (std::int64_t e = i.first;; ++e) {
            fingerprints_.insert(i.run, e);
            if (e == i.last) break;
          }
        }
      }
      segments_.clear();
      hashed_ = true;
      fingerprints_.insert(run, event);
    }
    return true;
  }

 private:
  struct Interval {  // the events first..last of a run
    std::int32_t run;
    std::int64_t first, last;
    [[nodiscard]] bool holds(std::int32_t r, std::int64_t e) const { return r == run && e >= first && e <= last; }
    [[nodiscard]] bool before(std::int32_t r, std::int64_t e) const { return run != r ? run < r : last < e; }
  };
  static constexpr std::size_t kMaxSegments = 64;
  std::vector<std::vector<Interval>> segments_;
  bool hashed_ = false;
  EventFingerprints fingerprints_;
};

Result<std::unique_ptr<RowSource>> openSource(const std::string& path, std::size_t readRows,
                                              const ReaderOptions& options) {
  if (formatOf(path) == EventFormat::Csv) return openCsvSource(path);
  return openIsolated(
      path, [&] { return openHdf5Source(path, readRows, options); }, options.hdf5TimeoutSeconds);
}

// ============================================================================ the reader

class EventReaderImpl final : public EventReader {
 public:
  EventReaderImpl(std::vector<std::string> paths, ReaderOptions options)
      : paths_(std::move(paths)), options_(options) {}

  Status start() { return openFile(0); }

  Result<bool> next(std::vector<ParticleRow>& rows) override {
    rows.clear();
    truth_.clear();
    hits_.clear();
    if (failed_) return *failed_;
    while (true) {
      if (exhausted_) {
        if (index_ + 1 >= paths_.size()) return false;
        if (auto s = openFile(index_ + 1); !s) return fail(s.error());
      }
      if (carry_) {
        rows.push_back(*carry_);
        if (source_->hasTruth()) truth_.push_back(carryTruth_);
        hits_.insert(hits_.end(), carryHits_.begin(), carryHits_.end());
        carry_.reset();
        carryHits_.clear();
      }
      ParticleRow row;
      TruthRow truth;
      while (true) {
        rowHits_.clear();
        auto got = source_->next(row, truth, rowHits_);
        if (!got) return fail(got.error());
        if (!*got) {
          exhausted_ = true;
          break;
        }
        ++rowInFile_;
        auto issue = checkRow(row);
        if (!issue) issue = consistency_.check(row);
        if (!issue && source_->hasHits()) issue = checkHits(row, rowHits_);
        if (issue) {
          return fail(Error{fmt::format("{}: column '{}': {}", source_->location(), issue->column, issue->what)});
        }
        if (Status s = checkEventOrder(row); !s) return fail(s.error());
        if (rows.size() >= options_.blockRows && !sameEvent(row, rows.back())) {
          carry_ = row;
          carryTruth_ = truth;
          carryHits_ = rowHits_;
          break;
        }
        rows.push_back(row);
        if (source_->hasTruth()) truth_.push_back(truth);
        hits_.insert(hits_.end(), rowHits_.begin(), rowHits_.end());
      }
      if (!rows.empty()) return true;
    }
  }

  [[nodiscard]] const std::string& path() const override { return paths_[index_]; }

  [[nodiscard]] const std::vector<TruthRow>* truth() const override {
    return source_ && source_->hasTruth() ? &truth_ : nullptr;
  }

  [[nodiscard]] const std::vector<Hit>* hits() const override {
    return source_ && source_->hasHits() ? &hits_ : nullptr;
  }

  [[nodiscard]] const Attributes& attributes() const override {
    static const Attributes kNone;
    return source_ ? source_->attributes() : kNone;
  }

 private:
  // Read rows in pieces of the block size (not fewer than a few hundred, so a tiny
  // blockRows does not turn into one HDF5 read per row).
  [[nodiscard]] std::size_t readRows() const { return std::max<std::size_t>(options_.blockRows, 256); }

  Status openFile(std::size_t index) {
    auto source = openSource(paths_[index], readRows(), options_);
    if (!source) return source.error();
    source_ = std::move(*source);
    index_ = index;
    rowInFile_ = 0;
    exhausted_ = false;
    carry_.reset();
    carryHits_.clear();
    consistency_.reset();
    inEvent_ = false;
    return {};
  }

  // Each event appears once, its rows contiguous and not absurdly many.
  Status checkEventOrder(const ParticleRow& row) {
    if (inEvent_ && sameEvent(row, current_)) {
      if (++eventRows_ > kMaxRowsPerEvent) {
        return Error{
            fmt::format("{}: run {} event {} has more than {} rows: an event holds a handful of particles "
                        "(are the run and event columns filled?)",
                        source_->location(), row.run, row.event, kMaxRowsPerEvent)};
      }
      return {};
    }
    inEvent_ = true;
    current_ = row;
    eventRows_ = 1;
    if (seen_.insert(row.run, row.event)) return {};
    auto first = locateEarlier(row);
    if (!first) return first.error();
    if (first->empty()) return {};  // a fingerprint collision (events in no order), not a repeat
    return Error{
        fmt::format("{}: run {} event {} appears again (its rows start at {}): each event must appear once, "
                    "its rows contiguous (is a file given twice, or are the rows of this event apart?)",
                    source_->location(), row.run, row.event, *first)};
  }

  // Where the event of `row` started before the current row, or "" if it did not.
  Result<std::string> locateEarlier(const ParticleRow& row) const {
    for (std::size_t f = 0; f <= index_; ++f) {
      auto source = openSource(paths_[f], readRows(), options_);
      if (!source) return source.error();
      const std::uint64_t limit = f == index_ ? rowInFile_ - 1 : UINT64_MAX;
      ParticleRow r;
      TruthRow t;
      std::vector<Hit> h;
      for (std::uint64_t k = 0; k < limit; ++k) {
        h.clear();
        auto got = (*source)->next(r, t, h);
        if (!got) return got.error();
        if (!*got) break;
        if (sameEvent(r, row)) return (*source)->location();
      }
    }
    return std::string();
  }

  Error fail(Error e) {
    failed_ = e;
    return e;
  }

  std::vector<std::string> paths_;
  ReaderOptions options_;
  std::size_t index_ = 0;
  std::uint64_t rowInFile_ = 0;  // rows the current source has delivered
  std::unique_ptr<RowSource> source_;
  bool exhausted_ = false;
  std::optional<ParticleRow> carry_;
  TruthRow carryTruth_;
  std::vector<TruthRow> truth_;
  std::vector<Hit> hits_;       // of the block
  std::vector<Hit> rowHits_;    // of the row just read
  std::vector<Hit> carryHits_;  // of the carried row
  EventConsistency consistency_;
  bool inEvent_ = false;
  ParticleRow current_;
  int eventRows_ = 0;
  SeenEvents seen_;
  std::optional<Error> failed_;
};

}  // namespace

// ============================================================================ public API

Result<std::unique_ptr<EventWriter>> EventWriter::open(const std::string& path, const WriterOptions& options) {
  return open(path, options, formatOf(path));
}

Result<std::unique_ptr<EventWriter>> EventWriter::open(const std::string& path, const WriterOptions& options,
                                                       EventFormat format) {
  if (auto s = checkAttributes(path, options.attributes, format); !s) return s.error();
  if (format == EventFormat::Csv) return openCsvWriter(path, options);
  return openHdf5Writer(path, options);
}

Result<std::unique_ptr<EventReader>> EventReader::open(std::vector<std::string> paths, ReaderOptions options) {
  if (paths.empty()) return Error{"no event files given"};
  if (options.blockRows == 0) return Error{"event reader: blockRows must be at least 1"};
  if (!(options.hdf5TimeoutSeconds > 0.0)) return Error{"event reader: the HDF5 timeout must be positive"};
  // Every file is checked before any is read: a missing or unreadable file is found at
  // once, not after hours of reading the ones before it, and so is a file given twice.
  std::vector<std::pair<dev_t, ino_t>> ids;
  for (std::size_t i = 0; i < paths.size(); ++i) {
    const std::string& path = paths[i];
    if (const long writer = temporaryWriter(std::filesystem::path(path).filename().string());
        writer > 0 && writer != static_cast<long>(::getpid())) {
      return Error{
          fmt::format("{}: a temporary file of an emcalign command (being written, or left by one that was "
                      "killed), not event data",
                      path)};
    }
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) {
      if (errno == ENOENT) return Error{fmt::format("{}: no such file", path)};
      return Error{fmt::format("{}: cannot open: {}", path, std::strerror(errno))};
    }
    if (!S_ISREG(st.st_mode)) {
      return Error{fmt::format("{}: not a regular file{}", path,
                               S_ISFIFO(st.st_mode) ? " but a pipe (a <(...) or a FIFO): emcalign reads event files "
                                                      "it can open again; write the events to a file first"
                                                    : "")};
    }
    if (::access(path.c_str(), R_OK) != 0) {
      return Error{fmt::format("{}: cannot read: {}", path, std::strerror(errno))};
    }
    // Opened once the way every input is (core/regular_file.hpp): a file of /proc that would
    // block (/proc/kmsg) is refused here, before a reader waits on it.
    if (auto checked = RegularFile::open(path); !checked) return checked.error();
    for (std::size_t j = 0; j < ids.size(); ++j) {
      if (ids[j] == std::pair{st.st_dev, st.st_ino}) {
        return Error{
            fmt::format("{}: is the same file as {} (given twice?): its events would count twice", path, paths[j])};
      }
    }
    ids.emplace_back(st.st_dev, st.st_ino);
    protectInput({"", path});
  }
  auto reader = std::make_unique<EventReaderImpl>(std::move(paths), options);
  if (auto s = reader->start(); !s) return s.error();
  return std::unique_ptr<EventReader>(std::move(reader));
}

Result<double> firstBeamEnergy(const std::vector<std::string>& paths) {
  auto reader = EventReader::open(paths, ReaderOptions{.blockRows = 1});
  if (!reader) return reader.error();
  std::vector<ParticleRow> rows;
  auto more = (*reader)->next(rows);
  if (!more) return more.error();
  if (!*more || rows.empty()) {
    return Error{paths.size() == 1 ? fmt::format("{}: no events", paths[0])
                                   : fmt::format("no events in the {} files ({}, ...)", paths.size(), paths[0])};
  }
  return rows.front().beamEnergy;
}

Result<std::map<std::string, std::optional<std::string>>> commonAttributes(const std::vector<std::string>& paths,
                                                                           const std::vector<std::string>& keys) {
  std::map<std::string, std::optional<std::string>> common;
  std::map<std::string, bool> differ;  // a file lacks the key, or two values differ
  for (std::size_t f = 0; f < paths.size(); ++f) {
    auto reader = EventReader::open({paths[f]}, ReaderOptions{.blockRows = 1, .truth = false, .hits = false});
    if (!reader) return reader.error();
    const auto& attributes = (*reader)->attributes();
    for (const auto& key : keys) {
      const auto it = std::find_if(attributes.begin(), attributes.end(), [&](const auto& a) { return a.first == key; });
      if (it == attributes.end() || (f > 0 && common[key] != it->second)) differ[key] = true;
      if (f == 0 && it != attributes.end()) common[key] = it->second;
    }
  }
  for (const auto& key : keys) {
    if (differ[key] || paths.empty()) common[key] = std::nullopt;
  }
  return common;
}

}  // namespace emcalign::io
