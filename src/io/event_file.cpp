#include "emcalign/io/event_file.hpp"

#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <numbers>
#include <optional>
#include <string_view>
#include <utility>

#include <fmt/format.h>

#include "emcalign/io/csv.hpp"

namespace emcalign::io {

const char* const kCsvHeader =
    "run,event,beam_energy_mev,muon_veto,charged,z0_cm,rho_cm,phi_ts_rad,theta_ts_rad,energy_mev,"
    "phi_emc_rad,theta_emc_rad";

EventFormat formatOf(const std::string& path) {
  constexpr std::string_view kCsv = ".csv";
  return std::string_view(path).ends_with(kCsv) ? EventFormat::Csv : EventFormat::Hdf5;
}

namespace {

namespace fs = std::filesystem;
using Attributes = std::vector<std::pair<std::string, std::string>>;

constexpr double kPi = std::numbers::pi;
constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

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

#define EMCALIGN_MEMBER_COLUMN(Row, name, member)                                       \
  DoubleColumn<Row> {                                                                   \
    name, [](const Row& r) { return r.member; }, [](Row& r, double v) { r.member = v; } \
  }

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

// ------------------------------------------------------------------------ row validation

// A refused value: which column and why (the caller adds file and line/record).
struct Issue {
  std::string_view column;
  std::string what;
};

std::optional<Issue> checkRow(const ParticleRow& r) {
  const auto name = [](int c) { return kColumnNames[static_cast<std::size_t>(c)]; };
  const std::array<double, kNumCols> v = {0.0,       0.0,      r.beamEnergy, 0.0,
                                          0.0,       r.z0,     r.rho,        r.phiTs,
                                          r.thetaTs, r.energy, r.phiEmc,     r.thetaEmc};
  for (int c = kBeam; c < kNumCols; ++c) {
    if (std::isinf(v[static_cast<std::size_t>(c)])) {
      return Issue{name(c),
                   fmt::format("{} is not a finite number", v[static_cast<std::size_t>(c)])};
    }
  }
  if (std::isnan(r.beamEnergy)) return Issue{name(kBeam), "empty (a value is required)"};
  if (!(r.beamEnergy > 0.0)) {
    return Issue{name(kBeam), fmt::format("beam energy must be > 0, got {}", r.beamEnergy)};
  }
  if (r.muonVeto != 0 && r.muonVeto != 1) {
    return Issue{name(kVeto), fmt::format("must be 0 or 1, got {}", static_cast<int>(r.muonVeto))};
  }
  if (r.charged != 0 && r.charged != 1) {
    return Issue{name(kCharged),
                 fmt::format("must be 0 or 1, got {}", static_cast<int>(r.charged))};
  }
  for (int c = kZ0; c <= kThetaTs; ++c) {
    const double x = v[static_cast<std::size_t>(c)];
    if (r.charged == 1 && std::isnan(x)) {
      return Issue{name(c),
                   "empty, but a charged particle (charged = 1) needs a complete track "
                   "(z0_cm, rho_cm, phi_ts_rad, theta_ts_rad)"};
    }
    if (r.charged == 0 && !std::isnan(x)) {
      return Issue{name(c), fmt::format("must be empty for a photon (charged = 0), got {}", x)};
    }
  }
  if (!std::isnan(r.phiTs) && (r.phiTs < 0.0 || r.phiTs > kTwoPi)) {
    return Issue{name(kPhiTs), fmt::format("{} is outside [0, 2*pi]", r.phiTs)};
  }
  if (!std::isnan(r.thetaTs) && (r.thetaTs < 0.0 || r.thetaTs > kPi)) {
    return Issue{name(kThetaTs), fmt::format("{} is outside [0, pi]", r.thetaTs)};
  }
  int clusterFields = 0;
  for (int c = kEnergy; c <= kThetaEmc; ++c)
    clusterFields += std::isnan(v[static_cast<std::size_t>(c)]) ? 0 : 1;
  if (clusterFields == 0 && r.charged == 0) {
    return Issue{name(kEnergy), "empty, but a photon (charged = 0) needs an EMC cluster"};
  }
  if (clusterFields != 0 && clusterFields != 3) {
    for (int c = kEnergy; c <= kThetaEmc; ++c) {
      if (std::isnan(v[static_cast<std::size_t>(c)])) {
        return Issue{name(c),
                     "empty while other cluster fields are filled (energy_mev, phi_emc_rad and "
                     "theta_emc_rad are all filled or all empty)"};
      }
    }
  }
  if (!std::isnan(r.energy) && r.energy < 0.0) {
    return Issue{name(kEnergy), fmt::format("negative energy {}", r.energy)};
  }
  if (!std::isnan(r.phiEmc) && (r.phiEmc < 0.0 || r.phiEmc > kTwoPi)) {
    return Issue{name(kPhiEmc), fmt::format("{} is outside [0, 2*pi]", r.phiEmc)};
  }
  if (!std::isnan(r.thetaEmc) && (r.thetaEmc < 0.0 || r.thetaEmc > kPi)) {
    return Issue{name(kThetaEmc), fmt::format("{} is outside [0, pi]", r.thetaEmc)};
  }
  return std::nullopt;
}

bool sameEvent(const ParticleRow& a, const ParticleRow& b) {
  return a.run == b.run && a.event == b.event;
}

// The rows of one event share the beam energy and the muon veto; this follows the current
// event through a stream of rows (block boundaries do not matter).
class EventConsistency {
 public:
  void reset() { active_ = false; }

