#pragma once
// Internal to the event-file implementation (src/io/event_*.cpp), not installed: the columns
// of docs/contract.md §6, the checks every row must pass (event_rows.cpp), and the interface between
// the reader and writer front (event_file.cpp) and the two formats (event_csv.cpp,
// event_hdf5_writer.cpp and event_hdf5_reader.cpp). The rules themselves are documented in
// include/emcalign/io/event_file.hpp.

#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "emcalign/core/event_record.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/types.hpp"
#include "emcalign/io/event_file.hpp"

namespace emcalign::io::detail {

using Attributes = std::vector<std::pair<std::string, std::string>>;

constexpr double kPi = std::numbers::pi;
constexpr double kTwoPi = 2.0 * std::numbers::pi;

// ------------------------------------------------------------------------------- columns

// Column indices in file order (CSV header order, HDF5 dataset names).
enum Col : int {
  kRun = 0,
  kEvent,
  kBeam,
  kVeto,
  kCharged,
  kZ0,
  kRho,
  kPhiTs,
  kThetaTs,
  kEnergy,
  kPhiEmc,
  kThetaEmc,
  kNumCols
};

constexpr std::array<std::string_view, kNumCols> kColumnNames = {
    "run",    "event",      "beam_energy_mev", "muon_veto",  "charged",     "z0_cm",
    "rho_cm", "phi_ts_rad", "theta_ts_rad",    "energy_mev", "phi_emc_rad", "theta_emc_rad"};

// The double columns of a row, as (column, accessor) pairs; the integer columns are handled
// one by one.
template <typename Row>
struct DoubleColumn {
  const char* name;
  double (*get)(const Row&);
  void (*set)(Row&, double);
};

// `member` names a member: it cannot be parenthesised.
// NOLINTBEGIN(bugprone-macro-parentheses)
#define EMCALIGN_MEMBER_COLUMN(Row, name, member)                                       \
  DoubleColumn<Row> {                                                                   \
    name, [](const Row& r) { return r.member; }, [](Row& r, double v) { r.member = v; } \
  }
// NOLINTEND(bugprone-macro-parentheses)

constexpr std::array<DoubleColumn<ParticleRow>, 8> kEventDoubles = {
    EMCALIGN_MEMBER_COLUMN(ParticleRow, "beam_energy_mev", beamEnergy),
    EMCALIGN_MEMBER_COLUMN(ParticleRow, "z0_cm", z0),
    EMCALIGN_MEMBER_COLUMN(ParticleRow, "rho_cm", rho),
    EMCALIGN_MEMBER_COLUMN(ParticleRow, "phi_ts_rad", phiTs),
    EMCALIGN_MEMBER_COLUMN(ParticleRow, "theta_ts_rad", thetaTs),
    EMCALIGN_MEMBER_COLUMN(ParticleRow, "energy_mev", energy),
    EMCALIGN_MEMBER_COLUMN(ParticleRow, "phi_emc_rad", phiEmc),
    EMCALIGN_MEMBER_COLUMN(ParticleRow, "theta_emc_rad", thetaEmc)};

constexpr std::array<DoubleColumn<TruthRow>, 9> kTruthDoubles = {
    EMCALIGN_MEMBER_COLUMN(TruthRow, "energy_mev", energy),
    EMCALIGN_MEMBER_COLUMN(TruthRow, "theta_rad", theta),
    EMCALIGN_MEMBER_COLUMN(TruthRow, "phi_rad", phi),
    EMCALIGN_MEMBER_COLUMN(TruthRow, "vertex_x_cm", vertex.x()),
    EMCALIGN_MEMBER_COLUMN(TruthRow, "vertex_y_cm", vertex.y()),
    EMCALIGN_MEMBER_COLUMN(TruthRow, "vertex_z_cm", vertex.z()),
    EMCALIGN_MEMBER_COLUMN(TruthRow, "shower_x_cm", showerCentre.x()),
    EMCALIGN_MEMBER_COLUMN(TruthRow, "shower_y_cm", showerCentre.y()),
    EMCALIGN_MEMBER_COLUMN(TruthRow, "shower_z_cm", showerCentre.z())};

#undef EMCALIGN_MEMBER_COLUMN

constexpr const char* kTruthPdg = "pdg";
constexpr const char* kEventsGroup = "events";
constexpr const char* kTruthGroup = "truth";
constexpr const char* kHitsGroup = "hits";
constexpr const char* kHitOffset = "hit_offset";  // in /events
constexpr const char* kHitCount = "hit_count";    // in /events
constexpr const char* kHitCounter = "counter";    // in /hits
constexpr const char* kHitEnergy = "energy_mev";  // in /hits

// ------------------------------------------------------------------------ row validation

// The most rows one event may have (an event holds a handful of particles).
constexpr int kMaxRowsPerEvent = 1000;

// A refused value: which column and why (the caller adds file and line/record).
struct Issue {
  std::string_view column;
  std::string what;
};

/// What is wrong with a row on its own, or none.
std::optional<Issue> checkRow(const ParticleRow& r);

// The rows of one event share the beam energy and the muon veto; this follows the current
// event through a stream of rows (block boundaries do not matter).
class EventConsistency {
 public:
  void reset() { active_ = false; }

