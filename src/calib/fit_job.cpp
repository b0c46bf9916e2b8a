#include "emcalign/calib/fit_job.hpp"
#include "emcalign/core/beam_energy.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <fmt/format.h>

#include "emcalign/core/units.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::calib {

std::string thetaRangeWarning(const std::optional<std::string>& simulation, const ModelCorrections& corrections,
                              const std::string& correctionsPath) {
  const io::Json settings = corrections.derivedFrom.value("settings", io::Json::object());
  const io::Json derived = settings.value("theta_range_deg", io::Json());
  if (!simulation || !derived.is_array() || derived.size() != 2) return {};  // data, or not recorded
  const io::Json j = io::Json::parse(*simulation, nullptr, false);
  const io::Json sample = j.is_object() ? j.value("theta_range_deg", io::Json()) : io::Json();
  if (!sample.is_array() || sample.size() != 2 || !sample[0].is_number() || !sample[1].is_number() ||
      !derived[0].is_number() || !derived[1].is_number()) {
    return {};
  }
  const double s0 = sample[0].get<double>(), s1 = sample[1].get<double>();
  const double d0 = derived[0].get<double>(), d1 = derived[1].get<double>();
  if (std::abs(s0 - d0) < 1e-6 && std::abs(s1 - d1) < 1e-6) return {};
  return fmt::format(
      "{}: derived from samples simulated at theta {:g}-{:g} deg, this sample at {:g}-{:g} deg: the corrections "
      "describe the detector as the derivation saw it (simulate --theta-min {:g} --theta-max {:g}, or derive them "
      "at this range)",
      correctionsPath, d0, d1, s0, s1, d0, d1);
}

Status FitRequest::validate() const {
  if ((events.empty() ? 0 : 1) + (profileIn.empty() ? 0 : 1) + (rows ? 1 : 0) != 1) {
    return Error{"give event files, events in memory or a saved profile (one of them)"};
  }
  if (beamEnergy) {
    if (std::string problem = beamEnergyProblem(*beamEnergy * units::MeV); !problem.empty()) {
      return Error{"beam energy " + problem};
    }
  }
  if (Status s = checkDepthOffset(depthOffset, corrections); !s) return s;
  if (sigmaSys) return sigmaSys->validate();
  return {};
}

namespace {

// The corrections at the sample's beam energy: the request's, else the first event's (a
// saved profile does not say it: a grid needs the request's).
Result<CorrectionsAt> correctionsOf(const FitRequest& r) {
  auto grid = CorrectionsGrid::read(r.corrections);
  if (!grid) return grid.error();
  std::optional<double> energy;
  if (r.beamEnergy) energy = *r.beamEnergy * units::MeV;
  if (!r.profileIn.empty()) {
    if (grid->isGrid() && !energy) {
      return Error{
          fmt::format("--corrections {} is a grid over beam energies and the profile {} does not say its "
                      "energy: give --beam-energy",
                      r.corrections, r.profileIn)};
    }
    return grid->at(energy.value_or(std::numeric_limits<double>::quiet_NaN()));
  }
  if (r.rows) {
    if (r.rows->empty()) return Error{fmt::format("{}: no row", r.rowsName)};
    return grid->at(energy.value_or(r.rows->front().beamEnergy * units::MeV));
  }
  return correctionsForSample(*grid, r.events, energy);
}

SelectionOptions selectionOf(const FitRequest& r) {
  SelectionOptions s;
  if (r.beamEnergy) s.beamEnergy = *r.beamEnergy;
  return s;
}

// A saved profile against the request: the corrections it was written with, no σ_sys.
Status checkSavedProfile(const FitRequest& r, const std::vector<ProfileBin>& bins) {
  const bool weighted = std::any_of(bins.begin(), bins.end(), [](const auto& b) { return !std::isnan(b.plusWeight); });
  // A profile written by a fit with corrections carries them (the plus_weight column, the
  // nominal profile subtracted); only the model's depth offset must come again.
  if (!r.corrections.empty() && !weighted) {
    return Error{
        fmt::format("{}: this profile was written without --corrections and cannot take them now "
                    "(its residuals were built at another depth): fit the events with --corrections",
                    r.profileIn)};
  }
  if (weighted && r.corrections.empty()) {
    return Error{
        fmt::format("{}: this profile was written with --corrections (it has a plus_weight column): "
                    "give the same --corrections file, for the model's depth offset",
                    r.profileIn)};
  }
  if (r.sigmaSys) {
    return Error{
        fmt::format("{}: a saved profile holds the total errors it was written with (statistical and "
                    "sigma_sys): --sigma-sys needs the events (fit them with --sigma-sys {})",
                    r.profileIn, r.sigmaSysText)};
  }
  return {};
}

}  // namespace

Result<FitJob> FitJob::prepare(FitRequest request, const geometry::DetectorDescription& detector) {
  if (Status s = request.validate(); !s) return s.error();
  FitJob job;
  job.geometry_ = FitGeometry::of(detector);
  job.geometry_.depth.offset = request.depthOffset;
  // The statistical errors, and the honest errors of σ_sys auto, take the correlation of an
  // event's two particles along (profiles.hpp).
  job.profile_.eventPairs = true;
  if (!request.corrections.empty()) {
    auto at = correctionsOf(request);
    if (!at) return at.error();
    job.corrections_ = std::move(*at);
    job.geometry_.apply(job.corrections_->corrections);
    job.profile_.apply(job.corrections_->corrections);
  }
  job.request_ = std::move(request);
  return job;
}

std::string FitJob::savedProfile(const FitOutcome& outcome) const {
  return corrections_ ? profileCsv(outcome.bins, filledWithLine(*corrections_)) : profileCsv(outcome.bins);
}

