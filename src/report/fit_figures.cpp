#include "emcalign/report/fit_figures.hpp"

#include <cmath>
#include <filesystem>
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

// The corrections the result names (or `given`), at the energy a grid was interpolated to.
Result<calib::ModelCorrections> correctionsOfResult(const calib::RecordedCorrections& corr, const std::string& given) {
  // The corrections the result names are named, never opened: a result file can name any file
  // of the system. The command line gives them (--corrections).
  const std::string named = corr.source();
  if (!named.empty() && given.empty()) {
    return Error{fmt::format(
        "the fit used the corrections {}: give them with --corrections to redraw its figures (the report opens "
        "only the files its command line names)",
        named)};
  }
  const std::string path = named.empty() ? std::string() : given;
  calib::ModelCorrections c;
  if (path.empty()) {
    c.depthOffset = corr.depthOffsetCm * units::cm;
    return c;
  }
  auto grid = calib::CorrectionsGrid::read(path);
  if (!grid) {
    return Error{fmt::format("the fit used the corrections {} (give --corrections if they moved): {}", path,
                             grid.error().message)};
  }
  auto at = grid->at(corr.interpolatedEnergyMev() * units::MeV);
  if (!at) return at.error();
  return at->corrections;
}

}  // namespace

Result<ResultModel> modelOfResult(const calib::FitRecord& result, std::string_view source,
                                  const geometry::Calorimeter& calo, const std::string& corrections) {
  // Any status: a report shows a failed fit too.
  const geometry::AlignmentParameters parameters = result.alignment();
  if (Status st = geometry::validate(parameters, calo.description().r1()); !st) {
    return Error{fmt::format("{}: {}", source, st.error().message)};
  }
  auto c = correctionsOfResult(result.input.modelCorrections.value_or(calib::RecordedCorrections{}), corrections);
  if (!c) return c.error();
  ResultModel m;
  m.fit.parameters = parameters;
  m.fit.chi2 = result.chi2;
  m.fit.ndf = static_cast<int>(result.ndf);
  m.fit.status = result.status;
  m.geometry = calib::FitGeometry::of(calo.description());
  m.geometry.apply(*c);
  m.profile.apply(*c);
  m.corrections = corrections;
  const double sigmaSys = result.sigmaSys ? result.sigmaSys->valueDeg : calib::kNotGiven;
  m.sigmaSys = (std::isfinite(sigmaSys) ? sigmaSys : 0.2) * units::deg;
  // The fit's selection: its one beam energy (an override, or the sample's own), else each event's.
  if (result.input.beamEnergiesMev.size() == 1) m.selection = result.input.beamEnergiesMev.front() * units::MeV;
  return m;
}

Status checkEventsOfResult(const calib::RecordedInput& result, std::string_view source,
                           const std::vector<std::string>& events) {
  namespace fs = std::filesystem;
  const std::vector<std::string>& named = result.files;
  if (result.fromProfile || named.empty()) {
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

Result<std::vector<std::string>> writeFitJobFigures(const calib::FitJob& job, const calib::FitOutcome& fitted,
                                                    const std::string& dir) {
  const calib::FitRequest& request = job.request();
  std::optional<FitFigureData> data;
  if (request.profileIn.empty()) {
    calib::SelectionOptions selection;
    selection.beamEnergy = request.beamEnergy;
    auto filled =
        fitFigureData(request.events, job.geometry(), selection, job.profileOptions(), fitted.result.parameters);
    if (!filled) return filled.error();
    data = std::move(*filled);
  }
  return writeFitPlots(dir, fitted.bins, job.geometry(), fitted.result, data ? &data->residuals : nullptr,
                       fitModelText(job.geometry(), job.profileOptions(), request.corrections));
}

}  // namespace emcalign::report
