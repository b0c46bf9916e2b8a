// A period scenario (validation/period.hpp): read and checked, its runs planned (events, seeds,
// truths), and its truth file written and read back.

#include "emcalign/validation/period.hpp"
#include "emcalign/calib/fit_notes.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/random.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/strict_json.hpp"

namespace emcalign::validation {

namespace fs = std::filesystem;
using geometry::AlignmentParameters;
using geometry::PhysicalParameters;
using io::Json;
using io::strict::BadInput;
using io::strict::StrictObject;

namespace {

// An integer of the scenario within [lo, hi] (throws BadInput naming the key).
std::int64_t integer(const Json& v, std::int64_t lo, std::int64_t hi, std::string_view source, const std::string& key) {
  auto n = io::integerIn(v, lo, hi, source, key);
  if (!n) throw BadInput{n.error().message};
  return *n;
}

std::pair<std::int64_t, std::int64_t> eventsRange(const Json& v, std::string_view source, const std::string& key) {
  if (v.is_array()) {
    if (v.size() != 2) throw BadInput{fmt::format("{}: key '{}': expected a number or [min, max]", source, key)};
    const auto lo = integer(v[0], 1, kMaxEventsPerRun, source, key + "[0]");
    const auto hi = integer(v[1], 1, kMaxEventsPerRun, source, key + "[1]");
    if (lo > hi) throw BadInput{fmt::format("{}: key '{}': min {} is above max {}", source, key, lo, hi)};
    return {lo, hi};
  }
  const auto n = integer(v, 1, kMaxEventsPerRun, source, key);
  return {n, n};
}

// Segment values over the previous segment's (parameters or physical, deg and cm).
AlignmentParameters segmentParameters(const Json& seg, const std::string& path, const AlignmentParameters& previous,
                                      double r1, std::string_view source) {
  StrictObject s(seg, path, source);
  s.allowOnly({"from_run", "parameters", "physical", "comment"});
  if (s.has("parameters") == s.has("physical")) {
    s.fail(path, "give \"parameters\" (the 12 fit names) or \"physical\" (the 12 physical names), one of them");
  }
  if (s.has("parameters")) {
    AlignmentParameters eta = previous;
    StrictObject p(s.at("parameters"), s.pathOf("parameters"), source);
    for (const auto& [key, value] : s.at("parameters").items()) {
      const auto q = paramFromName(key);
      if (!q) p.fail(p.pathOf(key), fmt::format("unknown parameter (the 12 are: {})", fmt::join(kParamNames, ", ")));
      eta[*q] = p.number(key) * AlignmentParameters::fileUnit(*q);
    }
    return eta;
  }
  auto phys = geometry::toPhysical(previous, r1);
  if (!phys) s.fail(path, fmt::format("the previous segment has no physical form: {}", phys.error().message));
  StrictObject p(s.at("physical"), s.pathOf("physical"), source);
  for (const auto& [key, value] : s.at("physical").items()) {
    std::optional<Physical> q;
    for (std::size_t k = 0; k < kNumParams; ++k) {
      if (kPhysicalNames[k] == key) q = static_cast<Physical>(k);
    }
    if (!q) p.fail(p.pathOf(key), fmt::format("unknown parameter (the 12 are: {})", fmt::join(kPhysicalNames, ", ")));
    (*phys)[*q] = p.number(key) * PhysicalParameters::fileUnit(*q);
  }
  return geometry::fromPhysical(*phys, r1);
}

// The truth of `run`: its segment's parameters plus the drifts up to it.
AlignmentParameters truthOf(const PeriodScenario& s, std::int64_t run) {
  auto seg = std::upper_bound(s.segments.begin(), s.segments.end(), run,
                              [](std::int64_t r, const PeriodScenario::Segment& g) { return r < g.fromRun; });
  AlignmentParameters eta = std::prev(seg)->parameters;
  for (const auto& d : s.drifts) {
    if (run > d.fromRun) eta[d.parameter] += d.perRun * static_cast<double>(std::min(run, d.toRun) - d.fromRun);
  }
  return eta;
}

const PeriodScenario::EnergyPoint& energyOf(const PeriodScenario& s, std::int64_t run) {
  auto it = std::upper_bound(s.beamEnergy.begin(), s.beamEnergy.end(), run,
                             [](std::int64_t r, const PeriodScenario::EnergyPoint& e) { return r < e.fromRun; });
  return *std::prev(it);
}

std::uint64_t runSeed(std::uint64_t seed, std::int64_t run) {
  Rng rng(seed ^ 0x9E71D5EEDULL, static_cast<std::uint64_t>(run) + (1ULL << 41));
  return rng.next();
}

// The runs where the entries of a list start (their from_run): the first at first_run, in
// increasing order.
std::vector<std::int64_t> fromRuns(const StrictObject& top, const Json& list, const std::string& key,
                                   const PeriodScenario& s, std::string_view source) {
  if (!list.is_array() || list.empty()) top.fail(key, "expected a non-empty list");
  std::vector<std::int64_t> runs;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string path = fmt::format("{}[{}]", key, i);
    StrictObject e(list[i], path, source);
    const auto r = integer(e.at("from_run"), s.firstRun, s.lastRun(), source, path + ".from_run");
    if (i == 0 && r != s.firstRun) e.fail(e.pathOf("from_run"), "the first one must start at first_run");
    if (i > 0 && r <= runs.back()) e.fail(e.pathOf("from_run"), "expected runs in increasing order");
    runs.push_back(r);
  }
  return runs;
}

// The beam energy from each of its first runs on (and the events per run there, if other).
void parseBeamEnergies(const StrictObject& top, PeriodScenario& s, std::string_view source) {
  const Json& energies = top.at("beam_energy_mev");
  const auto energyRuns = fromRuns(top, energies, "beam_energy_mev", s, source);
  for (std::size_t i = 0; i < energies.size(); ++i) {
    const std::string path = fmt::format("beam_energy_mev[{}]", i);
    StrictObject e(energies[i], path, source);
    e.allowOnly({"from_run", "value", "events_per_run", "comment"});
    PeriodScenario::EnergyPoint p;
    p.fromRun = energyRuns[i];
    p.value = e.number("value");
    if (!(p.value * units::MeV >= kMinBeamEnergy && p.value * units::MeV <= kMaxBeamEnergy)) {
      e.fail(e.pathOf("value"),
             fmt::format("a beam energy from {} to {} MeV", kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV));
    }
    if (e.has("events_per_run")) p.eventsPerRun = eventsRange(e.at("events_per_run"), source, path + ".events_per_run");
    s.beamEnergy.push_back(p);
  }
}

// The segments: each one's parameters over the previous one's, from its first run on.
void parseSegments(const StrictObject& top, PeriodScenario& s, double r1, std::string_view source) {
  const Json& segments = top.at("segments");
  const auto segmentRuns = fromRuns(top, segments, "segments", s, source);
  AlignmentParameters previous;
  for (std::size_t i = 0; i < segments.size(); ++i) {
    previous = segmentParameters(segments[i], fmt::format("segments[{}]", i), previous, r1, source);
    s.segments.push_back({segmentRuns[i], previous});
  }
}

// The drifts: a fit parameter changing by per_run each run from from_run to to_run.
void parseDrifts(const StrictObject& top, PeriodScenario& s, std::string_view source) {
  if (!top.has("drift")) return;
  const Json& drifts = top.at("drift");
  if (!drifts.is_array()) top.fail("drift", "expected a list");
  for (std::size_t i = 0; i < drifts.size(); ++i) {
    const std::string path = fmt::format("drift[{}]", i);
    StrictObject d(drifts[i], path, source);
    d.allowOnly({"parameter", "from_run", "to_run", "per_run", "comment"});
    PeriodScenario::Drift drift;
    const auto q = paramFromName(d.string("parameter"));
    if (!q) {
      d.fail(d.pathOf("parameter"),
             fmt::format("unknown parameter (the 12 fit names: {})", fmt::join(kParamNames, ", ")));
    }
    drift.parameter = *q;
    drift.fromRun = integer(d.at("from_run"), s.firstRun, s.lastRun(), source, path + ".from_run");
    drift.toRun = integer(d.at("to_run"), s.firstRun, s.lastRun(), source, path + ".to_run");
    if (drift.toRun <= drift.fromRun) d.fail(d.pathOf("to_run"), "expected after from_run");
    drift.perRun = d.number("per_run") * AlignmentParameters::fileUnit(*q);
    s.drifts.push_back(drift);
  }
}

// The runs missing from the period: single runs or [first, last] ranges.
void parseMissingRuns(const StrictObject& top, PeriodScenario& s, std::string_view source) {
  if (!top.has("missing_runs")) return;
  const Json& missing = top.at("missing_runs");
  if (!missing.is_array()) top.fail("missing_runs", "expected a list of runs or [first, last] ranges");
  for (std::size_t i = 0; i < missing.size(); ++i) {
    const std::string path = fmt::format("missing_runs[{}]", i);
    if (missing[i].is_array()) {
      if (missing[i].size() != 2) top.fail(path, "expected a run or [first, last]");
      const auto a = integer(missing[i][0], s.firstRun, s.lastRun(), source, path + "[0]");
      const auto b = integer(missing[i][1], s.firstRun, s.lastRun(), source, path + "[1]");
      if (a > b) top.fail(path, "the first run is after the last");
      s.missingRuns.emplace_back(a, b);
    } else {
      const auto a = integer(missing[i], s.firstRun, s.lastRun(), source, path);
      s.missingRuns.emplace_back(a, a);
    }
  }
  std::sort(s.missingRuns.begin(), s.missingRuns.end());
}

}  // namespace

