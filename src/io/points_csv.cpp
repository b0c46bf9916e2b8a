// A CSV of points on a stream (io/points_csv.hpp).

#include "emcalign/io/points_csv.hpp"

#include <array>
#include <string_view>

#include <fmt/format.h>

#include "emcalign/core/units.hpp"
#include "emcalign/io/csv.hpp"

namespace emcalign::io {

namespace {

constexpr std::array<const char*, 3> kColumns = {"x_cm", "y_cm", "z_cm"};

// The next line of `in` into `line` (false at the end); a line of three numbers is short: a
// longer one (no newline in megabytes: /dev/zero, a binary file) is refused.
Result<bool> nextLine(std::istream& in, std::string& line, long lineNo, const std::string& name) {
  line.clear();
  for (int c = in.get(); c != std::char_traits<char>::eof(); c = in.get()) {
    if (c == '\n') return true;
    if (line.size() == kMaxPointLine) {
      return Error{
          fmt::format("{}, line {}: longer than {} MiB: not a CSV of points", name, lineNo + 1, kMaxPointLine >> 20)};
    }
    line += static_cast<char>(c);
  }
  return !line.empty();
}

Result<Vec3> pointOf(const std::vector<std::string_view>& fields, long lineNo, const std::string& name) {
  if (fields.size() != 3) {
    return Error{fmt::format("{}, line {}: expected 3 columns (x_cm,y_cm,z_cm), got {}", name, lineNo, fields.size())};
  }
  Vec3 p;
  for (std::size_t i = 0; i < 3; ++i) {
    const auto v = parseFiniteDouble(fields[i]);
    if (!v) {
      return Error{fmt::format("{}, line {}, column '{}': not a finite number: {}", name, lineNo, kColumns[i],
                               quotedText(fields[i]))};
    }
    p[static_cast<Eigen::Index>(i)] = *v * units::cm;
  }
  return p;
}

}  // namespace

Result<std::vector<Vec3>> readPointsCsv(std::istream& in, const std::string& name) {
  std::vector<Vec3> points;
  std::string line;
  long lineNo = 0;
  bool header = false;
  while (true) {
    auto more = nextLine(in, line, lineNo, name);
    if (!more) return more.error();
    if (!*more) break;
    ++lineNo;
    if (isBlankOrComment(line)) continue;
    const auto fields = splitCsvLine(line);
    if (!header) {
      if (fields.size() != 3 || fields[0] != kColumns[0] || fields[1] != kColumns[1] || fields[2] != kColumns[2]) {
        return Error{
            fmt::format("{}, line {}: expected the header x_cm,y_cm,z_cm, got {}", name, lineNo, quotedText(line))};
      }
      header = true;
      continue;
    }
    auto p = pointOf(fields, lineNo, name);
    if (!p) return p.error();
    if (points.size() == kMaxPoints) {
      return Error{fmt::format("{}: more than {} points: give them in pieces", name, kMaxPoints)};
    }
    points.push_back(*p);
  }
  if (!header) return Error{fmt::format("{}: no header line x_cm,y_cm,z_cm", name)};
  return points;
}

}  // namespace emcalign::io
