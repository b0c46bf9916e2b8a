// The CSV event format (docs/contract.md §6): the writer and the streaming row source.

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>

#include <fmt/format.h>

#include "emcalign/io/csv.hpp"
#include "emcalign/io/file_kind.hpp"
#include "emcalign/io/output_file.hpp"
#include "event_file_internal.hpp"

namespace emcalign::io::detail {

namespace {

// ===================================================================================== CSV

constexpr std::size_t kCsvFlushBytes = std::size_t{1} << 20;

class CsvWriter final : public EventWriter {
 public:
  static Result<std::unique_ptr<EventWriter>> create(const std::string& path, const WriterOptions& options) {
    auto out = OutputFile::open(path, options.placement);
    if (!out) return out.error();
    auto w = std::unique_ptr<CsvWriter>(new CsvWriter(path, std::move(*out)));
    for (const auto& [key, value] : options.attributes) {
      fmt::format_to(std::back_inserter(w->buffer_), "# {}: {}\n", key, value);
    }
    fmt::format_to(std::back_inserter(w->buffer_), "{}\n", kCsvHeader);
    return std::unique_ptr<EventWriter>(std::move(w));
  }

  Status append(std::span<const ParticleRow> rows, std::span<const TruthRow> /*truth*/,
                std::span<const Hit> /*hits*/) override {
    if (auto s = usable(); !s) return s;
    if (auto s = checkAppend(path_, rows, {}, false, appended_, consistency_); !s) return fail(s.error().message);
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
    if (auto s = out_->commit(); !s) return fail(s.error().message);
    state_.close();
    return {};
  }

 private:
  CsvWriter(std::string path, std::unique_ptr<OutputFile> out) : path_(std::move(path)), out_(std::move(out)) {}

  [[nodiscard]] Status usable() const { return state_.usable(); }
  Status fail(std::string message) { return state_.fail(std::move(message)); }

  Status flush() {
    if (buffer_.size() == 0) return {};
    if (std::fwrite(buffer_.data(), 1, buffer_.size(), out_->stream()) != buffer_.size()) {
      return fail(fmt::format("{}: write failed: {}", path_, std::strerror(errno)));
    }
    buffer_.clear();
    return {};
  }

  std::string path_;
  std::unique_ptr<OutputFile> out_;  // destroyed uncommitted: its temporary is removed
  fmt::memory_buffer buffer_;
  std::uint64_t appended_ = 0;
  EventConsistency consistency_;
  WriterState state_{path_};  // after path_
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
    if (file_ == nullptr) return Error{fmt::format("{}: cannot open: {}", path, std::strerror(errno))};
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
        return Error{fmt::format("{}: line {}: longer than {} MiB (not an event CSV file?)", path_, lineNumber_ + 1,
                                 kMaxLineBytes >> 20)};
      }
      const std::size_t old = buffer_.size();
      buffer_.resize(old + kReadBytes);
      const std::size_t got = std::fread(buffer_.data() + old, 1, kReadBytes, file_);
      buffer_.resize(old + got);
      if (got < kReadBytes) {
        if (std::ferror(file_)) {
          return Error{fmt::format("{}: line {}: read error: {}", path_, lineNumber_ + 1, std::strerror(errno))};
        }
        eof_ = true;
      }
    }
  }

  /// 1-based physical number of the line last returned.
  [[nodiscard]] std::uint64_t lineNumber() const { return lineNumber_; }

 private:
  std::string path_;
  std::FILE* file_ = nullptr;
  std::string buffer_;
  std::size_t begin_ = 0;
  std::size_t scanFrom_ = 0;
  bool eof_ = false;
  std::uint64_t lineNumber_ = 0;
};

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
    return fmt::format("{} is not allowed (leave the field empty for a missing value)", quotedText(field));
  }
  return fmt::format("{} is not a finite number", quotedText(field));
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

std::optional<std::string> parseIntegerField(std::string_view field, std::int64_t lo, std::int64_t hi,
                                             std::int64_t& out) {
  if (field.empty()) return "empty (a value is required)";
  std::string_view digits = field;
  if (digits.front() == '+') digits.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), out);
  if (ec == std::errc() && ptr == digits.data() + digits.size() && !digits.empty()) {
    if (out < lo || out > hi) return fmt::format("{} is outside [{}, {}]", out, lo, hi);
    return std::nullopt;
  }
  if (ec == std::errc::result_out_of_range) return fmt::format("{} is out of range", quotedText(field));
  if (parseFiniteDouble(field)) {
    return fmt::format("{} is not an integer (write it without a decimal point or exponent)", quotedText(field));
  }
  return notANumber(field);
}

// The first names of a list, then how many in all: a message never lists fifty columns.
std::string quotedList(const std::vector<std::string_view>& names) {
  constexpr std::size_t kShown = 6;
  std::string out;
  for (std::size_t k = 0; k < names.size() && k < kShown; ++k) {
    out += fmt::format("{}{}", k == 0 ? "" : ", ", quotedText(names[k]));
  }
  if (names.size() > kShown) out += fmt::format(", … ({} in all)", names.size());
  return out;
}

