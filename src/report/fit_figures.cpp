#include "emcalign/report/fit_figures.hpp"

#include <cmath>
#include <filesystem>
#include <limits>
#include <numbers>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/apply/cluster_correction.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/report/fit_plots.hpp"

namespace emcalign::report {

Result<FitFigureData> fitFigureData(const std::vector<std::string>& files, const calib::FitGeometry& geometry,
                                    const calib::SelectionOptions& selection, const calib::ProfileOptions& profile,
                                    const geometry::AlignmentParameters& parameters) {
  auto transform = geometry::AlignmentTransform::create(parameters, geometry.radii);
  if (!transform) return transform.error();
  ResidualHistograms h;
  // Δφ = φ_TS,R − φ_EMC and Δθ = θ_TS,R − θ_EMC in degrees, before and after the correction.
  auto visit = [&](const ParticleRow& row, const calib::ParticleResidual& y) {
    h.dPhiBefore.fill(std::asin(y.yPhi) / units::deg);
    h.dThetaBefore.fill(y.yTheta / units::deg);
    const auto [phi, theta] = apply::correctDirection(*transform, geometry.depth, row.phiEmc, row.thetaEmc, row.energy);
    const double phiR = row.phiEmc + std::asin(y.yPhi), thetaR = row.thetaEmc + y.yTheta;
    h.dPhiAfter.fill(std::remainder(phiR - phi, 2.0 * std::numbers::pi) / units::deg);
    h.dThetaAfter.fill((thetaR - theta) / units::deg);
  };
  auto fill = calib::fillProfiles(files, geometry.depth, selection, profile, visit);
  if (!fill) return fill.error();
  return FitFigureData{std::move(*fill), std::move(h)};
}

}  // namespace emcalign::report

namespace emcalign::report {

namespace {

using io::Json;

// The corrections the result names (or `given`), at the energy a grid was interpolated to.
Result<calib::ModelCorrections> correctionsOfResult(const Json& corr, const std::string& given) {
  // The corrections the result names are named, never opened: a result file can name any file
  // of the system. The command line gives them (--corrections).
  std::string named;
  double energy = std::numeric_limits<double>::quiet_NaN();
  if (corr.contains("interpolation")) {
    energy = corr.at("interpolation").at("beam_energy_mev").get<double>() * units::MeV;
    named = corr.at("interpolation").at("directory").get<std::string>();
  }
  for (const char* key : {"response", "nominal_profile", "parting_plane_response"}) {
    if (named.empty() && corr.contains(key) && corr.at(key).is_string()) named = corr.at(key).get<std::string>();
  }
  if (!named.empty() && given.empty()) {
    return Error{fmt::format(
        "the fit used the corrections {}: give them with --corrections to redraw its figures (the report opens "
        "only the files its command line names)",
        named)};
  }
  const std::string path = named.empty() ? std::string() : given;
  calib::ModelCorrections c;
  if (path.empty()) {
    c.depthOffset = corr.contains("depth_offset_cm") && corr.at("depth_offset_cm").is_number()
                        ? corr.at("depth_offset_cm").get<double>() * units::cm
                        : 0.0;
    return c;
  }
  auto grid = calib::CorrectionsGrid::read(path);
  if (!grid) {
    return Error{fmt::format("the fit used the corrections {} (give --corrections if they moved): {}", path,
                             grid.error().message)};
  }
  auto at = grid->at(energy);
  if (!at) return at.error();
  return at->corrections;
}

double numberOr(const Json& j, const char* key, double otherwise) {
  return j.is_object() && j.contains(key) && j.at(key).is_number() ? j.at(key).get<double>() : otherwise;
}

}  // namespace

Result<ResultModel> modelOfResult(const Json& result, std::string_view source, const geometry::Calorimeter& calo,
                                  const std::string& corrections) {
  try {
    // Any status: a report shows a failed fit too.
    auto parameters = io::parseAlignmentFile(result, calo.description().r1(), source, io::AlignmentUse::Record);
    if (!parameters) return parameters.error();
    const Json& in = result.at("input");
    auto c = correctionsOfResult(in.contains("model_corrections") ? in.at("model_corrections") : Json::object(),
                                 corrections);
    if (!c) return c.error();
    ResultModel m;
    m.fit.parameters = parameters->parameters;
    m.fit.chi2 = numberOr(result, "chi2", std::numeric_limits<double>::quiet_NaN());
    m.fit.ndf = static_cast<int>(numberOr(result, "ndf", 0.0));
    m.fit.status = parameters->status.value_or(FitStatus::Converged);
    m.geometry = calib::FitGeometry::of(calo.description());
    m.geometry.apply(*c);
    m.profile.apply(*c);
    m.corrections = corrections;
    m.sigmaSys = numberOr(result.value("sigma_sys", Json::object()), "value_deg", 0.2) * units::deg;
    if (!std::isfinite(m.sigmaSys)) m.sigmaSys = 0.2 * units::deg;
    // The fit's selection: its one beam energy (an override, or the sample's own), else each event's.
    if (in.contains("beam_energies_mev") && in.at("beam_energies_mev").size() == 1) {
      m.selection = in.at("beam_energies_mev")[0].get<double>() * units::MeV;
    }
    return m;
  } catch (const Json::exception& e) {
    return Error{fmt::format("{}: not a fit result the report can redraw: {}", source, e.what())};
  }
}

Status checkEventsOfResult(const Json& result, std::string_view source, const std::vector<std::string>& events) {
  namespace fs = std::filesystem;
  std::vector<std::string> named;
  const Json in = result.value("input", Json::object());
  if (in.contains("files") && in.at("files").is_array()) {
    for (const auto& f : in.at("files")) {
      if (f.is_string()) named.push_back(f.get<std::string>());
    }
  }
  if (in.value("from_profile", false) || named.empty()) {
    return Error{
        fmt::format("{}: the fit was made from a saved profile, not from events: its figures cannot be "
                    "redrawn from --events (draw them with emcalign fit --plots)",
                    source)};
  }
  auto same = [](const std::string& a, const std::string& b) {
    std::error_code ec;
    if (fs::equivalent(a, b, ec)) return true;
    if (!fs::exists(a, ec)) return fs::path(a).filename() == fs::path(b).filename();  // the named file is gone
    auto da = sha256OfFile(a), db = sha256OfFile(b);
    return da && db && *da == *db;
  };
  bool ok = named.size() == events.size();
  for (std::size_t k = 0; ok && k < named.size(); ++k) ok = same(named[k], events[k]);
  if (ok) return {};
  return Error{
      fmt::format("--events {} are not the events {} was fitted from ({}): the figures would not be its "
                  "fit's",
                  fmt::join(events, " "), source, fmt::join(named, " "))};
}

Result<std::vector<std::string>> redrawFitFigures(const ResultModel& m, const std::vector<std::string>& events,
                                                  const std::string& dir) {
  calib::SelectionOptions selection;
  selection.beamEnergy = m.selection;
  auto data = fitFigureData(events, m.geometry, selection, m.profile, m.fit.parameters);
  if (!data) return data.error();
  return writeFitPlots(dir, data->fill.profiles.bins(m.sigmaSys), m.geometry, m.fit, &data->residuals,
                       fitModelText(m.geometry, m.profile, m.corrections));
}

}  // namespace emcalign::report