  std::optional<Issue> check(const ParticleRow& r) {
    if (active_ && sameEvent(r, first_)) {
      if (r.beamEnergy != first_.beamEnergy) {
        return Issue{kColumnNames[kBeam],
                     fmt::format("{} differs from {} in the earlier rows of run {} event {}",
                                 r.beamEnergy, first_.beamEnergy, r.run, r.event)};
      }
      if (r.muonVeto != first_.muonVeto) {
        return Issue{kColumnNames[kVeto],
                     fmt::format("{} differs from {} in the earlier rows of run {} event {}",
                                 static_cast<int>(r.muonVeto), static_cast<int>(first_.muonVeto),
                                 r.run, r.event)};
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

// Attribute keys are restricted so that the CSV form '# key: value' reads back unambiguously.
bool isAttributeKey(std::string_view key) {
  if (key.empty()) return false;
  for (char ch : key) {
    const bool ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
                    (ch >= '0' && ch <= '9') || ch == '_' || ch == '.' || ch == '-';
    if (!ok) return false;
  }
  return true;
}

Status checkAttributes(const std::string& path, const Attributes& attributes, EventFormat format) {
  for (std::size_t i = 0; i < attributes.size(); ++i) {
    const auto& [key, value] = attributes[i];
    if (!isAttributeKey(key)) {
      return Error{fmt::format(
          "{}: attribute '{}': a key is made of letters, digits, '_', '.' and '-'", path, key)};
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (attributes[j].first == key) {
        return Error{fmt::format("{}: attribute '{}': given twice", path, key)};
      }
    }
    if (value.find('\0') != std::string::npos) {
      return Error{
          fmt::format("{}: attribute '{}': the value contains a NUL character", path, key)};
    }
    if (format == EventFormat::Csv && value.find_first_of("\r\n") != std::string::npos) {
      return Error{fmt::format(
          "{}: attribute '{}': the value contains a line break, which a CSV comment line cannot "
          "hold (write it on one line, e.g. compact JSON)",
          path, key)};
    }
  }
  return {};
}

std::string tempPathFor(const std::string& path) {
  return fmt::format("{}.tmp-{}", path, static_cast<long>(::getpid()));
}

void removeQuietly(const std::string& path) {
  std::error_code ec;
  fs::remove(path, ec);
}

Status renameIntoPlace(const std::string& tmp, const std::string& path) {
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    removeQuietly(tmp);
    return Error{
        fmt::format("{}: cannot rename the temporary file into place: {}", path, ec.message())};
  }
  return {};
}

// Checks a whole append before any row is buffered: a refused append writes none of its rows
// (and the caller then fails the writer for good, see EventWriter::append).
Status checkAppend(const std::string& path, std::span<const ParticleRow> rows,
                   std::uint64_t firstIndex, EventConsistency& consistency) {
  EventConsistency trial = consistency;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    auto issue = checkRow(rows[i]);
    if (!issue) issue = trial.check(rows[i]);
    if (issue) {
      return Error{fmt::format("{}: appended row {} (0-based, run {} event {}): column '{}': {}",
                               path, firstIndex + i, rows[i].run, rows[i].event, issue->column,
                               issue->what)};
    }
  }
  consistency = trial;
  return {};
}

// ===================================================================================== CSV

constexpr std::size_t kCsvFlushBytes = std::size_t{1} << 20;

class CsvWriter final : public EventWriter {
 public:
  static Result<std::unique_ptr<EventWriter>> create(const std::string& path,
                                                     const WriterOptions& options) {
    auto w = std::unique_ptr<CsvWriter>(new CsvWriter(path));
    w->file_ = std::fopen(w->tmp_.c_str(), "wb");
    if (w->file_ == nullptr) {
      return Error{fmt::format("{}: cannot create the temporary file '{}': {}", path, w->tmp_,
                               std::strerror(errno))};
    }
    for (const auto& [key, value] : options.attributes) {
      fmt::format_to(std::back_inserter(w->buffer_), "# {}: {}\n", key, value);
    }
    fmt::format_to(std::back_inserter(w->buffer_), "{}\n", kCsvHeader);
    return std::unique_ptr<EventWriter>(std::move(w));
  }

  ~CsvWriter() override {
    if (file_ != nullptr) std::fclose(file_);
    if (!closed_) removeQuietly(tmp_);
  }

  Status append(std::span<const ParticleRow> rows, std::span<const TruthRow> /*truth*/) override {
    if (auto s = usable(); !s) return s;
    if (auto s = checkAppend(path_, rows, appended_, consistency_); !s)
      return fail(s.error().message);
    auto out = std::back_inserter(buffer_);
    const auto number = [&](double x) {
      if (!std::isnan(x)) fmt::format_to(out, "{:.17g}", x);
    };
    for (const ParticleRow& r : rows) {
      fmt::format_to(out, "{},{},", r.run, r.event);
      number(r.beamEnergy);
      fmt::format_to(out, ",{},{},", static_cast<int>(r.muonVeto), static_cast<int>(r.charged));
      for (double x : {r.z0, r.rho, r.phiTs, r.thetaTs, r.energy, r.phiEmc}) {
        number(x);
        buffer_.push_back(',');
      }
      number(r.thetaEmc);
      buffer_.push_back('\n');
      if (buffer_.size() >= kCsvFlushBytes) {
        if (auto s = flush(); !s) return s;
      }
    }
    appended_ += rows.size();
    return {};
  }

  Status close() override {
    if (auto s = usable(); !s) return s;
    if (auto s = flush(); !s) return s;
    const bool flushed = std::fflush(file_) == 0;
    const int flushErrno = errno;
    const bool closedOk = std::fclose(file_) == 0;
    file_ = nullptr;
    if (!flushed || !closedOk) {
      return fail(
          fmt::format("{}: write failed: {}", path_, std::strerror(flushed ? errno : flushErrno)));
    }
    if (auto s = renameIntoPlace(tmp_, path_); !s) return fail(s.error().message);
    closed_ = true;
    return {};
  }

 private:
  explicit CsvWriter(std::string path) : path_(std::move(path)), tmp_(tempPathFor(path_)) {}

  Status usable() const {
    if (closed_) return Error{fmt::format("{}: the writer is already closed", path_)};
    if (failed_) return Error{fmt::format("{}: the writer failed earlier: {}", path_, *failed_)};
    return {};
  }

  Status fail(std::string message) {
    failed_ = message;
    return Error{std::move(message)};
  }

  Status flush() {
    if (buffer_.size() == 0) return {};
    if (std::fwrite(buffer_.data(), 1, buffer_.size(), file_) != buffer_.size()) {
      return fail(fmt::format("{}: write failed: {}", path_, std::strerror(errno)));
    }
    buffer_.clear();
    return {};
  }

  std::string path_;
  std::string tmp_;
  std::FILE* file_ = nullptr;
  fmt::memory_buffer buffer_;
  std::uint64_t appended_ = 0;
  EventConsistency consistency_;
  std::optional<std::string> failed_;
  bool closed_ = false;
};

// Reads a file line by line through a fixed buffer (memory does not grow with the file).
class LineReader {
 public:
  static constexpr std::size_t kReadBytes = std::size_t{1} << 16;
  /// A line longer than this is refused: it is not an event CSV (or a binary file).
  static constexpr std::size_t kMaxLineBytes = std::size_t{16} << 20;

  LineReader() = default;
  LineReader(const LineReader&) = delete;
  LineReader& operator=(const LineReader&) = delete;
  ~LineReader() {
    if (file_ != nullptr) std::fclose(file_);
  }

  Status open(const std::string& path) {
    path_ = path;
    file_ = std::fopen(path.c_str(), "rb");
    if (file_ == nullptr)
      return Error{fmt::format("{}: cannot open: {}", path, std::strerror(errno))};
    return {};
  }

  /// The next line without its '\n' (valid until the next call); false at the end of the
  /// file. `terminated` is false for a last line that has no newline.
  Result<bool> next(std::string_view& line, bool& terminated) {
    while (true) {
      const std::size_t nl = buffer_.find('\n', scanFrom_);
      if (nl != std::string::npos) {
        line = std::string_view(buffer_).substr(begin_, nl - begin_);
        begin_ = scanFrom_ = nl + 1;
        terminated = true;
        ++lineNumber_;
        return true;
      }
      if (eof_) {
        if (begin_ == buffer_.size()) return false;
        line = std::string_view(buffer_).substr(begin_);
        begin_ = scanFrom_ = buffer_.size();
        terminated = false;
        ++lineNumber_;
        return true;
      }
      buffer_.erase(0, begin_);
      begin_ = 0;
      scanFrom_ = buffer_.size();
      if (buffer_.size() > kMaxLineBytes) {
        return Error{fmt::format("{}: line {}: longer than {} MiB (not an event CSV file?)", path_,
                                 lineNumber_ + 1, kMaxLineBytes >> 20)};
      }
      const std::size_t old = buffer_.size();
      buffer_.resize(old + kReadBytes);
      const std::size_t got = std::fread(buffer_.data() + old, 1, kReadBytes, file_);
      buffer_.resize(old + got);
      if (got < kReadBytes) {
        if (std::ferror(file_)) {
          return Error{fmt::format("{}: line {}: read error: {}", path_, lineNumber_ + 1,
                                   std::strerror(errno))};
        }
        eof_ = true;
      }
    }
  }

  /// 1-based physical number of the line last returned.
  std::uint64_t lineNumber() const { return lineNumber_; }

 private:
  std::string path_;
  std::FILE* file_ = nullptr;
  std::string buffer_;
  std::size_t begin_ = 0;
  std::size_t scanFrom_ = 0;
  bool eof_ = false;
  std::uint64_t lineNumber_ = 0;
};

// ------------------------------------------------------------------------- reader sources

// One input file delivering rows one by one; lexical checks (CSV text, HDF5 types) live
// here, the physics checks in the reader (checkRow, EventConsistency).
class RowSource {
 public:
  virtual ~RowSource() = default;
  /// The next row (and its truth when hasTruth()); false at the end of the file.
  virtual Result<bool> next(ParticleRow& row, TruthRow& truth) = 0;
  virtual bool hasTruth() const = 0;
  virtual const Attributes& attributes() const = 0;
  /// Where the row last returned is, for messages: "file: line N" or "file: record N".
  virtual std::string location() const = 0;
  /// Appended to a message about the row last returned (e.g. that it may be cut).
  virtual std::string_view note() const { return {}; }
};

constexpr std::string_view kNoNewlineNote = " (the last line has no newline: truncated file?)";

std::string lowerCase(std::string_view s) {
  std::string out(s);
  for (char& ch : out) {
    if (ch >= 'A' && ch <= 'Z') ch = static_cast<char>(ch - 'A' + 'a');
  }
  return out;
}

bool isNanOrInfText(std::string_view field) {
  if (!field.empty() && (field.front() == '+' || field.front() == '-')) field.remove_prefix(1);
  const std::string f = lowerCase(field);
  return f == "nan" || f == "inf" || f == "infinity" || f.starts_with("nan(");
}

std::string notANumber(std::string_view field) {
  if (isNanOrInfText(field)) {
    return fmt::format("'{}' is not allowed (leave the field empty for a missing value)", field);
  }
  return fmt::format("'{}' is not a finite number", field);
}

// A double field: empty → NaN; an error text otherwise.
std::optional<std::string> parseDoubleField(std::string_view field, double& out) {
  if (field.empty()) {
    out = kNaN;
    return std::nullopt;
  }
  if (auto x = parseFiniteDouble(field)) {
    out = *x;
    return std::nullopt;
  }
  return notANumber(field);
}

std::optional<std::string> parseIntegerField(std::string_view field, std::int64_t lo,
                                             std::int64_t hi, std::int64_t& out) {
  if (field.empty()) return "empty (a value is required)";
  std::string_view digits = field;
  if (digits.front() == '+') digits.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), out);
  if (ec == std::errc() && ptr == digits.data() + digits.size() && !digits.empty()) {
    if (out < lo || out > hi) return fmt::format("{} is outside [{}, {}]", out, lo, hi);
    return std::nullopt;
  }
  if (ec == std::errc::result_out_of_range) return fmt::format("'{}' is out of range", field);
  if (parseFiniteDouble(field)) {
    return fmt::format("'{}' is not an integer (write it without a decimal point or exponent)",
                       field);
  }
  return notANumber(field);
}

std::string quotedList(const std::vector<std::string_view>& names) {
  std::string out;
  for (auto n : names) out += fmt::format("{}'{}'", out.empty() ? "" : ", ", n);
  return out;
}

// What is wrong with a header line, or none.
std::optional<std::string> checkHeader(const std::vector<std::string_view>& fields) {
  if (fields.size() == kColumnNames.size() &&
      std::equal(fields.begin(), fields.end(), kColumnNames.begin())) {
    return std::nullopt;
  }
  const auto contains = [](const auto& range, std::string_view name) {
    return std::find(range.begin(), range.end(), name) != range.end();
  };
  std::vector<std::string_view> missing, extra;
  for (auto n : kColumnNames) {
    if (!contains(fields, n)) missing.push_back(n);
  }
  for (std::size_t i = 0; i < fields.size(); ++i) {
    const auto f = fields[i];
    if (!contains(kColumnNames, f) ||
        std::find(fields.begin(), fields.begin() + static_cast<std::ptrdiff_t>(i), f) !=
            fields.begin() + static_cast<std::ptrdiff_t>(i)) {
      extra.push_back(f);
    }
  }
  std::string what;
  if (missing.size() == 1 && extra.size() == 1) {
    what = fmt::format("column '{}' is missing and '{}' is unexpected (renamed?)", missing[0],
                       extra[0]);
  } else {
    if (!missing.empty()) what += fmt::format("missing column(s) {}", quotedList(missing));
    if (!extra.empty()) {
      what += fmt::format("{}unexpected or repeated column(s) {}", what.empty() ? "" : "; ",
                          quotedList(extra));
    }
  }
  if (what.empty()) {
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (fields[i] != kColumnNames[i]) {
        what = fmt::format("columns out of order: column {} is '{}', expected '{}'", i + 1,
                           fields[i], kColumnNames[i]);
        break;
      }
    }
  }
  return fmt::format("header: {} (expected exactly '{}')", what, kCsvHeader);
}

// '# key: value' → (key, value); other comments → none.
std::optional<std::pair<std::string_view, std::string_view>> parseAttributeLine(
    std::string_view line) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  if (line.empty() || line.front() != '#') return std::nullopt;
  line.remove_prefix(1);
  if (!line.empty() && line.front() == ' ') line.remove_prefix(1);
  const std::size_t colon = line.find(':');
  if (colon == std::string_view::npos) return std::nullopt;
  const std::string_view key = line.substr(0, colon);
  if (!isAttributeKey(key)) return std::nullopt;
  std::string_view value = line.substr(colon + 1);
  if (!value.empty() && value.front() == ' ') value.remove_prefix(1);
  return std::pair{key, value};
}