Result<PeriodScenario> parsePeriodScenario(const Json& j, double r1, std::string_view source) {
  try {
    PeriodScenario s;
    s.source = j;
    if (Status kind = io::expectFormat(j, kPeriodFormat, "a period scenario", source); !kind) {
      throw io::strict::BadInput{kind.error().message};
    }
    StrictObject top(j, "", source);
    top.allowOnly({"format", "name", "description", "first_run", "runs", "events_per_run", "seed", "theta_range_deg",
                   "beam_energy_mev", "segments", "drift", "missing_runs", "comment"});
    if (top.string("format") != kPeriodFormat) top.fail("format", fmt::format("expected \"{}\"", kPeriodFormat));
    if (top.has("name")) s.name = top.string("name");
    if (top.has("description")) s.description = top.string("description");
    s.firstRun = integer(top.at("first_run"), 0, std::numeric_limits<std::int32_t>::max(), source, "first_run");
    s.runs = integer(top.at("runs"), 1, kMaxPeriodRuns, source, "runs");
    if (s.lastRun() > std::numeric_limits<std::int32_t>::max()) {
      top.fail("runs", "the last run is beyond 2^31 - 1 (run numbers are 32-bit in event files)");
    }
    s.eventsPerRun = eventsRange(top.at("events_per_run"), source, "events_per_run");
    if (top.has("seed")) {
      const Json& seed = top.at("seed");
      if (!seed.is_number_unsigned()) top.fail("seed", "expected an integer from 0 to 2^64 - 1");
      s.seed = seed.get<std::uint64_t>();
    }
    const Json& theta = top.at("theta_range_deg");
    if (!theta.is_array() || theta.size() != 2) top.fail("theta_range_deg", "expected [min, max] in degrees");
    const double t0 = top.numberValue(theta[0], "theta_range_deg[0]");
    const double t1 = top.numberValue(theta[1], "theta_range_deg[1]");
    if (!(t0 >= 0.0 && t1 <= 180.0 && t0 < t1)) top.fail("theta_range_deg", "expected 0 <= min < max <= 180");
    s.thetaMin = t0 * units::deg;
    s.thetaMax = t1 * units::deg;
    parseBeamEnergies(top, s, source);
    parseSegments(top, s, r1, source);
    parseDrifts(top, s, source);
    parseMissingRuns(top, s, source);
    // Every run's truth must be plausible (a unit mistake in a drift shows at its end).
    for (std::int64_t run = s.firstRun; run <= s.lastRun(); ++run) {
      if (Status p = geometry::checkPlausible(truthOf(s, run)); !p) {
        return Error{fmt::format("{}: the truth of run {}: {}", source, run, p.error().message)};
      }
    }
    if (planPeriod(s).empty()) return Error{fmt::format("{}: key 'missing_runs': no run is left", source)};
    return s;
  } catch (const BadInput& e) {
    return Error{e.message};
  }
}

