#include "emcalign/io/json_files.hpp"

#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <system_error>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/regular_file.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/file_kind.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/io/strict_json.hpp"

namespace emcalign::io {

using geometry::AlignmentParameters;
using geometry::DetectorDescription;
using geometry::PhysicalParameters;
using json = Json;

namespace {

using strict::BadInput;
using strict::guarded;
using strict::StrictObject;

void checkUnits(const StrictObject& top) {
  if (!top.has("units")) return;
  const StrictObject u = top.object("units");
  u.allowOnly({"angle", "length"});
  if (u.has("angle") && u.string("angle") != "deg") top.fail("units.angle", "only \"deg\" is supported");
  if (u.has("length") && u.string("length") != "cm") top.fail("units.length", "only \"cm\" is supported");
}

}  // namespace

namespace {

// Deeper nesting than any emcalign file has (they need 4 levels) is refused before parsing:
// the parser, the digests and the printers recurse, and a hostile file must not overflow
// the stack.
constexpr int kMaxJsonDepth = 64;
constexpr std::size_t kMaxJsonBytes = kMaxInputFileBytes;

std::optional<std::size_t> tooDeep(std::string_view text) {
  int depth = 0;
  bool inString = false, escaped = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (inString) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        inString = false;
      }
      continue;
    }
    if (c == '"') {
      inString = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth) return i;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return std::nullopt;
}

}  // namespace

std::string describeFile(const json& j) {
  const std::string f = formatOf(j);
  if (f.empty()) return {};
  if (f == kAlignmentFormat) return j.contains("chi2") || j.contains("errors") ? "a fit result" : "a parameter file";
  static const std::pair<std::string_view, std::string_view> kinds[] = {
      {"emcalign-campaign-plan/1", "a campaign plan (campaign --plan)"},
      {"emcalign-corrections/1", "a corrections file (derive-corrections)"},
      {"emcalign-detector/1", "a detector description (geometry --description)"},
      {"emcalign-payload/1", "a conditions payload"},
      {"emcalign-period-state/1", "a period simulation's state"},
      {"emcalign-period-truth/1", "a period's truth (simulate --period)"},
      {"emcalign-period/1", "a period scenario (simulate --period)"},
      {"emcalign-placements/1", "a placements file (export)"},
      {"emcalign-trend/1", "a trend (trend.json)"},
      {"emcalign-validation-ranges/1", "a ranges file (validate --ranges)"},
      {"emcalign-validation-sample/1", "a validation sample's result"}};
  for (const auto& [format, what] : kinds) {
    if (f == format) return std::string(what);
  }
  return f.starts_with("emcalign-") ? fmt::format("an emcalign file of format {}", f) : std::string();
}

Status expectFormat(const json& j, std::string_view format, std::string_view expected, std::string_view source) {
  if (formatOf(j) == format) return {};
  const std::string kind = describeFile(j);
  if (kind.empty()) return {};  // the reader's own checks name what is wrong
  return Error{
      fmt::format("{}: this is {}, not {} (its format: {})", source, kind, expected, j["format"].get<std::string>())};
}

Result<json> parseJson(std::string_view text, std::string_view source) {
  if (const std::string kind = describeNonJson(text); !kind.empty()) {
    return Error{fmt::format("{}: this is {}, not a JSON file", source, kind)};
  }
  if (text.size() > kMaxJsonBytes) {
    return Error{fmt::format("{}: {} bytes is too large for an emcalign JSON file (at most {} MiB)", source,
                             text.size(), kMaxJsonBytes >> 20)};
  }
  if (auto at = tooDeep(text)) {
    return Error{
        fmt::format("{}: not an emcalign file: nested deeper than {} levels (at byte {})", source, kMaxJsonDepth, *at)};
  }
  // Duplicate keys are silently merged by JSON parsers; a calibration file with two
  // "alpha" entries is a mistake, so a callback tracks the keys of every open object.
  std::vector<std::set<std::string>> open;
  std::string duplicate;
  auto callback = [&](int /*depth*/, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
        open.emplace_back();
        break;
      case json::parse_event_t::object_end:
        if (!open.empty()) open.pop_back();
        break;
      case json::parse_event_t::key: {
        const auto key = parsed.get<std::string>();
        if (!open.empty() && !open.back().insert(key).second && duplicate.empty()) duplicate = key;
        break;
      }
      default:
        break;
    }
    return true;
  };
  try {
    json j = json::parse(text.begin(), text.end(), callback);
    if (!duplicate.empty()) return Error{fmt::format("{}: key '{}' appears twice", source, duplicate)};
    return j;
  } catch (const json::parse_error& e) {
    return Error{fmt::format("{}: not valid JSON (at byte {}): {}", source, e.byte, e.what())};
  } catch (const json::exception& e) {  // e.g. a number too large for a double
    return Error{fmt::format("{}: a value is out of range: {}", source, e.what())};
  }
}