Result<FitData> FitJob::load() const {
  FitData data;
  if (!request_.profileIn.empty()) {
    auto read = readProfileCsv(request_.profileIn);
    if (!read) return read.error();
    if (Status s = checkSavedProfile(request_, *read); !s) return s.error();
    if (corrections_) {
      auto text = io::readTextFile(request_.profileIn);
      if (!text) return text.error();
      if (Status s = checkFilledWith(*text, request_.profileIn, *corrections_); !s) return s.error();
    }
    data.bins = std::move(*read);
    markUsedBins(data.bins, ProfileOptions{}.minEntries);
    if (corrections_ && !corrections_->warning.empty()) data.warnings.push_back(corrections_->warning);
    return data;
  }
  auto filled = request_.rows ? fillProfilesOfRows(*request_.rows, request_.rowsName, geometry_.depth,
                                                   selectionOf(request_), profile_)
                              : fillProfiles(request_.events, geometry_.depth, selectionOf(request_), profile_);
  if (!filled) return filled.error();
  data.fill = std::move(*filled);
  if (std::string tracks = trackCutWarning(data.fill->cutFlow, selectionOf(request_)); !tracks.empty()) {
    data.warnings.push_back(std::move(tracks));
  }
  if (corrections_) {
    // From every selected event (a single file's own energy, a grid's interpolation point).
    auto warning = checkSampleEnergies(*corrections_, data.fill->beamEnergies);
    if (!warning) return warning.error();
    if (!warning->empty()) data.warnings.push_back(std::move(*warning));
  }
  if (request_.rows) return data;  // rows carry no attributes: no truth, no simulation settings
  // What a simulated sample says of itself, read once for the warning below and the truth.
  auto attributes = io::commonAttributes(request_.events, {"truth_parameters", "simulation"});
  if (!attributes) return attributes.error();
  data.truthAttribute = (*attributes)["truth_parameters"];
  data.simulationAttribute = (*attributes)["simulation"];
  if (corrections_) {
    std::string theta = thetaRangeWarning(data.simulationAttribute, corrections_->corrections, request_.corrections);
    if (!theta.empty()) data.warnings.push_back(std::move(theta));
  }
  return data;
}

Result<FitOutcome> FitJob::fit(const FitData& data) const {
  auto result = data.fill ? fitProfiles(data.fill->profiles, geometry_, sigmaSys()) : fitProfiles(data.bins, geometry_);
  if (!result) return result.error();
  FitOutcome out;
  out.result = std::move(*result);
  FitInput input;
  input.detector = request_.detectorName;
  input.depthOffset = geometry_.depth.offset;
  if (data.fill) {
    out.bins = fittedBins(data.fill->profiles, out.result.sigmaSys);
    input.files = request_.rows ? std::vector<std::string>{request_.rowsName} : request_.events;
    input.fill = &*data.fill;
  } else {
    out.bins = data.bins;
    out.result.sigmaSys = {.method = SigmaSysMethod::Saved, .value = std::numeric_limits<double>::quiet_NaN()};
    input.files = {request_.profileIn};
    input.fromProfile = true;
  }
  if (corrections_) {
    const ModelCorrections& c = corrections_->corrections;
    input.correctionsInterpolation = corrections_->interpolation;
    const std::string& path = request_.corrections;
    if (c.response) input.response = path;
    if (c.partingPlane) input.partingPlane = path;
    if (c.nominalProfile) input.nominalProfile = path;
    input.systematics = c.systematics;
    input.systematicsSource = path;
    if (!data.fill) input.partingPlane = input.nominalProfile = request_.profileIn + " (written with " + path + ")";
  }
  out.resultJson = fitResultJson(out.result, input);
  // What a physicist must know of this fit travels with it (the report shows it).
  std::vector<std::string> said = notes(data, out);
  if (auto w = rangeWarning(out.result)) said.push_back(*w);
  out.resultJson["notes"] = said;
  return out;
}

std::vector<std::string> FitJob::notes(const FitData& data, const FitOutcome& outcome) const {
  FitModel model;
  model.corrected = corrections_.has_value();
  model.corrections = request_.corrections;
  model.depthOffset = request_.depthOffset;
  std::vector<std::string> notes = fitNotes(outcome.result, model);
  if (data.fill && data.fill->particlesSelected > 0 && 2 * data.fill->particlesInRange < data.fill->particlesSelected) {
    notes.push_back(fmt::format(
        "only {:.0f} % of the selected particles ({} of {}) lie in the profiles' {:g}-{:g} deg of theta: the sample "
        "spans a wider theta than the fit uses (emcalign simulate's default is 10-170 deg; the shipped corrections "
        "were derived at 40-140 deg: --theta-min 40 --theta-max 140)",
        100.0 * static_cast<double>(data.fill->particlesInRange) / static_cast<double>(data.fill->particlesSelected),
        data.fill->particlesInRange, data.fill->particlesSelected, profile_.thetaMin / units::deg,
        profile_.thetaMax / units::deg));
  }
  return notes;
}

Result<std::optional<std::vector<TruthRow>>> FitJob::againstTruth(const FitData& data,
                                                                  const FitOutcome& outcome) const {
  if (!data.truthAttribute) return std::optional<std::vector<TruthRow>>();
  const std::string source = fmt::format("{}: its truth_parameters", request_.events.front());
  auto json = io::parseJson(*data.truthAttribute, source);
  if (!json) return json.error();
  auto truth = io::parseAlignment(*json, geometry_.radii.r1, source);
  if (!truth) return truth.error();
  auto rows = compareWithTruth(outcome.result, *truth, geometry_.radii.r1);
  if (!rows) return rows.error();
  return std::optional<std::vector<TruthRow>>(std::move(*rows));
}

}  // namespace emcalign::calib