Result<PeriodScenario> readPeriodScenario(const std::string& path, double r1) {
  auto text = io::readTextFile(path);
  if (!text) return text.error();
  auto j = io::parseJson(*text, path);
  if (!j) return j.error();
  return parsePeriodScenario(*j, r1, path);
}

std::vector<std::string> periodTruthWarnings(const PeriodScenario& s, double r1) {
  std::vector<std::string> out;
  std::string last;
  std::int64_t first = 0, end = 0;
  const auto flush = [&] {
    if (!last.empty())
      out.push_back(fmt::format(
          "{}: {}", first == end ? fmt::format("run {}", first) : fmt::format("runs {}-{}", first, end), last));
  };
  for (const auto& run : planPeriod(s)) {
    std::string w = calib::truthRangeWarning(run.truth, r1).value_or("");
    if (w == last && !w.empty()) {
      end = run.run;
      continue;
    }
    flush();
    last = std::move(w);
    first = end = run.run;
  }
  flush();
  if (out.size() > 3) {  // a drift beyond the ranges: each run's truth differs
    const std::size_t more = out.size() - 2;
    out.resize(2);
    out.push_back(fmt::format("and {} more stretches of runs whose truth lies outside the validated ranges", more));
  }
  return out;
}

std::vector<PeriodRun> planPeriod(const PeriodScenario& s, sim::Process process) {
  std::vector<PeriodRun> out;
  auto missing = s.missingRuns.begin();
  for (std::int64_t run = s.firstRun; run <= s.lastRun(); ++run) {
    while (missing != s.missingRuns.end() && missing->second < run) ++missing;
    if (missing != s.missingRuns.end() && missing->first <= run) continue;
    const auto& energy = energyOf(s, run);
    const auto [lo, hi] = energy.eventsPerRun.value_or(s.eventsPerRun);
    Rng rng(s.seed, static_cast<std::uint64_t>(run));
    PeriodRun r;
    r.run = run;
    r.events = lo + static_cast<std::int64_t>(rng.uniform() * static_cast<double>(hi - lo + 1));
    r.events = std::min(r.events, hi);
    r.beamEnergy = energy.value;
    // e+e- → e+e- keeps the seeds it always had; another process draws its own.
    r.seed = process == sim::Process::Bhabha
                 ? runSeed(s.seed, run)
                 : runSeed(s.seed ^ (0xA5A5D1CEULL * (static_cast<std::uint64_t>(process) + 1)), run);
    r.truth = truthOf(s, run);
    r.file = fmt::format("run_{:06d}.h5", run);
    out.push_back(std::move(r));
  }
  return out;
}