// What is wrong with a header line, or none.
std::optional<std::string> checkHeader(const std::vector<std::string_view>& fields) {
  if (fields.size() == kColumnNames.size() && std::equal(fields.begin(), fields.end(), kColumnNames.begin())) {
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
    if (!contains(kColumnNames, f) || std::find(fields.begin(), fields.begin() + static_cast<std::ptrdiff_t>(i), f) !=
                                          fields.begin() + static_cast<std::ptrdiff_t>(i)) {
      extra.push_back(f);
    }
  }
  if (missing.size() == kColumnNames.size()) {  // a header of something else: what it has, briefly
    return fmt::format("header: none of an event file's columns ('{}', '{}', '{}', …); this one has {}",
                       kColumnNames[0], kColumnNames[1], kColumnNames[2], quotedList(fields));
  }
  std::string what;
  if (missing.size() == 1 && extra.size() == 1) {
    what = fmt::format("column '{}' is missing and {} is unexpected (renamed?)", missing[0], quotedText(extra[0]));
  } else {
    if (!missing.empty()) what += fmt::format("missing column(s) {}", quotedList(missing));
    if (!extra.empty()) {
      what += fmt::format("{}unexpected or repeated column(s) {}", what.empty() ? "" : "; ", quotedList(extra));
    }
  }
  if (what.empty()) {
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (fields[i] != kColumnNames[i]) {
        what = fmt::format("columns out of order: column {} is {}, expected '{}'", i + 1, quotedText(fields[i]),
                           kColumnNames[i]);
        break;
      }
    }
  }
  return fmt::format("header: {} (expected exactly '{}')", what, kCsvHeader);
}

// '# key: value' → (key, value); other comments → none.
std::optional<std::pair<std::string_view, std::string_view>> parseAttributeLine(std::string_view line) {
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

  Result<bool> next(ParticleRow& row, TruthRow& /*truth*/, std::vector<Hit>& /*hits*/) override {
    row.hitCount = 0;
    std::string_view line;
    bool terminated = true;
    while (true) {
      auto got = lines_.next(line, terminated);
      if (!got) return got.error();
      if (!*got) return false;
      if (!isBlankOrComment(line)) break;
    }
    if (!terminated) {
      // A cut inside the last field would still read as a number: a row must be whole.
      return Error{
          fmt::format("{}: the file ends inside this row (the last line has no newline): truncated? Every "
                      "row, the last too, ends with a newline",
                      location())};
    }
    fields_ = splitCsvLine(line);
    const auto fail = [&](std::string_view column, const std::string& what) -> Error {
      return Error{fmt::format("{}: column '{}': {}", location(), column, what)};
    };
    if (fields_.size() != kColumnNames.size()) {
      return Error{fmt::format("{}: expected {} fields, got {}", location(), kColumnNames.size(), fields_.size())};
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
      const auto index = static_cast<std::size_t>(std::find(kColumnNames.begin(), kColumnNames.end(), column.name) -
                                                  kColumnNames.begin());
      double x = 0.0;
      if (auto e = parseDoubleField(fields_[index], x)) return fail(column.name, *e);
      column.set(row, x);
    }
    return true;
  }

  [[nodiscard]] bool hasTruth() const override { return false; }
  [[nodiscard]] const Attributes& attributes() const override { return attributes_; }
  [[nodiscard]] std::string location() const override { return fmt::format("{}: line {}", path_, lines_.lineNumber()); }

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
        return Error{fmt::format("{}: header: missing (the file has no header line '{}')", path_, kCsvHeader)};
      }
      if (lines_.lineNumber() == 1 && line.starts_with("\xEF\xBB\xBF")) line.remove_prefix(3);  // UTF-8 BOM
      if (isBlankOrComment(line)) {
        if (auto kv = parseAttributeLine(line)) {
          for (const auto& [key, value] : attributes_) {
            if (key == kv->first) {
              return Error{fmt::format("{}: attribute {} given twice", location(), quotedText(key))};
            }
          }
          attributes_.emplace_back(kv->first, kv->second);
        }
        continue;
      }
      if (auto e = checkHeader(splitCsvLine(line))) {
        // Another of emcalign's files (a conditions export, a profile, …) is named as what it is.
        if (const std::string kind = describeFileAt(path_); !kind.empty() && kind != kCsvEventFileKind) {
          return Error{fmt::format("{}: this is {}, not an event file", path_, kind)};
        }
        return Error{fmt::format("{}: {}", location(), *e)};
      }
      return {};
    }
  }

  std::string path_;
  LineReader lines_;
  std::vector<std::string_view> fields_;
  Attributes attributes_;
};

}  // namespace

Result<std::unique_ptr<EventWriter>> openCsvWriter(const std::string& path, const WriterOptions& options) {
  return CsvWriter::create(path, options);
}

Result<std::unique_ptr<RowSource>> openCsvSource(const std::string& path) { return CsvSource::open(path); }

}  // namespace emcalign::io::detail