Result<std::int64_t> integerIn(const json& v, std::int64_t lo, std::int64_t hi, std::string_view source,
                               std::string_view key) {
  if (!v.is_number_integer()) {
    return Error{fmt::format("{}: key '{}': expected an integer, got {}", source, key,
                             v.is_number() ? fmt::format("{}", v.get<double>()) : std::string(v.type_name()))};
  }
  std::int64_t x = 0;
  bool inRange = false;
  if (v.is_number_unsigned()) {
    const auto u = v.get<std::uint64_t>();
    inRange = hi >= 0 && u <= static_cast<std::uint64_t>(hi) && static_cast<std::int64_t>(u) >= lo;
    x = inRange ? static_cast<std::int64_t>(u) : 0;
  } else {
    x = v.get<std::int64_t>();
    inRange = x >= lo && x <= hi;
  }
  if (!inRange && lo == hi) return Error{fmt::format("{}: key '{}': {} must be {}", source, key, v.dump(), lo)};
  if (!inRange) return Error{fmt::format("{}: key '{}': {} is outside [{}, {}]", source, key, v.dump(), lo, hi)};
  return x;
}

Result<std::string> readTextFile(const std::string& path, std::size_t maxBytes) {
  auto file = RegularFile::open(path);
  if (!file) return file.error();
  protectInput({"", path});
  return file->readAll(maxBytes);
}

Result<std::string> readOwnOutput(const std::string& path, std::size_t maxBytes) {
  auto file = RegularFile::open(path);
  if (!file) return file.error();
  return file->readAll(maxBytes);
}

// ---------------------------------------------------------------- detector description

Result<DetectorDescription> parseDetectorDescription(const json& j, std::string_view source) {
  return guarded([&]() -> DetectorDescription {
    using units::deg;
    if (Status kind = expectFormat(j, kDetectorFormat, "a detector description", source); !kind) {
      throw strict::BadInput{kind.error().message};
    }
    StrictObject top(j, "", source);
    top.allowOnly({"format", "name", "layers", "support_spheres", "theta_min_deg", "theta_max_deg", "counters_per_ring",
                   "shower"});
    if (top.string("format") != kDetectorFormat) {
      top.fail("format", fmt::format("expected \"{}\"", kDetectorFormat));
    }
    DetectorDescription d = DetectorDescription::sndDefault();
    if (top.has("name")) d.name = top.string("name");

    auto readShells = [&](std::string_view key, auto& shells) {
      if (!top.has(key)) return;
      const json& arr = top.at(key);
      if (!arr.is_array() || arr.size() != shells.size()) {
        top.fail(key, fmt::format("expected a list of {} objects", shells.size()));
      }
      for (std::size_t i = 0; i < shells.size(); ++i) {
        StrictObject s(arr[i], fmt::format("{}[{}]", key, i), source);
        s.allowOnly({"r_inner_cm", "r_outer_cm"});
        shells[i].rInner = s.number("r_inner_cm") * units::cm;
        shells[i].rOuter = s.number("r_outer_cm") * units::cm;
      }
    };
    readShells("layers", d.layers);
    readShells("support_spheres", d.supports);
    d.thetaMin = top.number("theta_min_deg", d.thetaMin / deg) * deg;
    d.thetaMax = top.number("theta_max_deg", d.thetaMax / deg) * deg;
    if (top.has("counters_per_ring")) {
      const json& arr = top.at("counters_per_ring");
      if (!arr.is_array()) top.fail("counters_per_ring", "expected a list of integers");
      if (arr.size() > static_cast<std::size_t>(DetectorDescription::kMaxRings)) {
        top.fail("counters_per_ring", fmt::format("{} rings: at most {}", arr.size(), DetectorDescription::kMaxRings));
      }
      d.countersPerRing.clear();
      for (std::size_t i = 0; i < arr.size(); ++i) {
        auto n = integerIn(arr[i], 1, DetectorDescription::kMaxCountersPerRing, source,
                           fmt::format("counters_per_ring[{}]", i));
        if (!n) throw BadInput{n.error().message};
        d.countersPerRing.push_back(static_cast<int>(*n));
      }
    }
    if (top.has("shower")) {
      StrictObject s(top.at("shower"), "shower", source);
      s.allowOnly({"x0_cm", "critical_energy_mev", "x_pre"});
      d.material.radiationLength = s.number("x0_cm", d.material.radiationLength);
      d.material.criticalEnergy = s.number("critical_energy_mev", d.material.criticalEnergy);
      d.material.preshowerMaterial = s.number("x_pre", d.material.preshowerMaterial);
    }
    if (Status st = d.validate(); !st) throw BadInput{fmt::format("{}: {}", source, st.error().message)};
    return d;
  });
}