Json periodTruthJson(const PeriodScenario& s, const std::vector<PeriodRun>& runs, double r1) {
  Json list = Json::array();
  for (const PeriodRun& r : runs) {
    Json derived = Json::object();
    if (auto phys = geometry::toPhysical(r.truth, r1); phys) {
      for (Physical p : {Physical::Beta, Physical::Psi, Physical::Mu, Physical::Tau, Physical::DxRel}) {
        derived[std::string(name(p))] = (*phys)[p] / PhysicalParameters::fileUnit(p);
      }
    }
    list.push_back({{"run", r.run},
                    {"file", r.file},
                    {"events", r.events},
                    {"beam_energy_mev", r.beamEnergy},
                    {"seed", r.seed},
                    {"parameters", io::alignmentToJson(r.truth)["parameters"]},
                    {"derived", derived}});
  }
  return {{"format", kPeriodTruthFormat},
          {"software", fmt::format("emcalign {}", kVersion)},
          {"scenario", s.source},
          {"runs", list}};
}

double PeriodTruth::mean(Quantity parameter, std::int64_t first, std::int64_t last) const {
  auto it = byParameter.find(parameter);
  if (it == byParameter.end()) return std::numeric_limits<double>::quiet_NaN();
  double sum = 0.0;
  std::int64_t n = 0;
  for (const auto& [run, value] : it->second) {
    if (run >= first && run <= last) {
      sum += value;
      ++n;
    }
  }
  return n > 0 ? sum / static_cast<double>(n) : std::numeric_limits<double>::quiet_NaN();
}

