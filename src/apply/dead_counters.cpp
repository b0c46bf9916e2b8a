#include "emcalign/apply/dead_counters.hpp"

#include <algorithm>
#include <charconv>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/text.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/csv.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/sim/reconstruction.hpp"

namespace emcalign::apply {

Result<CounterOccupancy> countCounterHits(const std::vector<std::string>& paths, const geometry::Calorimeter& calo) {
  io::ReaderOptions ro;
  ro.truth = false;
  ro.hits = true;
  auto reader = io::EventReader::open(paths, ro);
  if (!reader) return reader.error();
  CounterOccupancy out;
  out.hits.assign(static_cast<std::size_t>(calo.size()), 0);
  std::vector<ParticleRow> rows;
  while (true) {
    auto more = (*reader)->next(rows);
    if (!more) return more.error();
    if (!*more) break;
    const std::string& path = (*reader)->path();
    const std::vector<Hit>* hits = (*reader)->hits();
    if (hits == nullptr) {
      return Error{
          fmt::format("{}: the file has no hits (the counters of each cluster), which dead counters are "
                      "found from: HDF5 event files written with hits (simulate writes them unless "
                      "--no-hits; CSV has none)",
                      path)};
    }
    for (std::size_t i = 0; i < rows.size(); ++i) {
      if (i == 0 || !sameEvent(rows[i], rows[i - 1])) ++out.events;  // a block holds whole events
      if (rows[i].hasCluster()) ++out.clusterRows;
    }
    for (const Hit& h : *hits) {
      if (h.counter < 0 || h.counter >= calo.size()) {
        return Error{fmt::format("{}: a cluster has counter {}, which the detector does not have (0..{})", path,
                                 h.counter, calo.size() - 1)};
      }
      ++out.hits[static_cast<std::size_t>(h.counter)];
    }
  }
  if (out.events == 0 || out.clusterRows == 0) {
    return Error{fmt::format("{}: no cluster in the events: no counter can be told dead or alive",
                             paths.size() == 1 ? paths.front() : paths.front() + " …")};
  }
  return out;
}

DeadCounters findDeadCounters(const CounterOccupancy& occupancy, const geometry::Calorimeter& calo,
                              const DeadCounterOptions& options) {
  const sim::CounterNeighbours neighbours(calo);
  DeadCounters out;
  out.expected.assign(static_cast<std::size_t>(calo.size()), 0.0);
  std::vector<std::int64_t> fired;
  for (int c = 0; c < calo.size(); ++c) {
    const auto n = occupancy.hits[static_cast<std::size_t>(c)];
    if (n > 0) fired.push_back(n);
    double sum = 0.0;
    int count = 0;
    for (int k : neighbours.of(c)) {
      if (calo.counter(k).layer != calo.counter(c).layer) continue;
      sum += static_cast<double>(occupancy.hits[static_cast<std::size_t>(k)]);
      ++count;
    }
    const double mu = count > 0 ? sum / count : 0.0;
    out.expected[static_cast<std::size_t>(c)] = mu;
    if (n == 0) (mu >= options.minExpected ? out.dead : out.undecided).push_back(c);
  }
  if (!fired.empty()) {
    std::nth_element(fired.begin(), fired.begin() + static_cast<std::ptrdiff_t>(fired.size() / 2), fired.end());
    out.medianOccupancy = static_cast<double>(fired[fired.size() / 2]);
  }
  return out;
}

std::string deadCountersText(const DeadCounters& found, const CounterOccupancy& occupancy,
                             const DeadCounterOptions& options, const std::string& sources) {
  std::string text = fmt::format(
      "# emcalign dead counters (emcalign {})\n"
      "# from: {} ({} events, {} cluster rows; median hits of a counter that fired: {:g})\n"
      "# dead: no hit while the neighbours in its layer had {:g} or more on average\n",
      kVersion, sources, occupancy.events, occupancy.clusterRows, found.medianOccupancy, options.minExpected);
  if (!found.undecided.empty()) {
    text += fmt::format("# undecided (no hit, too few around to tell; not listed as dead): {}\n",
                        fmt::join(found.undecided, ","));
  }
  text += fmt::format("# use: emcalign simulate --dead-counters @FILE\n{}\n", fmt::join(found.dead, ","));
  return text;
}

Result<std::vector<int>> parseCounterList(const std::string& text, const std::string& source) {
  std::vector<int> out;
  std::size_t lineNumber = 0, from = 0;
  while (from < text.size()) {
    std::size_t end = text.find('\n', from);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + from, end - from);
    from = end + 1;
    ++lineNumber;
    if (io::isBlankOrComment(line)) continue;
    line = line.substr(0, line.find('#'));  // a comment after the counters
    std::size_t at = 0;
    while (at < line.size()) {
      const std::size_t stop = line.find_first_of(", \t\r", at);
      const std::string_view item =
          line.substr(at, stop == std::string_view::npos ? std::string_view::npos : stop - at);
      at = stop == std::string_view::npos ? line.size() : stop + 1;
      if (item.empty()) continue;
      int v = -1;
      const auto [p, ec] = std::from_chars(item.data(), item.data() + item.size(), v);
      if (ec != std::errc() || p != item.data() + item.size()) {
        return Error{fmt::format("{}{}: {} is not a counter index", source,
                                 lineNumber > 1 || text.find('\n') != std::string::npos
                                     ? fmt::format(": line {}", lineNumber)
                                     : std::string(),
                                 io::quotedText(item))};
      }
      out.push_back(v);
    }
  }
  std::sort(out.begin(), out.end());  // a counter listed twice is one dead counter
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::string deadCounterSources(const std::vector<std::string>& files) {
  if (files.empty()) return {};
  return files.size() == 1 ? files.front() : fmt::format("{} and {} more", files.front(), files.size() - 1);
}

std::string deadCountersSummary(const DeadCounters& found, const CounterOccupancy& occupancy,
                                const std::string& output) {
  return fmt::format(
      "dead-counters: {} read, {}: {}{} -> {}\n", counted(occupancy.events, "event"),
      counted(found.dead.size(), "dead counter"),
      found.dead.empty() ? "none" : fmt::format("{}", fmt::join(found.dead, ", ")),
      found.undecided.empty()
          ? std::string()
          : fmt::format("; {} never fired where too few hits are expected to tell (listed in the file, not as dead)",
                        counted(found.undecided.size(), "counter")),
      output);
}

}  // namespace emcalign::apply