Result<DetectorDescription> readDetectorDescription(const std::string& path) {
  auto text = readTextFile(path);
  if (!text) return text.error();
  auto j = parseJson(*text, path);
  if (!j) return j.error();
  return parseDetectorDescription(*j, path);
}

json toJson(const DetectorDescription& d) {
  auto shells = [](const auto& list) {
    json arr = json::array();
    for (const auto& s : list)
      arr.push_back({{"r_inner_cm", s.rInner / units::cm}, {"r_outer_cm", s.rOuter / units::cm}});
    return arr;
  };
  return json{{"format", kDetectorFormat},
              {"name", d.name},
              {"layers", shells(d.layers)},
              {"support_spheres", shells(d.supports)},
              {"theta_min_deg", d.thetaMin / units::deg},
              {"theta_max_deg", d.thetaMax / units::deg},
              {"counters_per_ring", d.countersPerRing},
              {"shower",
               {{"x0_cm", d.material.radiationLength / units::cm},
                {"critical_energy_mev", d.material.criticalEnergy / units::MeV},
                {"x_pre", d.material.preshowerMaterial}}}};
}

// ---------------------------------------------------------------- alignment parameters

void strict::checkAlignmentHeader(const StrictObject& top) {
  // The parameter keys, plus what a fit result adds (docs/contract.md §3), read elsewhere.
  top.allowOnly({"format",
                 "units",
                 "parameters",
                 "physical",
                 "errors",
                 "statistical_errors",
                 "systematic_errors",
                 "covariance",
                 "derived",
                 "chi2",
                 "ndf",
                 "p_value",
                 "stages",
                 "status",
                 "warnings",
                 "input",
                 "software",
                 "correlation",
                 "sigma_sys",
                 "notes"});
  if (top.has("format") && top.string("format") != kAlignmentFormat) {
    top.fail("format", fmt::format("expected \"{}\"", kAlignmentFormat));
  }
  checkUnits(top);
  if (top.has("parameters")) {
    const StrictObject p = top.object("parameters");
    for (const auto& [key, value] : top.at("parameters").items()) {
      if (!paramFromName(key)) {
        p.fail(p.pathOf(key), fmt::format("unknown parameter (the 12 are: {})", fmt::join(kParamNames, ", ")));
      }
    }
  }
}