Result<PeriodTruth> readPeriodTruth(const std::string& path) {
  auto text = io::readTextFile(path);
  if (!text) return text.error();
  auto j = io::parseJson(*text, path);
  if (!j) return j.error();
  if (!j->is_object() || j->value("format", "") != kPeriodTruthFormat || !j->contains("runs") ||
      !(*j)["runs"].is_array()) {
    return Error{
        fmt::format("{}: not a period truth file ({}, written by simulate --period)", path, kPeriodTruthFormat)};
  }
  PeriodTruth out;
  std::size_t k = 0;
  for (const Json& r : (*j)["runs"]) {
    if (!r.is_object() || !r.contains("run") || !r["run"].is_number_integer()) {
      return Error{fmt::format("{}: runs[{}]: no integer \"run\"", path, k)};
    }
    const auto run = r["run"].get<std::int64_t>();
    for (const char* group : {"parameters", "derived"}) {
      if (!r.contains(group) || !r[group].is_object()) {
        return Error{fmt::format("{}: run {}: no \"{}\" object", path, run, group)};
      }
      for (const auto& [name, v] : r[group].items()) {
        if (!v.is_number()) return Error{fmt::format("{}: run {}: {}.{} is not a number", path, run, group, name)};
        const std::optional<Quantity> q = quantityFromName(name);
        if (!q)
          return Error{fmt::format(
              "{}: run {}: {}.{} is not a parameter (the 12 of docs/conventions.md, or beta, psi, mu, tau, dx_rel)",
              path, run, group, name)};
        out.byParameter[*q].emplace_back(run, v.get<double>());
      }
    }
    ++k;
  }
  // Tilts and gaps as the trend's series take them (trend_series.hpp): each direction within
  // 90° of the one before, its magnitude's sign flipped on an odd half turn.
  for (const auto& [magnitude, direction] : {std::pair{"beta", "psi"}, {"mu", "tau"}}) {
    auto m = out.byParameter.find(*quantityFromName(magnitude)), d = out.byParameter.find(*quantityFromName(direction));
    if (m == out.byParameter.end() || d == out.byParameter.end() || m->second.size() != d->second.size()) continue;
    bool negative = false;
    std::optional<double> last;
    for (std::size_t i = 0; i < m->second.size(); ++i) {
      double &size = m->second[i].second, &angle = d->second[i].second;
      if (size != 0.0 && last) {
        const double turns = std::round((angle - *last) / 180.0);
        angle -= 180.0 * turns;
        negative = std::fmod(std::abs(turns), 2.0) == 1.0;
      }
      if (size != 0.0) last = angle;
      if (negative) size = -size;
    }
  }
  return out;
}

}  // namespace emcalign::validation
