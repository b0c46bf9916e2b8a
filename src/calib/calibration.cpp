#include "emcalign/calib/calibration.hpp"
#include "emcalign/core/beam_energy.hpp"

#include <optional>

#include <cmath>

#include <fmt/format.h>

#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/event_file.hpp"

namespace emcalign::calib {

namespace {
// Selection and profiles use the reconstructed rows only: the truth and the hits of a
// simulated file are not read (two thirds of its bytes).
const io::ReaderOptions kProfileReading{.truth = false, .hits = false};
}  // namespace

ProfileFiller::ProfileFiller(const geometry::ShowerDepth& depth, SelectionOptions selection, ProfileOptions profile,
                             ParticleVisitor visit)
    : depth_(depth), selection_(selection), visit_(std::move(visit)) {
  fill_.profiles = Profiles(std::move(profile));
}

void ProfileFiller::addEvents(std::span<const ParticleRow> rows, std::string_view source) {
  fill_.cutFlow.rows += static_cast<std::int64_t>(rows.size());
  for (std::size_t i = 0; i < rows.size();) {
    std::size_t j = i + 1;
    while (j < rows.size() && sameEvent(rows[j], rows[i])) ++j;
    const std::span<const ParticleRow> event = rows.subspan(i, j - i);
    if (selection_.beamEnergy && fill_.beamEnergyMismatch.empty()) {
      if (std::string why = beamEnergyOverrideProblem(*selection_.beamEnergy, event[0].beamEnergy); !why.empty()) {
        fill_.beamEnergyMismatch = fmt::format("{}{}run {} event {}, beam_energy_mev: {}", source,
                                               source.empty() ? "" : ": ", event[0].run, event[0].event, why);
      }
    }
    const int failed = selectEvent(event, selection_);
    const int passed = failed == 0 ? static_cast<int>(CutFlow::kNames.size()) : failed;
    for (int k = 0; k < passed; ++k) fill_.cutFlow.events[static_cast<std::size_t>(k)] += 1;
    if (failed == 4) {  // the cluster energies: how far from the beam's, for a unit hint
      for (const auto& r : event) {
        const double beam = selection_.beamEnergy.value_or(r.beamEnergy);
        if (r.hasCluster() && beam > 0.0) {
          fill_.cutFlow.refusedEnergyRatio += r.energy / beam;
          ++fill_.cutFlow.refusedByEnergy;
        }
      }
    }
    if (failed == 0) {
      fill_.beamEnergies.insert(selection_.beamEnergy.value_or(event[0].beamEnergy));
      std::optional<ParticleResidual> first;
      for (const auto& r : event) {
        ++fill_.particlesSelected;
        const auto y = residualOf(r, depth_);
        if (!y) {
          ++fill_.trackMisses;
          continue;
        }
        if (fill_.profiles.fill(*y)) ++fill_.particlesInRange;
        if (visit_) visit_(r, *y);
        // A selected event has two particles: their correlation, for the errors (profiles.hpp).
        if (first) {
          fill_.profiles.fillPair(*first, *y);
        } else {
          first = y;
        }
      }
    }
    i = j;
  }
}

Status ProfileFiller::checkSelected() const {
  if (!fill_.beamEnergyMismatch.empty()) return Error{fill_.beamEnergyMismatch};
  if (fill_.cutFlow.events.back() > 0) return {};
  std::string flow;
  for (std::size_t k = 0; k < CutFlow::kNames.size(); ++k) {
    flow += fmt::format("{}{} {}", k ? ", " : "", CutFlow::kNames[k], fill_.cutFlow.events[k]);
  }
  const CutFlow& c = fill_.cutFlow;
  const std::string hint =
      c.refusedByEnergy > 0 ? clusterEnergyUnitHint(c.refusedEnergyRatio / static_cast<double>(c.refusedByEnergy)) : "";
  return Error{fmt::format("no event passes the e+e- -> e+e- selection ({}){}", flow, hint.empty() ? "" : ": " + hint)};
}

Result<ProfileFill> fillProfiles(const std::vector<std::string>& files, const geometry::ShowerDepth& depth,
                                 const SelectionOptions& selection, const ProfileOptions& profile,
                                 const ParticleVisitor& visit) {
  if (Status s = profile.validate(); !s) return s.error();
  auto reader = io::EventReader::open(files, kProfileReading);
  if (!reader) return reader.error();
  ProfileFiller filler(depth, selection, profile, visit);
  std::vector<ParticleRow> rows;
  while (true) {
    auto more = (*reader)->next(rows);
    if (!more) return more.error();
    if (!*more) break;
    filler.addEvents(rows, (*reader)->path());  // blocks hold whole events
  }
  if (Status s = filler.checkSelected(); !s) return s.error();
  return std::move(filler.fill());
}

Result<ProfileFill> fillProfilesOfRows(std::span<const ParticleRow> rows, const std::string& source,
                                       const geometry::ShowerDepth& depth, const SelectionOptions& selection,
                                       const ProfileOptions& profile, const ParticleVisitor& visit) {
  if (Status s = profile.validate(); !s) return s.error();
  if (Status s = io::checkRowsInMemory(rows, source); !s) return s.error();
  ProfileFiller filler(depth, selection, profile, visit);
  filler.addEvents(rows);
  if (Status s = filler.checkSelected(); !s) return Error{fmt::format("{}: {}", source, s.error().message)};
  return std::move(filler.fill());
}

void ProfileFill::merge(const ProfileFill& other) {
  for (std::size_t k = 0; k < cutFlow.events.size(); ++k) cutFlow.events[k] += other.cutFlow.events[k];
  cutFlow.rows += other.cutFlow.rows;
  cutFlow.refusedEnergyRatio += other.cutFlow.refusedEnergyRatio;
  cutFlow.refusedByEnergy += other.cutFlow.refusedByEnergy;
  profiles.merge(other.profiles);
  particlesSelected += other.particlesSelected;
  particlesInRange += other.particlesInRange;
  trackMisses += other.trackMisses;
  beamEnergies.insert(other.beamEnergies.begin(), other.beamEnergies.end());
  if (beamEnergyMismatch.empty()) beamEnergyMismatch = other.beamEnergyMismatch;
}

io::Json ProfileFill::state() const {
  io::Json energies = io::Json::array();
  for (double e : beamEnergies) energies.push_back(e);
  return {{"cut_flow", cutFlow.events},
          {"rows", cutFlow.rows},
          {"refused_energy_ratio", cutFlow.refusedEnergyRatio},
          {"refused_by_energy", cutFlow.refusedByEnergy},
          {"particles_selected", particlesSelected},
          {"particles_in_range", particlesInRange},
          {"track_misses", trackMisses},
          {"beam_energies", energies},
          {"beam_energy_mismatch", beamEnergyMismatch},
          {"profiles", profiles.state()}};
}

Result<ProfileFill> ProfileFill::restore(const io::Json& state, const ProfileOptions& options,
                                         const std::string& source) {
  const auto bad = [&](std::string_view key) {
    return Error{fmt::format("{}: \"{}\" is missing or wrong", source, key)};
  };
  if (!state.is_object()) return Error{fmt::format("{}: not a fill (a JSON object)", source)};
  ProfileFill f;
  const auto count = [&](std::string_view key, std::int64_t& to) -> bool {
    const auto it = state.find(key);
    if (it == state.end() || !it->is_number_integer() || it->get<std::int64_t>() < 0) return false;
    to = it->get<std::int64_t>();
    return true;
  };
  const auto flow = state.find("cut_flow");
  if (flow == state.end() || !flow->is_array() || flow->size() != f.cutFlow.events.size()) return bad("cut_flow");
  for (std::size_t k = 0; k < f.cutFlow.events.size(); ++k) {
    if (!(*flow)[k].is_number_integer() || (*flow)[k].get<std::int64_t>() < 0) return bad("cut_flow");
    f.cutFlow.events[k] = (*flow)[k].get<std::int64_t>();
  }
  for (const auto& [key, to] : {std::pair<std::string_view, std::int64_t*>{"rows", &f.cutFlow.rows},
                                {"refused_by_energy", &f.cutFlow.refusedByEnergy},
                                {"particles_selected", &f.particlesSelected},
                                {"particles_in_range", &f.particlesInRange},
                                {"track_misses", &f.trackMisses}}) {
    if (!count(key, *to)) return bad(key);
  }
  const auto ratio = state.find("refused_energy_ratio");
  if (ratio == state.end() || !ratio->is_number()) return bad("refused_energy_ratio");
  f.cutFlow.refusedEnergyRatio = ratio->get<double>();
  const auto energies = state.find("beam_energies");
  if (energies == state.end() || !energies->is_array()) return bad("beam_energies");
  for (const io::Json& e : *energies) {
    if (!e.is_number() || !std::isfinite(e.get<double>())) return bad("beam_energies");
    f.beamEnergies.insert(e.get<double>());
  }
  const auto mismatch = state.find("beam_energy_mismatch");
  if (mismatch == state.end() || !mismatch->is_string()) return bad("beam_energy_mismatch");
  f.beamEnergyMismatch = mismatch->get<std::string>();
  const auto profiles = state.find("profiles");
  if (profiles == state.end()) return bad("profiles");
  auto p = Profiles::restore(*profiles, options, source);
  if (!p) return p.error();
  f.profiles = std::move(*p);
  return f;
}

Result<std::map<std::int32_t, ProfileFill>> fillProfilesByRun(const std::string& file,
                                                              const geometry::DepthAtEnergy& depthAt,
                                                              const SelectionOptions& selection,
                                                              const ProfileOptions& profile,
                                                              std::map<std::int32_t, io::EventNumbers>* events) {
  if (Status s = profile.validate(); !s) return s.error();
  auto reader = io::EventReader::open({file}, kProfileReading);
  if (!reader) return reader.error();
  std::map<std::int32_t, ProfileFiller> fillers;
  std::vector<ParticleRow> rows;
  while (true) {
    auto more = (*reader)->next(rows);
    if (!more) return more.error();
    if (!*more) break;
    // Blocks hold whole events; each stretch of one run goes to that run's filler.
    for (std::size_t i = 0; i < rows.size();) {
      std::size_t j = i + 1;
      while (j < rows.size() && rows[j].run == rows[i].run) ++j;
      auto it = fillers.find(rows[i].run);
      if (it == fillers.end()) {
        const double energy = selection.beamEnergy.value_or(rows[i].beamEnergy);
        auto depth = depthAt(energy);
        if (!depth)
          return Error{fmt::format("{}: run {} ({} MeV): {}", file, rows[i].run, energy, depth.error().message)};
        it = fillers.emplace(rows[i].run, ProfileFiller(*depth, selection, profile)).first;
      }
      it->second.addEvents(std::span<const ParticleRow>(rows).subspan(i, j - i));
      if (events != nullptr) {
        io::EventNumbers& numbers = (*events)[rows[i].run];
        for (std::size_t k = i; k < j; ++k) numbers.insert(rows[k].event);
      }
      i = j;
    }
  }
  std::map<std::int32_t, ProfileFill> out;
  for (auto& [run, filler] : fillers) out.emplace(run, std::move(filler.fill()));
  return out;
}

io::Json sigmaSysJson(const SigmaSysUsed& s) {
  using io::Json;
  Json j = {{"method", std::string(name(s.method))},
            {"value_deg", io::numberOrNull(s.value / units::deg)},
            {"event_pair_correlations", s.eventPairs}};
  if (s.method == SigmaSysMethod::Auto) {
    j["interval_deg"] = {io::numberOrNull(s.lower / units::deg), io::numberOrNull(s.upper / units::deg)};
    j["chi2_statistical_errors"] = s.chi2Stat;
    j["p_value_statistical_errors"] = s.pValueStat;
    j["fits"] = s.fits;
  }
  return j;
}

namespace {

using geometry::AlignmentParameters;
using io::Json;

// "covariance" (file units) and "correlation"; a null covariance when the fit has none.
void addCovariance(const FitResult& r, Json& j) {
  if (r.covariance) {
    Json cov = Json::array(), corr = Json::array();
    for (Param p : kAllParams) {
      Json row = Json::array(), crow = Json::array();
      for (Param q : kAllParams) {
        row.push_back((*r.covariance)(p, q) / (AlignmentParameters::fileUnit(p) * AlignmentParameters::fileUnit(q)));
        crow.push_back(r.correlation(p, q));
      }
      cov.push_back(row);
      corr.push_back(crow);
    }
    j["covariance"] = cov;
    j["correlation"] = corr;
  } else {
    j["covariance"] = nullptr;
  }
}

// "derived": the physical parameters with their errors (and systematic errors, when given).
Json derivedJson(const FitResult& r, const FitInput& input) {
  Json derived = Json::object();
  for (Physical p : kDerivedParams) {
    const double unit = geometry::PhysicalParameters::fileUnit(p);
    const DerivedValue& v = r.derived[p];
    derived[std::string(name(p))] = {
        {"value", v.value / unit}, {"error", io::numberOrNull(v.error / unit)}, {"unit", fileUnitName(dimension(p))}};
    if (std::isfinite(v.statisticalError))
      derived[std::string(name(p))]["statistical_error"] = v.statisticalError / unit;
    if (!input.systematics) continue;
    if (auto it = input.systematics->errors.find(p); it != input.systematics->errors.end()) {
      derived[std::string(name(p))]["systematic_error"] = it->second;
    }
  }
  return derived;
}

// "stages": each stage's free parameters, χ², iterations and convergence.
Json stagesJson(const FitResult& r) {
  Json stages = Json::array();
  for (std::size_t k = 0; k < r.stages.size(); ++k) {
    Json free = Json::array();
    for (Param p : r.stages[k].free) free.push_back(std::string(name(p)));
    stages.push_back({{"stage", k + 1},
                      {"free", free},
                      {"chi2", r.stages[k].chi2},
                      {"iterations", r.stages[k].iterations},
                      {"converged", r.stages[k].converged}});
  }
  return stages;
}

// "input": the files, detector, bins, model corrections, selection and eigenvalues.
Json inputJson(const FitResult& r, const FitInput& input) {
  Json in = {{"files", input.files},
             {"from_profile", input.fromProfile},
             {"detector", input.detector},
             {"bins_used", r.binsUsed},
             {"bins_left_out", r.binsLeftOut.size()}};
  in["model_corrections"] = {
      {"depth_offset_cm", input.depthOffset / units::cm},
      {"parting_plane_response", input.partingPlane.empty() ? Json(nullptr) : Json(input.partingPlane)},
      {"nominal_profile", input.nominalProfile.empty() ? Json(nullptr) : Json(input.nominalProfile)},
      {"response", input.response.empty() ? Json(nullptr) : Json(input.response)}};
  if (!input.correctionsInterpolation.is_null())
    in["model_corrections"]["interpolation"] = input.correctionsInterpolation;
  if (input.systematics) {
    in["model_corrections"]["systematic_errors"] = {{"source", input.systematicsSource},
                                                    {"study", input.systematics->study}};
  }
  if (input.fill != nullptr) {
    Json flow = Json::object();
    for (std::size_t k = 0; k < CutFlow::kNames.size(); ++k) flow[CutFlow::kNames[k]] = input.fill->cutFlow.events[k];
    in["cut_flow"] = flow;
    in["particles_selected"] = input.fill->particlesSelected;
    in["particles_in_profiles"] = input.fill->particlesInRange;
    in["beam_energies_mev"] = std::vector<double>(input.fill->beamEnergies.begin(), input.fill->beamEnergies.end());
  }
  Json eig = Json::array();
  for (double e : r.eigenvalues) eig.push_back(e);
  in["correlation_eigenvalues"] = eig;
  return in;
}

}  // namespace

io::Json fitResultJson(const FitResult& r, const FitInput& input) {
  Json j = io::alignmentToJson(r.parameters);
  Json errors = Json::object();
  for (Param p : kAllParams) {
    errors[std::string(name(p))] = io::numberOrNull(r.errors[p] / AlignmentParameters::fileUnit(p));
  }
  j["errors"] = errors;
  if (r.statisticalCovariance) {
    Json statistical = Json::object();
    for (Param p : kAllParams) {
      statistical[std::string(name(p))] = io::numberOrNull(r.statisticalErrors[p] / AlignmentParameters::fileUnit(p));
    }
    j["statistical_errors"] = statistical;
  }
  if (input.systematics) {
    Json systematic = Json::object();
    for (Param p : kAllParams) systematic[std::string(name(p))] = input.systematics->errors.find(p)->second;
    j["systematic_errors"] = systematic;
  }
  addCovariance(r, j);
  j["derived"] = derivedJson(r, input);
  j["chi2"] = r.chi2;
  j["ndf"] = r.ndf;
  j["p_value"] = r.pValue;
  j["stages"] = stagesJson(r);
  j["status"] = std::string(name(r.status));
  j["warnings"] = r.warnings;
  j["sigma_sys"] = sigmaSysJson(r.sigmaSys);
  j["input"] = inputJson(r, input);
  j["software"] = fmt::format("emcalign {}", kVersion);
  return j;
}

}  // namespace emcalign::calib
