#include "emcalign/calib/fit_job.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <fmt/format.h>

namespace emcalign::calib {

Status FitRequest::validate() const {
  if (events.empty() == profileIn.empty()) return Error{"give event files or a saved profile (one of them)"};
  if (beamEnergy && !(std::isfinite(*beamEnergy) && *beamEnergy > 0.0)) {
    return Error{fmt::format("beam energy {} MeV: expected a positive energy", *beamEnergy)};
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
  // The honest errors take the correlation of an event's two particles along (profiles.hpp).
  job.profile_.eventPairs = request.sigmaSys && request.sigmaSys->keepsEventPairs();
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

Result<FitData> FitJob::load() const {
  FitData data;
  if (!request_.profileIn.empty()) {
    auto read = readProfileCsv(request_.profileIn);
    if (!read) return read.error();
    if (Status s = checkSavedProfile(request_, *read); !s) return s.error();
    data.bins = std::move(*read);
    markUsedBins(data.bins, ProfileOptions{}.minEntries);
    if (corrections_ && !corrections_->warning.empty()) data.warnings.push_back(corrections_->warning);
    return data;
  }
  auto filled = fillProfiles(request_.events, geometry_.depth, selectionOf(request_), profile_);
  if (!filled) return filled.error();
  data.fill = std::move(*filled);
  if (corrections_) {
    // From every selected event (a single file's own energy, a grid's interpolation point).
    auto warning = checkSampleEnergies(*corrections_, data.fill->beamEnergies);
    if (!warning) return warning.error();
    if (!warning->empty()) data.warnings.push_back(std::move(*warning));
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
    input.files = request_.events;
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
  return out;
}

}  // namespace emcalign::calib