class CsvSource final : public RowSource {
 public:
  static Result<std::unique_ptr<RowSource>> open(const std::string& path) {
    auto s = std::unique_ptr<CsvSource>(new CsvSource(path));
    if (auto st = s->lines_.open(path); !st) return st.error();
    if (auto st = s->readPreamble(); !st) return st.error();
    return std::unique_ptr<RowSource>(std::move(s));
  }

  Result<bool> next(ParticleRow& row, TruthRow& /*truth*/) override {
    std::string_view line;
    bool terminated = true;
    while (true) {
      auto got = lines_.next(line, terminated);
      if (!got) return got.error();
      if (!*got) return false;
      if (!isBlankOrComment(line)) break;
    }
    fields_ = splitCsvLine(line);
    unterminated_ = !terminated;
    const auto fail = [&](std::string_view column, const std::string& what) -> Error {
      return Error{fmt::format("{}: column '{}': {}{}", location(), column, what, note())};
    };
    if (fields_.size() != kColumnNames.size()) {
      return Error{fmt::format("{}: expected {} fields, got {}{}", location(), kColumnNames.size(),
                               fields_.size(), note())};
    }
    std::int64_t integer = 0;
    if (auto e = parseIntegerField(fields_[kRun], std::numeric_limits<std::int32_t>::min(),
                                   std::numeric_limits<std::int32_t>::max(), integer)) {
      return fail(kColumnNames[kRun], *e);
    }
    row.run = static_cast<std::int32_t>(integer);
    if (auto e = parseIntegerField(fields_[kEvent], std::numeric_limits<std::int64_t>::min(),
                                   std::numeric_limits<std::int64_t>::max(), integer)) {
      return fail(kColumnNames[kEvent], *e);
    }
    row.event = integer;
    for (int c : {kVeto, kCharged}) {
      if (auto e = parseIntegerField(fields_[static_cast<std::size_t>(c)], 0, 1, integer)) {
        return fail(kColumnNames[static_cast<std::size_t>(c)], *e);
      }
      (c == kVeto ? row.muonVeto : row.charged) = static_cast<std::int8_t>(integer);
    }
    for (const auto& column : kEventDoubles) {
      const auto index = static_cast<std::size_t>(
          std::find(kColumnNames.begin(), kColumnNames.end(), column.name) - kColumnNames.begin());
      double x = 0.0;
      if (auto e = parseDoubleField(fields_[index], x)) return fail(column.name, *e);
      column.set(row, x);
    }
    return true;
  }

