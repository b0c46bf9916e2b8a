#pragma once
// From event files to profiles: stream the events, select e+e- → e+e- (docs/contract.md §7), compute
// each particle's residuals and fill the 160 bins. Memory does not grow with the number of
// events. Also: the fit-result file (docs/contract.md §3).

#include <cstdint>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "emcalign/calib/corrections.hpp"
#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/profiles.hpp"
#include "emcalign/calib/selection.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/event_numbers.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::calib {

struct ProfileFill {
  CutFlow cutFlow;
  Profiles profiles;
  std::int64_t particlesSelected = 0;  ///< particles of selected events
  std::int64_t particlesInRange = 0;   ///< of those, inside the profile range
  std::int64_t trackMisses = 0;        ///< tracks that miss the sphere R(E, θ)
  std::set<double> beamEnergies;       ///< MeV, of the selected events (the selection's, when given)
  /// The first event whose file's beam energy the selection's (--beam-energy) cannot stand for
  /// (beamEnergyOverrideProblem): where, and why; empty when none.
  std::string beamEnergyMismatch;
  /// An empty fill with these profile bins.
  static ProfileFill empty(const ProfileOptions& options) {
    ProfileFill f;
    f.profiles = Profiles(options);
    return f;
  }
  /// Adds another fill with the same profile bins (the fills of several runs make their
  /// group's).
  void merge(const ProfileFill& other);
  /// The fill as JSON, exactly (Profiles::state), and back: a run's fill kept on disk until
  /// its group is fitted (validation/prompt.hpp).
  [[nodiscard]] io::Json state() const;
  static Result<ProfileFill> restore(const io::Json& state, const ProfileOptions& options, const std::string& source);
};

/// Called for every particle of a selected event with its residuals (for histograms).
using ParticleVisitor = std::function<void(const ParticleRow&, const ParticleResidual&)>;

/// Selects events and fills the profiles from rows of whole events (from files, or straight
/// from the simulation).
class ProfileFiller {
 public:
  ProfileFiller(const geometry::ShowerDepth& depth, SelectionOptions selection, ProfileOptions profile = {},
                ParticleVisitor visit = {});
  /// Rows of whole events, the rows of an event contiguous; `source` names them (a file) in
  /// what checkSelected says.
  void addEvents(std::span<const ParticleRow> rows, std::string_view source = {});
  [[nodiscard]] const ProfileFill& fill() const { return fill_; }
  ProfileFill& fill() { return fill_; }
  /// Fails when an event's file has another beam energy than the selection's (--beam-energy:
  /// ProfileFill::beamEnergyMismatch), or when no event passed the selection (the message gives
  /// the cut flow).
  Status checkSelected() const;

 private:
  geometry::ShowerDepth depth_;
  SelectionOptions selection_;
  ParticleVisitor visit_;
  ProfileFill fill_;
};

/// Streams `files`, selects, fills the profiles. Fails on unreadable or malformed input and
/// when no event passes the selection.
Result<ProfileFill> fillProfiles(const std::vector<std::string>& files, const geometry::ShowerDepth& depth,
                                 const SelectionOptions& selection, const ProfileOptions& profile = {},
                                 const ParticleVisitor& visit = {});

/// As fillProfiles, from rows in memory (whole events, each event's rows together), checked
/// first by the rules of the event files (io::checkRowsInMemory; `source` names them).
Result<ProfileFill> fillProfilesOfRows(std::span<const ParticleRow> rows, const std::string& source,
                                       const geometry::ShowerDepth& depth, const SelectionOptions& selection,
                                       const ProfileOptions& profile = {}, const ParticleVisitor& visit = {});

/// The profiles of each run of a file (rows of one run contiguous or not), for a campaign
/// that groups runs: run → its fill. A run's residuals are built at the depth of the beam
/// energy of its first row (the selection's when it overrides the files'); an error of
/// `depthAt` names the run. With `events`, the event numbers of each run read (all events,
/// selected or not) are put there, to compare files read one by one.
Result<std::map<std::int32_t, ProfileFill>> fillProfilesByRun(
    const std::string& file, const geometry::DepthAtEnergy& depthAt, const SelectionOptions& selection,
    const ProfileOptions& profile = {}, std::map<std::int32_t, io::EventNumbers>* events = nullptr);

/// Describes the input of a fit in the result file.
// (bugprone-exception-escape takes the assertion in nlohmann::json's noexcept default
// constructor for a throw from FitInput().)
// NOLINTNEXTLINE(bugprone-exception-escape)
struct FitInput {
  std::vector<std::string> files;  ///< event files, or the profile file
  bool fromProfile = false;
  const ProfileFill* fill = nullptr;  ///< cut flow and counts when fitted from events
  std::string detector;               ///< "embedded default" or a path
  /// The model corrections of calib/corrections.hpp: the depth offset (cm) and where the
  /// parting-plane response came from (empty: none, the contract's hard hemisphere assignment).
  double depthOffset = 0.0;
  std::string partingPlane;
  std::string nominalProfile;  ///< where the subtracted nominal profile came from (empty: none)
  std::string response;        ///< where the fit's response R came from (empty: none)
  /// A corrections grid's interpolation to the sample's beam energy (null: none;
  /// calib/corrections_grid.hpp, CorrectionsAt::interpolation).
  io::Json correctionsInterpolation;
  /// The systematic errors the corrections carry (none: not measured): the result writes
  /// them as "systematic_errors" beside "errors", and in each derived entry.
  std::shared_ptr<const SystematicErrors> systematics;
  std::string systematicsSource;  ///< the corrections file or grid they came from
};

/// How σ_sys was chosen, as the result file says it: {"method": name(SigmaSysMethod) ("spec",
/// "fixed", "auto", or "saved profile": a saved profile's bins carry their total σ, value null),
/// "value_deg", "event_pair_correlations"} and, for auto, "interval_deg" [lower, upper] (68 %;
/// upper null when unbounded), "chi2_statistical_errors", "p_value_statistical_errors", "fits".
io::Json sigmaSysJson(const SigmaSysUsed& sigmaSys);

/// The fit-result file of docs/contract.md §3 (file units: deg, cm).
io::Json fitResultJson(const FitResult& result, const FitInput& input);

}  // namespace emcalign::calib