  std::optional<Issue> check(const ParticleRow& r) {
    if (active_ && sameEvent(r, first_)) {
      if (r.beamEnergy != first_.beamEnergy) {
        return Issue{kColumnNames[kBeam], fmt::format("{} differs from {} in the earlier rows of run {} event {}",
                                                      r.beamEnergy, first_.beamEnergy, r.run, r.event)};
      }
      if (r.muonVeto != first_.muonVeto) {
        return Issue{kColumnNames[kVeto],
                     fmt::format("{} differs from {} in the earlier rows of run {} event {}",
                                 static_cast<int>(r.muonVeto), static_cast<int>(first_.muonVeto), r.run, r.event)};
      }
      return std::nullopt;
    }
    active_ = true;
    first_ = r;
    return std::nullopt;
  }

 private:
  bool active_ = false;
  ParticleRow first_;
};

/// Attribute keys are restricted so that the CSV form '# key: value' reads back unambiguously.
bool isAttributeKey(std::string_view key);

/// Keys, duplicates and values of a writer's attributes.
Status checkAttributes(const std::string& path, const Attributes& attributes, EventFormat format);

/// What is wrong with a row's hits (`hits`: its hitCount hits), or none.
std::optional<Issue> checkHits(const ParticleRow& r, std::span<const Hit> hits);

/// Checks a whole append before any row is buffered: a refused append writes none of its
/// rows (and the caller then fails the writer for good, see EventWriter::append). With
/// `withHits`, `hits` are the rows' hits in row order.
Status checkAppend(const std::string& path, std::span<const ParticleRow> rows, std::span<const Hit> hits, bool withHits,
                   std::uint64_t firstIndex, EventConsistency& consistency);

// What a writer's calls find: open, closed, or failed (its first error, said again by every
// later call), for the writer of `path`.
class WriterState {
 public:
  explicit WriterState(std::string path) : path_(std::move(path)) {}
  [[nodiscard]] Status usable() const {
    if (closed_) return Error{fmt::format("{}: the writer is already closed", path_)};
    if (failed_) return Error{fmt::format("{}: the writer failed earlier: {}", path_, *failed_)};
    return {};
  }
  Status fail(std::string message) {
    failed_ = message;
    return Error{std::move(message)};
  }
  void close() { closed_ = true; }
  [[nodiscard]] bool closed() const { return closed_; }

 private:
  std::string path_;
  std::optional<std::string> failed_;
  bool closed_ = false;
};

// ------------------------------------------------------------------------- reader sources

// One input file delivering rows one by one; lexical checks (CSV text, HDF5 types) live
// here, the physics checks in the reader (checkRow, EventConsistency).
class RowSource {
 public:
  virtual ~RowSource() = default;
  /// The next row (and its truth when hasTruth(), and its row.hitCount hits appended to
  /// `hits` when hasHits()); false at the end of the file.
  virtual Result<bool> next(ParticleRow& row, TruthRow& truth, std::vector<Hit>& hits) = 0;
  [[nodiscard]] virtual bool hasTruth() const = 0;
  [[nodiscard]] virtual bool hasHits() const { return false; }
  [[nodiscard]] virtual const Attributes& attributes() const = 0;
  /// Where the row last returned is, for messages: "file: line N" or "file: record N".
  [[nodiscard]] virtual std::string location() const = 0;
};

// ------------------------------------------------------------------------------ formats

Result<std::unique_ptr<EventWriter>> openCsvWriter(const std::string& path, const WriterOptions& options);
Result<std::unique_ptr<EventWriter>> openHdf5Writer(const std::string& path, const WriterOptions& options);
Result<std::unique_ptr<RowSource>> openCsvSource(const std::string& path);
/// In this process (see openIsolated); `readRows`: rows read from each dataset at a time;
/// the truth and the hits only when `options` asks for them.
Result<std::unique_ptr<RowSource>> openHdf5Source(const std::string& path, std::size_t readRows,
                                                  const ReaderOptions& options);

/// The process's lock on HDF5. Debian's libhdf5 is the serial build: no two threads may be
/// inside it at once (a program that writes one file while it reads another, the Python
/// module's threads), and a reader forked while another thread is inside HDF5 would start
/// with HDF5's state half-changed and its internal locks held. So every call into HDF5
/// holds this lock (Hdf5Quiet), and so does the fork of openIsolated. The forked reader is
/// alone in its process and takes no lock (leaveHdf5LockAfterFork).
class Hdf5Lock {
 public:
  Hdf5Lock();
  ~Hdf5Lock();
  Hdf5Lock(const Hdf5Lock&) = delete;
  Hdf5Lock& operator=(const Hdf5Lock&) = delete;

 private:
  bool held_ = false;
};
/// Called in a forked reader: from now on this process has one thread and takes no lock.
void leaveHdf5LockAfterFork();

/// The source `open` makes, run in a child process that streams its rows back
/// (isolated_source.cpp): a crash of the child is an error naming `path`, and a child silent
/// for `timeoutSeconds` is killed and reported. For HDF5, whose library is not safe on
/// corrupted files.
Result<std::unique_ptr<RowSource>> openIsolated(const std::string& path,
                                                const std::function<Result<std::unique_ptr<RowSource>>()>& open,
                                                double timeoutSeconds);
/// `read` run in a child process as openIsolated's source is, for a file read at once (a
/// random-trigger file): its bytes, or its error; a crash or a silence is an error naming `path`.
Result<std::string> readIsolated(const std::string& path, const std::function<Result<std::string>()>& read,
                                 double timeoutSeconds);

}  // namespace emcalign::io::detail
