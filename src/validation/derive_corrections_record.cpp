// The record of a derivation (validation/derive_corrections.hpp): the corrections file with
// what it was derived from, and the grid of such files a plan derives.

#include <filesystem>
#include <memory>
#include <set>

#include <fmt/format.h>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/validation/derive_corrections.hpp"

namespace emcalign::validation {

using geometry::AlignmentParameters;
using io::Json;

namespace {

Json parameterErrorsJson(const geometry::ParamVector& errors) {
  Json out = Json::object();
  for (Param p : kAllParams) {
    out[std::string(name(p))] = errors[p] / AlignmentParameters::fileUnit(p);
  }
  return out;
}

// The statistical errors of R in file units (as the file's "response" matrix).
Json responseErrorJson(const DerivationReport& r) {
  Json rows = Json::array();
  for (Param pj : kAllParams) {
    Json row = Json::array();
    for (Param pk : kAllParams) {
      row.push_back(r.responseErrors(pj, pk) * AlignmentParameters::fileUnit(pk) / AlignmentParameters::fileUnit(pj));
    }
    rows.push_back(row);
  }
  Json offset = Json::array();
  for (Param p : kAllParams) {
    offset.push_back(r.responseOffsetErrors[p] / AlignmentParameters::fileUnit(p));
  }
  return {{"matrix", rows}, {"offset", offset}};
}

}  // namespace

DerivationProgress simulatedEventsProgress(std::function<void(std::int64_t)> events) {
  struct Count {
    std::int64_t before = 0, lastTotal = 0;  // events of the finished stages; the current one's total
    std::string lastStage;
  };
  return [count = std::make_shared<Count>(), events = std::move(events)](std::string_view stage, std::int64_t done,
                                                                         std::int64_t total) {
    if (stage.rfind("simulate", 0) != 0) return;
    if (stage != count->lastStage) {
      count->lastStage = std::string(stage);
      count->before += count->lastTotal;
      count->lastTotal = total;
    }
    events(count->before + done);
  };
}

Json derivationJson(const DerivationReport& r, const Json& settings) {
  calib::ModelCorrections c = r.corrections;
  Json closure = Json::array();
  for (const auto& f : r.closure) {
    closure.push_back({{"sample", f.sample},
                       {"parameter", f.parameter},
                       {"truth_cm", f.truth},
                       {"paper_model_cm", f.paperModel},
                       {"paper_model_error_cm", f.paperError},
                       {"corrected_cm", f.corrected},
                       {"corrected_error_cm", f.correctedError}});
  }
  const Json nominalErrors = parameterErrorsJson(r.nominalProfileErrors);
  c.derivedFrom = {{"command", "emcalign derive-corrections"},
                   {"settings", settings},
                   {"selected_events",
                    {{"nominal", r.selectedEvents[0]}, {"shift", r.selectedEvents[1]}, {"gap", r.selectedEvents[2]}}},
                   {"depth_offset_error_cm", r.depthOffsetError},
                   {"depth_chi2", r.depthChi2},
                   {"depth_bins", r.depthBins},
                   {"column_plus_weight_measured", r.columnWeights},
                   {"column_plus_weight_error", r.columnWeightErrors},
                   {"closure", closure},
                   {"response_error", r.corrections.response ? responseErrorJson(r) : Json(nullptr)},
                   {"response_parameter_errors",
                    r.corrections.response ? parameterErrorsJson(r.responseParameterErrors) : Json(nullptr)},
                   {"nominal_profile_parameter_errors", nominalErrors}};
  return calib::correctionsJson(c);
}

bool derivedWith(const std::string& file, const Json& settings) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) return false;
  // This command's own output of an earlier run: unreadable or other settings, derived again.
  auto text = io::readOwnOutput(file);
  auto j = text ? io::parseJson(*text, file) : Result<Json>(text.error());
  auto c = j ? calib::parseCorrections(*j, file) : Result<calib::ModelCorrections>(j.error());
  return c && c->derivedFrom.is_object() && c->derivedFrom.value("settings", Json()) == settings;
}

Result<std::vector<GridPoint>> planGrid(const std::string& dir, const std::vector<double>& energies,
                                        const std::function<Json(double beamEnergy)>& settingsAt) {
  namespace fs = std::filesystem;
  std::vector<GridPoint> points;
  std::set<std::string> names;
  for (double e : energies) {
    GridPoint p{e, (fs::path(dir) / calib::gridPointName(e)).string(), false};
    std::error_code ec;
    p.done = derivedWith(p.file, settingsAt(e));
    names.insert(fs::path(p.file).filename().string());
    points.push_back(std::move(p));
  }
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return points;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() == ".json" && !names.contains(name)) {
      return Error{
          fmt::format("{}: this grid directory holds {}, which is not one of the energies asked for: the "
                      "directory is the grid that fit --corrections reads (give its energy too, or remove "
                      "the file)",
                      dir, name)};
    }
  }
  if (ec) return Error{fmt::format("{}: cannot list the directory: {}", dir, ec.message())};
  return points;
}

std::string derivationTaskDirectory(const std::string& workDirectory, double beamEnergy) {
  return (std::filesystem::path(workDirectory) /
          ("derive-" + std::filesystem::path(calib::gridPointName(beamEnergy)).stem().string()))
      .string();
}

}  // namespace emcalign::validation