  bool hasTruth() const override { return false; }
  const Attributes& attributes() const override { return attributes_; }
  std::string location() const override {
    return fmt::format("{}: line {}", path_, lines_.lineNumber());
  }
  std::string_view note() const override {
    return unterminated_ ? kNoNewlineNote : std::string_view();
  }

 private:
  explicit CsvSource(std::string path) : path_(std::move(path)) {}

  // Attribute comments, then the header line.
  Status readPreamble() {
    std::string_view line;
    bool terminated = true;
    while (true) {
      auto got = lines_.next(line, terminated);
      if (!got) return got.error();
      if (!*got) {
        return Error{fmt::format("{}: header: missing (the file has no header line '{}')", path_,
                                 kCsvHeader)};
      }
      if (lines_.lineNumber() == 1 && line.starts_with("\xEF\xBB\xBF"))
        line.remove_prefix(3);  // UTF-8 BOM
      if (isBlankOrComment(line)) {
        if (auto kv = parseAttributeLine(line)) {
          for (const auto& [key, value] : attributes_) {
            if (key == kv->first) {
              return Error{fmt::format("{}: attribute '{}' given twice", location(), key)};
            }
          }
          attributes_.emplace_back(kv->first, kv->second);
        }
        continue;
      }
      if (auto e = checkHeader(splitCsvLine(line)))
        return Error{fmt::format("{}: {}", location(), *e)};
      return {};
    }
  }

  std::string path_;
  LineReader lines_;
  std::vector<std::string_view> fields_;
  bool unterminated_ = false;
  Attributes attributes_;
};

// ==================================================================================== HDF5

// HDF5 prints its error stack to stderr by default; the library must not print. This
// silences it for the scope of one call into HDF5 and restores what the caller had.
class Hdf5Quiet {
 public:
  Hdf5Quiet() {
    H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~Hdf5Quiet() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }
  Hdf5Quiet(const Hdf5Quiet&) = delete;
  Hdf5Quiet& operator=(const Hdf5Quiet&) = delete;

 private:
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

// The most specific message of HDF5's error stack (then cleared), e.g. "file signature not
// found" or "truncated file: eof = …".
std::string hdf5Reason() {
  std::string reason;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_UPWARD,
      [](unsigned n, const H5E_error2_t* e, void* data) -> herr_t {
        if (n == 0 && e->desc != nullptr) *static_cast<std::string*>(data) = e->desc;
        return 0;
      },
      &reason);
  H5Eclear2(H5E_DEFAULT);
  return reason.empty() ? "HDF5 error" : reason;
}

// An owned HDF5 identifier.
class Hid {
 public:
  using Closer = herr_t (*)(hid_t);
  Hid() = default;
  Hid(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  Hid(Hid&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)), closer_(o.closer_) {}
  Hid& operator=(Hid&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = std::exchange(o.id_, H5I_INVALID_HID);
      closer_ = o.closer_;
    }
    return *this;
  }
  Hid(const Hid&) = delete;
  Hid& operator=(const Hid&) = delete;
  ~Hid() { reset(); }

  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  /// Closes now; false when HDF5 reports a failure (e.g. the final write of a file).
  bool reset() {
    bool ok = true;
    if (id_ >= 0 && closer_ != nullptr) ok = closer_(id_) >= 0;
    id_ = H5I_INVALID_HID;
    return ok;
  }

 private:
  hid_t id_ = H5I_INVALID_HID;
  Closer closer_ = nullptr;
};

constexpr hsize_t kChunkRows = 16384;
constexpr unsigned kDeflateLevel = 4;

enum class Kind { I8, I32, I64, F64 };

hid_t fileType(Kind k) {
  switch (k) {
    case Kind::I8:
      return H5T_STD_I8LE;
    case Kind::I32:
      return H5T_STD_I32LE;
    case Kind::I64:
      return H5T_STD_I64LE;
    case Kind::F64:
      return H5T_IEEE_F64LE;
  }
  return H5T_IEEE_F64LE;
}

hid_t memoryType(Kind k) {
  switch (k) {
    case Kind::I8:
      return H5T_NATIVE_INT8;
    case Kind::I32:
      return H5T_NATIVE_INT32;
    case Kind::I64:
      return H5T_NATIVE_INT64;
    case Kind::F64:
      return H5T_NATIVE_DOUBLE;
  }
  return H5T_NATIVE_DOUBLE;
}

const char* kindName(Kind k) {
  switch (k) {
    case Kind::I8:
      return "8-bit signed integer";
    case Kind::I32:
      return "32-bit signed integer";
    case Kind::I64:
      return "64-bit signed integer";
    case Kind::F64:
      return "64-bit float";
  }
  return "?";
}

bool typeMatches(hid_t type, Kind k) {
  const H5T_class_t cls = H5Tget_class(type);
  const std::size_t size = H5Tget_size(type);
  switch (k) {
    case Kind::I8:
      return cls == H5T_INTEGER && size == 1 && H5Tget_sign(type) == H5T_SGN_2;
    case Kind::I32:
      return cls == H5T_INTEGER && size == 4 && H5Tget_sign(type) == H5T_SGN_2;
    case Kind::I64:
      return cls == H5T_INTEGER && size == 8 && H5Tget_sign(type) == H5T_SGN_2;
    case Kind::F64:
      return cls == H5T_FLOAT && size == 8;
  }
  return false;
}

std::string describeType(hid_t type) {
  const std::size_t bits = H5Tget_size(type) * 8;
  switch (H5Tget_class(type)) {
    case H5T_INTEGER:
      return fmt::format("{}-bit {} integer", bits,
                         H5Tget_sign(type) == H5T_SGN_2 ? "signed" : "unsigned");
    case H5T_FLOAT:
      return fmt::format("{}-bit float", bits);
    case H5T_STRING:
      return "string";
    case H5T_COMPOUND:
      return "compound";
    default:
      return "another type";
  }
}

Kind eventKind(int column) {
  switch (column) {
    case kRun:
      return Kind::I32;
    case kEvent:
      return Kind::I64;
    case kVeto:
    case kCharged:
      return Kind::I8;
    default:
      return Kind::F64;
  }
}

// --------------------------------------------------------------------------- HDF5 writer