Result<AlignmentFile> parseAlignmentFile(const json& j, double r1, std::string_view source, AlignmentUse use) {
  return guarded([&]() -> AlignmentFile {
    if (Status kind = expectFormat(j, kAlignmentFormat, "a parameter file or a fit result", source); !kind) {
      throw strict::BadInput{kind.error().message};
    }
    StrictObject top(j, "", source);
    strict::checkAlignmentHeader(top);
    if (!top.has("parameters") && !top.has("physical")) {
      top.fail("parameters", "missing (give \"parameters\" or \"physical\")");
    }

    std::optional<AlignmentParameters> fromFit;
    if (top.has("parameters")) {
      StrictObject p(top.at("parameters"), "parameters", source);
      AlignmentParameters eta;
      for (Param q : kAllParams) eta[q] = p.number(name(q)) * AlignmentParameters::fileUnit(q);
      fromFit = eta;
    }
    std::optional<AlignmentParameters> fromPhys;
    if (top.has("physical")) {
      StrictObject p(top.at("physical"), "physical", source);
      for (const auto& [key, value] : top.at("physical").items()) {
        bool known = false;
        for (auto n : kPhysicalNames) known = known || n == key;
        if (!known)
          p.fail(p.pathOf(key), fmt::format("unknown parameter (the 12 are: {})", fmt::join(kPhysicalNames, ", ")));
      }
      PhysicalParameters phys;
      for (std::size_t i = 0; i < kNumParams; ++i) {
        const auto q = static_cast<Physical>(i);
        phys[q] = p.number(name(q)) * PhysicalParameters::fileUnit(q);
      }
      fromPhys = geometry::fromPhysical(phys, r1);
    }
    if (fromFit && fromPhys) {
      for (Param q : kAllParams) {
        const double a = (*fromFit)[q] / AlignmentParameters::fileUnit(q);
        const double b = (*fromPhys)[q] / AlignmentParameters::fileUnit(q);
        if (std::abs(a - b) > 1e-9 * std::max(1.0, std::abs(a))) {
          top.fail("physical", fmt::format("disagrees with \"parameters\" on {} ({} vs {}); give one "
                                           "of the two, or both consistent",
                                           name(q), a, b));
        }
      }
    }
    AlignmentFile file;
    file.parameters = fromFit ? *fromFit : *fromPhys;
    if (Status st = geometry::validate(file.parameters, r1); !st) {
      throw BadInput{fmt::format("{}: {}", source, st.error().message)};
    }
    if (top.has("status")) {
      const FitStatus s = strict::fitStatusAt(top, "status");
      file.status = s;
      if (use == AlignmentUse::Input && !usable(s)) {
        throw BadInput{
            fmt::format("{}: a fit result with status '{}': its parameters are not a calibration (read its "
                        "warnings and refit; to use them anyway, copy its \"parameters\" into a parameter "
                        "file)",
                        source, name(s))};
      }
      if (s == FitStatus::PoorFit) {
        file.warnings.push_back(
            fmt::format("{}: a fit result with status 'poor fit' (p-value below {:g}): the model does "
                        "not describe its profiles well; use it with care",
                        source, kPoorFitPValue));
      }
    }
    if (use == AlignmentUse::Input) {
      if (Status st = geometry::checkPlausible(file.parameters); !st) {
        throw BadInput{fmt::format("{}: {}{}", source, fromFit ? "" : "(from \"physical\") ", st.error().message)};
      }
      for (auto& w : geometry::unitWarnings(file.parameters)) file.warnings.push_back(fmt::format("{}: {}", source, w));
    }
    for (auto& w : geometry::warnings(file.parameters)) file.warnings.push_back(fmt::format("{}: {}", source, w));
    return file;
  });
}

Result<AlignmentParameters> parseAlignment(const json& j, double r1, std::string_view source, AlignmentUse use) {
  auto file = parseAlignmentFile(j, r1, source, use);
  if (!file) return file.error();
  return file->parameters;
}

Result<AlignmentFile> readAlignmentFile(const std::string& path, double r1) {
  auto text = readTextFile(path);
  if (!text) return text.error();
  auto j = parseJson(*text, path);
  if (!j) return j.error();
  return parseAlignmentFile(*j, r1, path, AlignmentUse::Input);
}

Result<AlignmentParameters> readAlignment(const std::string& path, double r1) {
  auto file = readAlignmentFile(path, r1);
  if (!file) return file.error();
  return file->parameters;
}

json alignmentToJson(const AlignmentParameters& eta) {
  json params = json::object();
  for (Param q : kAllParams) params[std::string(name(q))] = eta[q] / AlignmentParameters::fileUnit(q);
  return json{{"format", kAlignmentFormat}, {"units", {{"angle", "deg"}, {"length", "cm"}}}, {"parameters", params}};
}

Result<json> alignmentToJsonWithPhysical(const AlignmentParameters& eta, double r1) {
  auto phys = geometry::toPhysical(eta, r1);
  if (!phys) return phys.error();
  json j = alignmentToJson(eta);
  json p = json::object();
  for (std::size_t i = 0; i < kNumParams; ++i) {
    const auto q = static_cast<Physical>(i);
    p[std::string(name(q))] = (*phys)[q] / PhysicalParameters::fileUnit(q);
  }
  j["physical"] = p;
  return j;
}

Result<geometry::Calorimeter> loadCalorimeter(const std::string& path) {
  if (path.empty()) return geometry::Calorimeter::create(geometry::DetectorDescription::sndDefault());
  auto description = io::readDetectorDescription(path);
  if (!description) return description.error();
  auto calo = geometry::Calorimeter::create(std::move(*description));
  if (!calo) return Error{fmt::format("{}: {}", path, calo.error().message)};
  return calo;
}

}  // namespace emcalign::io
