#include "emcalign/calib/corrections_grid.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/csv.hpp"
#include "emcalign/io/data_directory.hpp"
#include "emcalign/io/event_file.hpp"

namespace emcalign::calib {

namespace fs = std::filesystem;
using io::Json;

namespace {

// The *.json files of a directory, by name.
Result<std::vector<std::string>> jsonFilesIn(const std::string& dir) {
  return io::dataFilesIn(dir, {".json"}, "a corrections file", "--corrections");
}

Result<std::string> directoryDigest(const std::string& dir, const std::vector<std::string>& files) {
  std::string listing;
  for (const auto& f : files) {
    auto d = sha256OfFile(f);
    if (!d) return d.error();
    listing += fmt::format("{}  {}\n", *d, fs::path(f).filename().string());
  }
  if (files.empty()) return Error{fmt::format("{}: no corrections files (*.json) in this directory", dir)};
  return sha256(listing);
}

// Which pieces a corrections file has: a grid interpolates between files with the same.
struct Pieces {
  bool partingPlane, nominalProfile, response, gapMatrix;
  bool operator==(const Pieces&) const = default;
};

Pieces piecesOf(const ModelCorrections& c) {
  return {c.partingPlane != nullptr, c.nominalProfile != nullptr, c.response != nullptr,
          c.response && !c.response->gapMatrix.isZero(0.0)};
}

std::string describe(const Pieces& p) {
  return fmt::format("parting plane {}, nominal profile {}, response {}{}", p.partingPlane ? "yes" : "no",
                     p.nominalProfile ? "yes" : "no", p.response ? "yes" : "no", p.gapMatrix ? " with gap matrix" : "");
}

// The derivation settings two points of a grid must share, when both files record them (the
// number of events and the seed may differ: they change the noise, not what is measured).
Status sameDerivation(const CorrectionsPoint& a, const CorrectionsPoint& b) {
  const Pieces pa = piecesOf(a.corrections), pb = piecesOf(b.corrections);
  if (pa != pb) {
    return Error{
        fmt::format("{} ({}) and {} ({}) do not have the same corrections: a grid interpolates between "
                    "files derived alike",
                    a.file, describe(pa), b.file, describe(pb))};
  }
  const Json& sa = a.corrections.derivedFrom.is_object() ? a.corrections.derivedFrom.value("settings", Json()) : Json();
  const Json& sb = b.corrections.derivedFrom.is_object() ? b.corrections.derivedFrom.value("settings", Json()) : Json();
  if (!sa.is_object() || !sb.is_object()) return {};
  for (const char* key : {"theta_range_deg", "detector", "ideal", "off", "shift_cm", "gap_cm"}) {
    if (sa.contains(key) && sb.contains(key) && sa[key] != sb[key]) {
      return Error{
          fmt::format("{} and {} were derived with different {} ({} and {}): a grid interpolates between "
                      "files derived alike",
                      a.file, b.file, key, sa[key].dump(), sb[key].dump())};
    }
  }
  return {};
}

// The warning of a single file used away from its own energy, for events at lo to hi MeV.
std::string awayFromItsEnergy(const std::string& path, double own, double lo, double hi) {
  return fmt::format(
      "{} was derived at {} MeV and is applied to events at {}{} MeV: derive the corrections at this "
      "energy, or give a grid of them (a directory; docs/validation.md)",
      path, own / units::MeV, lo / units::MeV, hi > lo ? fmt::format(" to {}", hi / units::MeV) : "");
}

std::vector<double> mix(const std::vector<double>& a, const std::vector<double>& b, double w) {
  std::vector<double> out(a.size());
  for (std::size_t k = 0; k < a.size(); ++k) out[k] = (1.0 - w) * a[k] + w * b[k];  // NaN stays NaN
  return out;
}

}  // namespace

Result<ModelCorrections> interpolateCorrections(const ModelCorrections& a, const ModelCorrections& b, double w) {
  if (!(w >= 0.0 && w <= 1.0)) return Error{fmt::format("interpolation weight {} outside [0, 1]", w)};
  if (piecesOf(a) != piecesOf(b)) {
    return Error{fmt::format("cannot interpolate between corrections with different pieces ({}; {})",
                             describe(piecesOf(a)), describe(piecesOf(b)))};
  }
  ModelCorrections c;
  c.beamEnergy = (1.0 - w) * a.beamEnergy + w * b.beamEnergy;
  c.depthOffset = (1.0 - w) * a.depthOffset + w * b.depthOffset;
  if (a.partingPlane) {
    if (a.partingPlane->phiBins() != b.partingPlane->phiBins()) {
      return Error{"cannot interpolate between parting-plane responses of different phi bins"};
    }
    auto p = PartingPlaneResponse::create(mix(a.partingPlane->weights(), b.partingPlane->weights(), w));
    if (!p) return p.error();
    c.partingPlane = std::make_shared<const PartingPlaneResponse>(std::move(*p));
  }
  if (a.nominalProfile) {
    const NominalProfile &x = *a.nominalProfile, &y = *b.nominalProfile;
    if (x.phiBins != y.phiBins || x.thetaBins != y.thetaBins) {
      return Error{"cannot interpolate between nominal profiles of different bins"};
    }
    NominalProfile t{x.phiBins,
                     x.thetaBins,
                     mix(x.yPhi, y.yPhi, w),
                     mix(x.sigmaPhi, y.sigmaPhi, w),
                     mix(x.yTheta, y.yTheta, w),
                     mix(x.sigmaTheta, y.sigmaTheta, w)};
    if (Status s = t.validate(); !s) return s.error();
    c.nominalProfile = std::make_shared<const NominalProfile>(std::move(t));
  }
  if (a.response) {
    FitResponse r;
    r.matrix = (1.0 - w) * a.response->matrix + w * b.response->matrix;
    r.gapMatrix = (1.0 - w) * a.response->gapMatrix + w * b.response->gapMatrix;
    r.offset = (1.0 - w) * a.response->offset + w * b.response->offset;
    if (Status s = r.validate(); !s) return s.error();
    c.response = std::make_shared<const FitResponse>(r);
  }
  // Systematic errors only where both points have them (a grid's points are studied apart).
  if (a.systematics && b.systematics) {
    SystematicErrors e;
    for (const auto& [name, value] : a.systematics->errors) {
      if (auto it = b.systematics->errors.find(name); it != b.systematics->errors.end()) {
        e.errors.emplace(name, (1.0 - w) * value + w * it->second);
      }
    }
    e.study = {{"interpolated", "linearly between the two points' systematic errors"}};
    c.systematics = std::make_shared<const SystematicErrors>(std::move(e));
  }
  return c;
}

Result<CorrectionsGrid> CorrectionsGrid::of(std::vector<CorrectionsPoint> points, std::string path) {
  if (points.empty()) return Error{fmt::format("{}: no corrections", path)};
  CorrectionsGrid g;
  g.path_ = std::move(path);
  g.grid_ = points.size() > 1;
  if (g.grid_) {
    for (const auto& p : points) {
      if (std::isnan(p.corrections.beamEnergy)) {
        return Error{
            fmt::format("{}: key 'beam_energy_mev': missing; every file of a grid says its beam energy "
                        "(derive it again, or add the energy it was derived at)",
                        p.file)};
      }
    }
    std::sort(points.begin(), points.end(), [](const CorrectionsPoint& a, const CorrectionsPoint& b) {
      return a.corrections.beamEnergy < b.corrections.beamEnergy;
    });
    for (std::size_t k = 1; k < points.size(); ++k) {
      if (points[k].corrections.beamEnergy == points[k - 1].corrections.beamEnergy) {
        return Error{fmt::format("{} and {}: two corrections for the same beam energy {} MeV", points[k - 1].file,
                                 points[k].file, points[k].corrections.beamEnergy / units::MeV)};
      }
      if (Status s = sameDerivation(points[0], points[k]); !s) return s.error();
    }
  }
  g.points_ = std::move(points);
  return g;
}

Result<CorrectionsGrid> CorrectionsGrid::read(const std::string& path) {
  std::error_code ec;
  if (!fs::is_directory(path, ec)) {
    auto c = readCorrections(path);
    if (!c) return c.error();
    auto digest = sha256OfFile(path);
    if (!digest) return digest.error();
    auto g = of({{path, std::move(*c)}}, path);
    if (g) g->sha256_ = *digest;
    return g;
  }
  auto files = jsonFilesIn(path);
  if (!files) return files.error();
  auto digest = directoryDigest(path, *files);
  if (!digest) return digest.error();
  if (files->size() < 2) {
    return Error{
        fmt::format("{}: a grid needs corrections at two beam energies at least, found {} (give a single "
                    "file as --corrections FILE)",
                    path, files->size())};
  }
  std::vector<CorrectionsPoint> points;
  for (const auto& f : *files) {
    auto c = readCorrections(f);
    if (!c) return c.error();
    points.push_back({f, std::move(*c)});
  }
  auto g = of(std::move(points), path);
  if (g) g->sha256_ = *digest;
  return g;
}

Result<std::pair<std::size_t, double>> CorrectionsGrid::around(double beamEnergy) const {
  const double first = points_.front().corrections.beamEnergy, last = points_.back().corrections.beamEnergy;
  if (!(beamEnergy >= first && beamEnergy <= last)) {
    // The advice writes into a copy: the grid may be the installed one (a shipped data directory
    // is no place for a user's files, and may not be writable).
    return Error{
        fmt::format("beam energy {} MeV is outside the corrections grid {} ({} to {} MeV): the corrections "
                    "are not extrapolated; derive a point there into a grid of your own (cp -r {} my-grid, then "
                    "emcalign derive-corrections --beam-energy {} -o my-grid/{}, and --corrections my-grid)",
                    beamEnergy / units::MeV, path_, first / units::MeV, last / units::MeV, path_,
                    beamEnergy / units::MeV, gridPointName(beamEnergy))};
  }
  std::size_t k = 1;
  while (k + 1 < points_.size() && points_[k].corrections.beamEnergy < beamEnergy) ++k;
  const double ea = points_[k - 1].corrections.beamEnergy, eb = points_[k].corrections.beamEnergy;
  return std::pair{k, (beamEnergy - ea) / (eb - ea)};
}

Result<double> CorrectionsGrid::depthOffsetAt(double beamEnergy) const {
  if (!grid_) return points_.front().corrections.depthOffset;
  auto bracket = around(beamEnergy);
  if (!bracket) return bracket.error();
  const auto [k, w] = *bracket;
  return (1.0 - w) * points_[k - 1].corrections.depthOffset + w * points_[k].corrections.depthOffset;
}

Result<CorrectionsAt> CorrectionsGrid::at(double beamEnergy) const {
  CorrectionsAt out;
  out.beamEnergy = beamEnergy;
  out.path = path_;
  out.sha256 = sha256_;
  if (!grid_) {
    const ModelCorrections& c = points_.front().corrections;
    out.corrections = c;
    if (!std::isnan(c.beamEnergy) && std::abs(beamEnergy - c.beamEnergy) > kCorrectionsEnergyTolerance * c.beamEnergy) {
      out.warning = awayFromItsEnergy(path_, c.beamEnergy, beamEnergy, beamEnergy);
    }
    return out;
  }
  auto bracket = around(beamEnergy);
  if (!bracket) return bracket.error();
  const auto [k, w] = *bracket;
  const CorrectionsPoint &a = points_[k - 1], &b = points_[k];
  Json used = Json::array();
  if (w == 0.0 || w == 1.0) {
    const CorrectionsPoint& p = w == 0.0 ? a : b;
    out.corrections = p.corrections;
    used.push_back({{"file", p.file}, {"beam_energy_mev", p.corrections.beamEnergy / units::MeV}, {"weight", 1.0}});
  } else {
    auto c = interpolateCorrections(a.corrections, b.corrections, w);
    if (!c) return Error{fmt::format("{}: at {} MeV: {}", path_, beamEnergy / units::MeV, c.error().message)};
    out.corrections = std::move(*c);
    out.corrections.beamEnergy = beamEnergy;
    used.push_back({{"file", a.file}, {"beam_energy_mev", a.corrections.beamEnergy / units::MeV}, {"weight", 1.0 - w}});
    used.push_back({{"file", b.file}, {"beam_energy_mev", b.corrections.beamEnergy / units::MeV}, {"weight", w}});
  }
  out.interpolation = {{"directory", path_}, {"beam_energy_mev", beamEnergy / units::MeV}, {"points", used}};
  out.corrections.derivedFrom = {{"interpolated", out.interpolation}};
  return out;
}

namespace {
constexpr std::string_view kFilledWith = "# filled with the corrections sha256 ";
// "<hex>" or "<hex> at <E> MeV": which corrections, for a grid at which energy.
std::string stampOf(const CorrectionsAt& c) {
  return c.interpolation.is_null() ? c.sha256 : fmt::format("{} at {} MeV", c.sha256, c.beamEnergy / units::MeV);
}

// The same digest and, for a grid, the same energy (as numbers: a typed 1019.46 is the
// 1019.4600219726562 of a float32 in an event file).
bool sameStamp(std::string_view said, const CorrectionsAt& c) {
  const std::size_t at = said.find(" at ");
  if (said.substr(0, at) != c.sha256 || (at == std::string_view::npos) != c.interpolation.is_null()) return false;
  if (at == std::string_view::npos) return true;
  constexpr std::string_view kMeV = " MeV";
  if (!said.ends_with(kMeV) || said.size() < at + 4 + kMeV.size()) return false;
  const auto energy = io::parseFiniteDouble(said.substr(at + 4, said.size() - at - 4 - kMeV.size()));
  const double ours = c.beamEnergy / units::MeV;
  return energy && std::abs(*energy - ours) <= 1e-6 * std::abs(ours) + 1e-6;
}
}  // namespace

std::string filledWithLine(const CorrectionsAt& c) { return fmt::format("{}{} ({})", kFilledWith, stampOf(c), c.path); }

Status checkFilledWith(const std::string& profileText, const std::string& profilePath, const CorrectionsAt& c) {
  if (!profileText.starts_with(kFilledWith)) return {};
  const std::string line = profileText.substr(0, profileText.find('\n'));
  // The stamp holds no " (": the path (which may) follows the first one.
  const std::size_t open = line.find(" (", kFilledWith.size());
  const std::string said = line.substr(kFilledWith.size(), open - kFilledWith.size());
  if (sameStamp(said, c)) return {};
  // "PATH (sha256 <12 digits>[ at E MeV])", theirs and ours.
  const auto shown = [](std::string_view path, std::string_view stamp) {
    return fmt::format("{} (sha256 {}{})", path, stamp.substr(0, 12),
                       stamp.substr(std::min<std::size_t>(64, stamp.size())));
  };
  const std::string theirs = open == std::string::npos ? said : line.substr(open + 2, line.size() - open - 3);
  return Error{fmt::format(
      "{}: this profile was filled with the corrections {}, not with --corrections {}: give those it was filled with "
      "(a grid with the same --beam-energy), or fit the events",
      profilePath, shown(theirs, said), shown(c.path, stampOf(c)))};
}

std::string gridPointName(double beamEnergy) {
  return std::isnan(beamEnergy) ? std::string("ee-<E>MeV.json") : fmt::format("ee-{}MeV.json", beamEnergy / units::MeV);
}

geometry::DepthAtEnergy depthAtEnergy(std::shared_ptr<const CorrectionsGrid> grid, const geometry::ShowerDepth& depth) {
  return [grid = std::move(grid), depth](double beamEnergy) -> Result<geometry::ShowerDepth> {
    auto offset = grid->depthOffsetAt(beamEnergy);
    if (!offset) return offset.error();
    geometry::ShowerDepth d = depth;
    d.offset = *offset;
    return d;
  };
}

Result<CorrectionsAt> correctionsForSample(const CorrectionsGrid& grid, const std::vector<std::string>& files,
                                           std::optional<double> beamEnergy) {
  if (!grid.isGrid()) return grid.at(beamEnergy.value_or(grid.points().front().corrections.beamEnergy));
  if (!beamEnergy) {
    auto first = io::firstBeamEnergy(files);
    if (!first) return first.error();
    beamEnergy = *first;
  }
  return grid.at(*beamEnergy);
}

Result<std::string> checkSampleEnergies(const CorrectionsAt& c, const std::set<double>& energies) {
  const bool grid = !c.interpolation.is_null();
  const double own = grid ? c.beamEnergy : c.corrections.beamEnergy;  // a single file's: its own
  if (energies.empty() || std::isnan(own)) return std::string();
  const double lo = *energies.begin(), hi = *energies.rbegin();
  const double tolerance = kCorrectionsEnergyTolerance * own;
  if (std::abs(lo - own) <= tolerance && std::abs(hi - own) <= tolerance) return std::string();
  if (!grid) {
    return awayFromItsEnergy(c.path, own, lo, hi);
  }
  return Error{
      fmt::format("the selected events have {} beam energies ({} to {} MeV), but the corrections of the grid "
                  "{} were interpolated to one ({} MeV): fit each energy apart, or calibrate the runs with "
                  "emcalign campaign (each group at its own energy)",
                  energies.size(), lo / units::MeV, hi / units::MeV, c.interpolation.value("directory", std::string()),
                  c.beamEnergy / units::MeV)};
}

Result<std::string> correctionsDigest(const std::string& path) {
  std::error_code ec;
  if (!fs::is_directory(path, ec)) return sha256OfFile(path);
  auto files = jsonFilesIn(path);
  if (!files) return files.error();
  return directoryDigest(path, *files);
}

std::string interpolationText(const io::Json& interpolation) {
  if (interpolation.is_null()) return {};
  std::vector<std::string> points;
  for (const auto& p : interpolation.at("points")) {
    points.push_back(
        fmt::format("{} MeV × {:.3f}", p.at("beam_energy_mev").get<double>(), p.at("weight").get<double>()));
  }
  return fmt::format("{} MeV ({})", interpolation.at("beam_energy_mev").get<double>(), fmt::join(points, ", "));
}

}  // namespace emcalign::calib