// A property list whose objects do not record times: the only thing that makes two files
// of the same rows differ byte for byte.
Hid creationList(hid_t cls) {
  Hid plist(H5Pcreate(cls), H5Pclose);
  if (plist.valid() && H5Pset_obj_track_times(plist.get(), 0) < 0) return {};
  return plist;
}

class Hdf5Writer final : public EventWriter {
 public:
  static Result<std::unique_ptr<EventWriter>> create(const std::string& path,
                                                     const WriterOptions& options) {
    Hdf5Quiet quiet;
    auto w = std::unique_ptr<Hdf5Writer>(new Hdf5Writer(path, options.withTruth));
    if (auto s = w->createFile(options.attributes); !s) return s.error();
    return std::unique_ptr<EventWriter>(std::move(w));
  }

  ~Hdf5Writer() override {
    if (!closed_) {
      Hdf5Quiet quiet;
      closeHandles();
      removeQuietly(tmp_);
    }
  }

  Status append(std::span<const ParticleRow> rows, std::span<const TruthRow> truth) override {
    if (auto s = usable(); !s) return s;
    if (withTruth_ && truth.size() != rows.size()) {
      return fail(
          fmt::format("{}: append: {} truth rows for {} rows (a file with truth needs one per row)",
                      path_, truth.size(), rows.size()));
    }
    if (auto s = checkAppend(path_, rows, appended_, consistency_); !s)
      return fail(s.error().message);
    Hdf5Quiet quiet;
    for (std::size_t i = 0; i < rows.size(); ++i) {
      rows_.push_back(rows[i]);
      if (withTruth_) truth_.push_back(truth[i]);
      // Always whole chunks, whatever the append sizes: the layout depends on the rows only.
      if (rows_.size() == kChunkRows) {
        if (auto s = flush(); !s) return s;
      }
    }
    appended_ += rows.size();
    return {};
  }

  Status close() override {
    if (auto s = usable(); !s) return s;
    Hdf5Quiet quiet;
    if (auto s = flush(); !s) return s;
    if (!closeHandles())
      return fail(fmt::format("{}: cannot close the HDF5 file: {}", path_, hdf5Reason()));
    if (auto s = renameIntoPlace(tmp_, path_); !s) return fail(s.error().message);
    closed_ = true;
    return {};
  }

 private:
  Hdf5Writer(std::string path, bool withTruth)
      : path_(std::move(path)), tmp_(tempPathFor(path_)), withTruth_(withTruth) {
    rows_.reserve(kChunkRows);
    if (withTruth_) truth_.reserve(kChunkRows);
  }

  Status usable() const {
    if (closed_) return Error{fmt::format("{}: the writer is already closed", path_)};
    if (failed_) return Error{fmt::format("{}: the writer failed earlier: {}", path_, *failed_)};
    return {};
  }

  Status fail(std::string message) {
    failed_ = message;
    return Error{std::move(message)};
  }

  Status hdf5Error(std::string_view what) {
    return fail(fmt::format("{}: {}: {}", path_, what, hdf5Reason()));
  }

  Status createFile(const Attributes& attributes) {
    if (H5Zfilter_avail(H5Z_FILTER_DEFLATE) <= 0) {
      return Error{fmt::format("{}: the HDF5 library has no deflate filter", path_)};
    }
    // The file-creation list also creates the root group: no times there either, and the
    // attributes keep the order they were given in.
    Hid fcpl = creationList(H5P_FILE_CREATE);
    if (!fcpl.valid() ||
        H5Pset_attr_creation_order(fcpl.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED) < 0) {
      return hdf5Error("cannot set up the file-creation properties");
    }
    Hid fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
    if (!fapl.valid() || H5Pset_fclose_degree(fapl.get(), H5F_CLOSE_STRONG) < 0) {
      return hdf5Error("cannot set up the file-access properties");
    }
    file_ = Hid(H5Fcreate(tmp_.c_str(), H5F_ACC_TRUNC, fcpl.get(), fapl.get()), H5Fclose);
    if (!file_.valid()) {
      return Error{
          fmt::format("{}: cannot create the temporary file '{}': {}", path_, tmp_, hdf5Reason())};
    }
    if (auto s = writeAttributes(attributes); !s) return s;

    Hid gcpl = creationList(H5P_GROUP_CREATE);
    Hid dcpl = creationList(H5P_DATASET_CREATE);
    const hsize_t chunk = kChunkRows;
    if (!gcpl.valid() || !dcpl.valid() || H5Pset_chunk(dcpl.get(), 1, &chunk) < 0 ||
        H5Pset_shuffle(dcpl.get()) < 0 || H5Pset_deflate(dcpl.get(), kDeflateLevel) < 0) {
      return hdf5Error("cannot set up the dataset-creation properties");
    }
    events_ =
        Hid(H5Gcreate2(file_.get(), kEventsGroup, H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose);
    if (!events_.valid()) return hdf5Error("cannot create the group '/events'");
    for (int c = 0; c < kNumCols; ++c) {
      const std::string name(kColumnNames[static_cast<std::size_t>(c)]);
      auto ds = createDataset(events_.get(), name, eventKind(c), dcpl.get());
      if (!ds.valid())
        return hdf5Error(fmt::format("cannot create the dataset '/events/{}'", name));
      eventSets_[static_cast<std::size_t>(c)] = std::move(ds);
    }
    if (withTruth_) {
      truthGroup_ =
          Hid(H5Gcreate2(file_.get(), kTruthGroup, H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose);
      if (!truthGroup_.valid()) return hdf5Error("cannot create the group '/truth'");
      truthSets_[0] = createDataset(truthGroup_.get(), kTruthPdg, Kind::I32, dcpl.get());
      for (std::size_t i = 0; i < kTruthDoubles.size(); ++i) {
        truthSets_[i + 1] =
            createDataset(truthGroup_.get(), kTruthDoubles[i].name, Kind::F64, dcpl.get());
      }
      for (const Hid& ds : truthSets_) {
        if (!ds.valid()) return hdf5Error("cannot create the datasets of '/truth'");
      }
    }
    return {};
  }

  static Hid createDataset(hid_t group, const std::string& name, Kind kind, hid_t dcpl) {
    const hsize_t dims = 0;
    const hsize_t maxDims = H5S_UNLIMITED;
    Hid space(H5Screate_simple(1, &dims, &maxDims), H5Sclose);
    if (!space.valid()) return {};
    return Hid(H5Dcreate2(group, name.c_str(), fileType(kind), space.get(), H5P_DEFAULT, dcpl,
                          H5P_DEFAULT),
               H5Dclose);
  }

  // Variable-length UTF-8 strings, scalar, on the root group.
  Status writeAttributes(const Attributes& attributes) {
    if (attributes.empty()) return {};
    Hid type(H5Tcopy(H5T_C_S1), H5Tclose);
    Hid space(H5Screate(H5S_SCALAR), H5Sclose);
    if (!type.valid() || !space.valid() || H5Tset_size(type.get(), H5T_VARIABLE) < 0 ||
        H5Tset_cset(type.get(), H5T_CSET_UTF8) < 0) {
      return hdf5Error("cannot set up the string type of the attributes");
    }
    for (const auto& [key, value] : attributes) {
      Hid attr(
          H5Acreate2(file_.get(), key.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT),
          H5Aclose);
      const char* text = value.c_str();
      if (!attr.valid() || H5Awrite(attr.get(), type.get(), &text) < 0) {
        return hdf5Error(fmt::format("cannot write the attribute '{}'", key));
      }
    }
    return {};
  }

  static bool writeColumn(hid_t dataset, hsize_t offset, hsize_t count, Kind kind,
                          const void* data) {
    const hsize_t size = offset + count;
    if (H5Dset_extent(dataset, &size) < 0) return false;
    Hid fileSpace(H5Dget_space(dataset), H5Sclose);
    Hid memSpace(H5Screate_simple(1, &count, nullptr), H5Sclose);
    if (!fileSpace.valid() || !memSpace.valid()) return false;
    if (H5Sselect_hyperslab(fileSpace.get(), H5S_SELECT_SET, &offset, nullptr, &count, nullptr) <
        0) {
      return false;
    }
    return H5Dwrite(dataset, memoryType(kind), memSpace.get(), fileSpace.get(), H5P_DEFAULT,
                    data) >= 0;
  }

  Status flush() {
    if (rows_.empty()) return {};
    const hsize_t count = rows_.size();
    const auto write = [&](const Hid& ds, std::string_view group, std::string_view name, Kind kind,
                           const void* data) -> Status {
      if (!writeColumn(ds.get(), written_, count, kind, data)) {
        return hdf5Error(fmt::format("cannot write the dataset '/{}/{}'", group, name));
      }
      return {};
    };
    const auto gather = [&](auto&& get, auto& out) {
      out.clear();
      for (const ParticleRow& r : rows_) out.push_back(get(r));
    };
    std::vector<std::int32_t> i32;
    std::vector<std::int64_t> i64;
    std::vector<std::int8_t> i8;
    std::vector<double> f64;
    gather([](const ParticleRow& r) { return r.run; }, i32);
    if (auto s = write(eventSets_[kRun], kEventsGroup, kColumnNames[kRun], Kind::I32, i32.data());
        !s)
      return s;
    gather([](const ParticleRow& r) { return r.event; }, i64);
    if (auto s =
            write(eventSets_[kEvent], kEventsGroup, kColumnNames[kEvent], Kind::I64, i64.data());
        !s) {
      return s;
    }
    gather([](const ParticleRow& r) { return r.muonVeto; }, i8);
    if (auto s = write(eventSets_[kVeto], kEventsGroup, kColumnNames[kVeto], Kind::I8, i8.data());
        !s)
      return s;
    gather([](const ParticleRow& r) { return r.charged; }, i8);
    if (auto s =
            write(eventSets_[kCharged], kEventsGroup, kColumnNames[kCharged], Kind::I8, i8.data());
        !s) {
      return s;
    }
    for (const auto& column : kEventDoubles) {
      const auto index = static_cast<std::size_t>(
          std::find(kColumnNames.begin(), kColumnNames.end(), column.name) - kColumnNames.begin());
      gather(column.get, f64);
      if (auto s = write(eventSets_[index], kEventsGroup, column.name, Kind::F64, f64.data()); !s)
        return s;
    }
    if (withTruth_) {
      i32.clear();
      for (const TruthRow& t : truth_) i32.push_back(t.pdg);
      if (auto s = write(truthSets_[0], kTruthGroup, kTruthPdg, Kind::I32, i32.data()); !s)
        return s;
      for (std::size_t i = 0; i < kTruthDoubles.size(); ++i) {
        f64.clear();
        for (const TruthRow& t : truth_) f64.push_back(kTruthDoubles[i].get(t));
        if (auto s =
                write(truthSets_[i + 1], kTruthGroup, kTruthDoubles[i].name, Kind::F64, f64.data());
            !s) {
          return s;
        }
      }
    }
    written_ += count;
    rows_.clear();
    truth_.clear();
    return {};
  }

  bool closeHandles() {
    bool ok = true;
    for (Hid& ds : eventSets_) ok = ds.reset() && ok;
    for (Hid& ds : truthSets_) ok = ds.reset() && ok;
    ok = events_.reset() && ok;
    ok = truthGroup_.reset() && ok;
    ok = file_.reset() && ok;
    return ok;
  }

  std::string path_;
  std::string tmp_;
  bool withTruth_;
  Hid file_;
  Hid events_;
  Hid truthGroup_;
  std::array<Hid, kNumCols> eventSets_;
  std::array<Hid, 1 + kTruthDoubles.size()> truthSets_;
  std::vector<ParticleRow> rows_;  // at most one chunk
  std::vector<TruthRow> truth_;
  hsize_t written_ = 0;
  std::uint64_t appended_ = 0;
  EventConsistency consistency_;
  std::optional<std::string> failed_;
  bool closed_ = false;
};

// --------------------------------------------------------------------------- HDF5 reader

// One 1-D dataset of a group, checked for type; reads ranges into a typed buffer.
struct Hdf5Column {
  Hid dataset;
  Kind kind = Kind::F64;
  std::string name;  // "/events/run"
};

class Hdf5Source final : public RowSource {
 public:
  static Result<std::unique_ptr<RowSource>> open(const std::string& path, std::size_t readRows) {
    Hdf5Quiet quiet;
    auto s = std::unique_ptr<Hdf5Source>(new Hdf5Source(path, readRows));
    if (auto st = s->openFile(); !st) return st.error();
    return std::unique_ptr<RowSource>(std::move(s));
  }

  Result<bool> next(ParticleRow& row, TruthRow& truth) override {
    if (pos_ == loaded_) {
      if (first_ + loaded_ == rows_) return false;
      Hdf5Quiet quiet;
      if (auto s = load(first_ + loaded_); !s) return s.error();
    }
    const std::size_t i = pos_++;
    row.run = run_[i];
    row.event = event_[i];
    row.muonVeto = veto_[i];
    row.charged = charged_[i];
    for (std::size_t c = 0; c < kEventDoubles.size(); ++c)
      kEventDoubles[c].set(row, doubles_[c][i]);
    if (hasTruth_) {
      truth.pdg = pdg_[i];
      for (std::size_t c = 0; c < kTruthDoubles.size(); ++c)
        kTruthDoubles[c].set(truth, truthDoubles_[c][i]);
    }
    return true;
  }

  bool hasTruth() const override { return hasTruth_; }
  const Attributes& attributes() const override { return attributes_; }
  std::string location() const override {
    return fmt::format("{}: record {}", path_, first_ + pos_ - (pos_ > 0 ? 1 : 0));
  }

 private:
  Hdf5Source(std::string path, std::size_t readRows)
      : path_(std::move(path)), readRows_(readRows) {}

  Error error(std::string_view what) const { return Error{fmt::format("{}: {}", path_, what)}; }

  Status openFile() {
    const htri_t isHdf5 = H5Fis_hdf5(path_.c_str());
    if (isHdf5 <= 0) {
      H5Eclear2(H5E_DEFAULT);
      return error(
          "not an HDF5 file (no HDF5 signature; event files are HDF5 unless the name ends with "
          "\".csv\")");
    }
    file_ = Hid(H5Fopen(path_.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    if (!file_.valid()) return error(fmt::format("cannot open the HDF5 file: {}", hdf5Reason()));
    if (auto s = readAttributes(); !s) return s;

    std::vector<std::pair<std::string, Kind>> eventColumns;
    for (int c = 0; c < kNumCols; ++c) {
      eventColumns.emplace_back(kColumnNames[static_cast<std::size_t>(c)], eventKind(c));
    }
    auto events = openColumns(kEventsGroup, eventColumns, true);
    if (!events) return events.error();
    eventCols_ = std::move(*events);
    rows_ = rowsOf_;

    std::vector<std::pair<std::string, Kind>> truthColumns{{kTruthPdg, Kind::I32}};
    for (const auto& column : kTruthDoubles) truthColumns.emplace_back(column.name, Kind::F64);
    auto truth = openColumns(kTruthGroup, truthColumns, false);
    if (!truth) return truth.error();
    truthCols_ = std::move(*truth);
    hasTruth_ = !truthCols_.empty();
    if (hasTruth_ && rowsOf_ != rows_) {
      return error(fmt::format("the datasets of '/truth' have {} records, those of '/events' {}",
                               rowsOf_, rows_));
    }
    return {};
  }

  // Opens every listed dataset of a group (all required), checking names, types, rank and
  // equal lengths; an absent optional group gives no columns. Sets rowsOf_.
  Result<std::vector<Hdf5Column>> openColumns(
      const char* groupName, const std::vector<std::pair<std::string, Kind>>& columns,
      bool required) {
    const htri_t exists = H5Lexists(file_.get(), groupName, H5P_DEFAULT);
    if (exists <= 0) {
      H5Eclear2(H5E_DEFAULT);
      if (!required) return std::vector<Hdf5Column>{};
      return error(fmt::format("missing group '/{}' (not an emcalign event file?)", groupName));
    }
    Hid group(H5Gopen2(file_.get(), groupName, H5P_DEFAULT), H5Gclose);
    if (!group.valid())
      return error(fmt::format("'/{}' is not a group: {}", groupName, hdf5Reason()));

    // Every link of the group must be a known column.
    std::vector<std::string> links;
    hsize_t index = 0;
    const herr_t iterated = H5Literate(
        group.get(), H5_INDEX_NAME, H5_ITER_INC, &index,
        [](hid_t, const char* name, const H5L_info_t*, void* data) -> herr_t {
          static_cast<std::vector<std::string>*>(data)->emplace_back(name);
          return 0;
        },
        &links);
    if (iterated < 0) return error(fmt::format("cannot list '/{}': {}", groupName, hdf5Reason()));
    for (const std::string& link : links) {
      bool known = false;
      for (const auto& column : columns) known = known || column.first == link;
      if (!known) return error(fmt::format("unexpected dataset '/{}/{}'", groupName, link));
    }

    std::vector<Hdf5Column> out;
    for (const auto& [name, kind] : columns) {
      Hdf5Column column{{}, kind, fmt::format("/{}/{}", groupName, name)};
      if (H5Lexists(group.get(), name.c_str(), H5P_DEFAULT) <= 0) {
        H5Eclear2(H5E_DEFAULT);
        return error(fmt::format("missing dataset '{}' (column '{}')", column.name, name));
      }
      column.dataset = Hid(H5Dopen2(group.get(), name.c_str(), H5P_DEFAULT), H5Dclose);
      if (!column.dataset.valid()) {
        return error(fmt::format("'{}' is not a dataset: {}", column.name, hdf5Reason()));
      }
      Hid type(H5Dget_type(column.dataset.get()), H5Tclose);
      if (!type.valid()) return error(fmt::format("dataset '{}': {}", column.name, hdf5Reason()));
      if (!typeMatches(type.get(), kind)) {
        return error(fmt::format("dataset '{}' (column '{}'): type is {}, expected {}", column.name,
                                 name, describeType(type.get()), kindName(kind)));
      }
      Hid space(H5Dget_space(column.dataset.get()), H5Sclose);
      hsize_t dims = 0;
      if (!space.valid() || H5Sget_simple_extent_ndims(space.get()) != 1 ||
          H5Sget_simple_extent_dims(space.get(), &dims, nullptr) != 1) {
        H5Eclear2(H5E_DEFAULT);
        return error(
            fmt::format("dataset '{}' (column '{}'): not one-dimensional", column.name, name));
      }
      if (!out.empty() && dims != rowsOf_) {
        return error(
            fmt::format("dataset '{}' (column '{}') has {} records, '{}' has {} (datasets of "
                        "unequal length: truncated or inconsistent file)",
                        column.name, name, dims, out.front().name, rowsOf_));
      }
      rowsOf_ = dims;
      out.push_back(std::move(column));
    }
    return out;
  }

  // String attributes of the root group, in creation order when the file tracks it;
  // attributes of other types are skipped.
  Status readAttributes() {
    Hid root(H5Gopen2(file_.get(), "/", H5P_DEFAULT), H5Gclose);
    if (!root.valid()) return error(fmt::format("cannot open the root group: {}", hdf5Reason()));
    std::vector<std::string> names;
    const auto collect = [](hid_t, const char* name, const H5A_info_t*, void* data) -> herr_t {
      static_cast<std::vector<std::string>*>(data)->emplace_back(name);
      return 0;
    };
    hsize_t index = 0;
    if (H5Aiterate2(root.get(), H5_INDEX_CRT_ORDER, H5_ITER_INC, &index, collect, &names) < 0) {
      H5Eclear2(H5E_DEFAULT);
      names.clear();
      index = 0;
      if (H5Aiterate2(root.get(), H5_INDEX_NAME, H5_ITER_INC, &index, collect, &names) < 0) {
        return error(fmt::format("cannot list the attributes: {}", hdf5Reason()));
      }
    }
    for (const std::string& name : names) {
      Hid attr(H5Aopen(root.get(), name.c_str(), H5P_DEFAULT), H5Aclose);
      Hid type(attr.valid() ? H5Aget_type(attr.get()) : H5I_INVALID_HID, H5Tclose);
      Hid space(attr.valid() ? H5Aget_space(attr.get()) : H5I_INVALID_HID, H5Sclose);
      if (!attr.valid() || !type.valid() || !space.valid()) {
        return error(fmt::format("cannot open the attribute '{}': {}", name, hdf5Reason()));
      }
      if (H5Tget_class(type.get()) != H5T_STRING || H5Sget_simple_extent_npoints(space.get()) != 1)
        continue;
      Hid memType(H5Tcopy(H5T_C_S1), H5Tclose);
      std::string value;
      bool ok = memType.valid() && H5Tset_cset(memType.get(), H5Tget_cset(type.get())) >= 0;
      if (ok && H5Tis_variable_str(type.get()) > 0) {
        char* text = nullptr;
        ok = H5Tset_size(memType.get(), H5T_VARIABLE) >= 0 &&
             H5Aread(attr.get(), memType.get(), &text) >= 0;
        if (ok && text != nullptr) value = text;
        if (text != nullptr) H5free_memory(text);
      } else if (ok) {
        const std::size_t size = H5Tget_size(type.get());
        std::string buffer(size, '\0');
        ok = H5Tset_size(memType.get(), size) >= 0 &&
             H5Tset_strpad(memType.get(), H5T_STR_NULLPAD) >= 0 &&
             H5Aread(attr.get(), memType.get(), buffer.data()) >= 0;
        value = buffer.substr(0, buffer.find('\0'));
      }
      if (!ok) return error(fmt::format("cannot read the attribute '{}': {}", name, hdf5Reason()));
      attributes_.emplace_back(name, std::move(value));
    }
    return {};
  }

  static bool readRange(const Hdf5Column& column, hsize_t offset, hsize_t count, void* out) {
    Hid fileSpace(H5Dget_space(column.dataset.get()), H5Sclose);
    Hid memSpace(H5Screate_simple(1, &count, nullptr), H5Sclose);
    if (!fileSpace.valid() || !memSpace.valid()) return false;
    if (H5Sselect_hyperslab(fileSpace.get(), H5S_SELECT_SET, &offset, nullptr, &count, nullptr) <
        0) {
      return false;
    }
    return H5Dread(column.dataset.get(), memoryType(column.kind), memSpace.get(), fileSpace.get(),
                   H5P_DEFAULT, out) >= 0;
  }

  Status load(hsize_t offset) {
    const hsize_t count = std::min<hsize_t>(readRows_, rows_ - offset);
    const auto read = [&](const Hdf5Column& column, auto& buffer) -> Status {
      buffer.resize(count);
      if (!readRange(column, offset, count, buffer.data())) {
        return error(fmt::format("records {}..{}: cannot read dataset '{}': {}", offset,
                                 offset + count - 1, column.name, hdf5Reason()));
      }
      return {};
    };
    if (auto s = read(eventCols_[kRun], run_); !s) return s;
    if (auto s = read(eventCols_[kEvent], event_); !s) return s;
    if (auto s = read(eventCols_[kVeto], veto_); !s) return s;
    if (auto s = read(eventCols_[kCharged], charged_); !s) return s;
    for (std::size_t c = 0; c < kEventDoubles.size(); ++c) {
      const auto index = static_cast<std::size_t>(
          std::find(kColumnNames.begin(), kColumnNames.end(), kEventDoubles[c].name) -
          kColumnNames.begin());
      if (auto s = read(eventCols_[index], doubles_[c]); !s) return s;
    }
    if (hasTruth_) {
      if (auto s = read(truthCols_[0], pdg_); !s) return s;
      for (std::size_t c = 0; c < kTruthDoubles.size(); ++c) {
        if (auto s = read(truthCols_[c + 1], truthDoubles_[c]); !s) return s;
      }
    }
    first_ = offset;
    loaded_ = count;
    pos_ = 0;
    return {};
  }

  std::string path_;
  hsize_t readRows_;
  Hid file_;
  Attributes attributes_;
  std::vector<Hdf5Column> eventCols_;
  std::vector<Hdf5Column> truthCols_;
  bool hasTruth_ = false;
  hsize_t rowsOf_ = 0;  // length found by the last openColumns
  hsize_t rows_ = 0;
  // The loaded range [first_, first_ + loaded_) and the next row in it.
  hsize_t first_ = 0;
  hsize_t loaded_ = 0;
  hsize_t pos_ = 0;
  std::vector<std::int32_t> run_;
  std::vector<std::int64_t> event_;
  std::vector<std::int8_t> veto_;
  std::vector<std::int8_t> charged_;
  std::array<std::vector<double>, kEventDoubles.size()> doubles_;
  std::vector<std::int32_t> pdg_;
  std::array<std::vector<double>, kTruthDoubles.size()> truthDoubles_;
};

// ============================================================================ the reader

class EventReaderImpl final : public EventReader {
 public:
  EventReaderImpl(std::vector<std::string> paths, ReaderOptions options)
      : paths_(std::move(paths)), options_(options) {}

  Status start() { return openFile(0); }

  Result<bool> next(std::vector<ParticleRow>& rows) override {
    rows.clear();
    truth_.clear();
    if (failed_) return *failed_;
    while (true) {
      if (exhausted_) {
        if (index_ + 1 >= paths_.size()) return false;
        if (auto s = openFile(index_ + 1); !s) return fail(s.error());
      }
      if (carry_) {
        rows.push_back(*carry_);
        if (source_->hasTruth()) truth_.push_back(carryTruth_);
        carry_.reset();
      }
      ParticleRow row;
      TruthRow truth;
      while (true) {
        auto got = source_->next(row, truth);
        if (!got) return fail(got.error());
        if (!*got) {
          exhausted_ = true;
          break;
        }
        auto issue = checkRow(row);
        if (!issue) issue = consistency_.check(row);
        if (issue) {
          return fail(Error{fmt::format("{}: column '{}': {}{}", source_->location(), issue->column,
                                        issue->what, source_->note())});
        }
        if (rows.size() >= options_.blockRows && !sameEvent(row, rows.back())) {
          carry_ = row;
          carryTruth_ = truth;
          break;
        }
        rows.push_back(row);
        if (source_->hasTruth()) truth_.push_back(truth);
      }
      if (!rows.empty()) return true;
    }
  }

  const std::vector<TruthRow>* truth() const override {
    return source_ && source_->hasTruth() ? &truth_ : nullptr;
  }

  const Attributes& attributes() const override {
    static const Attributes kNone;
    return source_ ? source_->attributes() : kNone;
  }

 private:
  Status openFile(std::size_t index) {
    const std::string& path = paths_[index];
    // Read rows in pieces of the block size (not fewer than a few hundred, so a tiny
    // blockRows does not turn into one HDF5 read per row).
    const std::size_t readRows = std::max<std::size_t>(options_.blockRows, 256);
    auto source = formatOf(path) == EventFormat::Csv ? CsvSource::open(path)
                                                     : Hdf5Source::open(path, readRows);
    if (!source) return source.error();
    source_ = std::move(*source);
    index_ = index;
    exhausted_ = false;
    carry_.reset();
    consistency_.reset();
    return {};
  }

  Error fail(Error e) {
    failed_ = e;
    return e;
  }

  std::vector<std::string> paths_;
  ReaderOptions options_;
  std::size_t index_ = 0;
  std::unique_ptr<RowSource> source_;
  bool exhausted_ = false;
  std::optional<ParticleRow> carry_;
  TruthRow carryTruth_;
  std::vector<TruthRow> truth_;
  EventConsistency consistency_;
  std::optional<Error> failed_;
};

}  // namespace

// ============================================================================ public API

Result<std::unique_ptr<EventWriter>> EventWriter::open(const std::string& path,
                                                       WriterOptions options) {
  const EventFormat format = formatOf(path);
  if (auto s = checkAttributes(path, options.attributes, format); !s) return s.error();
  if (format == EventFormat::Csv) return CsvWriter::create(path, options);
  return Hdf5Writer::create(path, options);
}

Result<std::unique_ptr<EventReader>> EventReader::open(std::vector<std::string> paths,
                                                       ReaderOptions options) {
  if (paths.empty()) return Error{"no event files given"};
  if (options.blockRows == 0) return Error{"event reader: blockRows must be at least 1"};
  // Every file is checked before any is read: a missing file is found at once, not after
  // hours of reading the ones before it.
  for (const std::string& path : paths) {
    std::error_code ec;
    const auto status = fs::status(path, ec);
    if (!fs::exists(status)) return Error{fmt::format("{}: no such file", path)};
    if (!fs::is_regular_file(status)) return Error{fmt::format("{}: not a regular file", path)};
  }
  auto reader = std::make_unique<EventReaderImpl>(std::move(paths), options);
  if (auto s = reader->start(); !s) return s.error();
  return std::unique_ptr<EventReader>(std::move(reader));
}

}  // namespace emcalign::io
