#pragma once
// The calibration of a period run by run (docs/campaign.md; the paper, section 5): the runs
// grouped until each group has enough selected e+e- → e+e- events for one calibration, each
// group fitted, and its result stored as one IOV of a conditions tag.
//
// 1. Scan: every file is read once (files in parallel); each run's selected events fill its
//    own profiles, and the file's SHA-256 is taken for the provenance.
// 2. Plan: consecutive runs of one beam energy are grouped until a group has min_events
//    selected events; a group left short joins the previous group of its energy (or the
//    next one); an energy point short as a whole stays one short group. The IOVs tile the
//    runs: a group's IOV runs from its first run to the run before the next group's first
//    (runs missing from the files are covered by the IOV around them).
// 3. Fit: each group's profile is the merge of its runs' (the same as filling it from all
//    their particles), fitted like `emcalign fit` (with the model corrections if given);
//    groups in parallel. Each result goes into the tag in its own transaction, so an
//    interrupted campaign keeps what it finished and a rerun skips the IOVs already there.
// The plan can be written as a job list and one group run from it (a batch system's array
// job against a shared PostgreSQL database).

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/sigma_sys.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/task_plan.hpp"

namespace emcalign::validation {

inline constexpr std::string_view kCampaignPlanFormat = "emcalign-campaign-plan/1";

/// One run as the scan found it.
struct CampaignRun {
  std::int32_t run = 0;
  double beamEnergy = 0.0;  ///< MeV (of its selected events; NaN when none was selected)
  std::int64_t selected = 0;
  std::vector<std::size_t> files;  ///< indices into the scan's files
  calib::ProfileFill fill;
};

struct CampaignScan {
  std::vector<std::string> files;
  std::vector<std::string> digests;  ///< SHA-256 of each file (empty when not taken)
  std::vector<CampaignRun> runs;     ///< by run number
  /// The files holding runs [first, last], in the order of `files`.
  [[nodiscard]] std::vector<std::string> filesOf(std::int64_t first, std::int64_t last) const;
  /// The mean beam energy of the selected events of runs [first, last] (MeV; NaN: none).
  [[nodiscard]] double meanBeamEnergy(std::int64_t first, std::int64_t last) const;
  /// The merged fill of runs [first, last] (profiles with `options`), and those runs.
  calib::ProfileFill fillOf(std::int64_t first, std::int64_t last, const calib::ProfileOptions& options,
                            std::vector<std::int32_t>* runsFound = nullptr) const;
};

/// How the events are turned into profiles and fitted: the fit's geometry and corrections.
/// With a corrections grid (a directory, calib/corrections_grid.hpp) the corrections depend
/// on the beam energy: every run is filled at the depth of its energy (depthAtEnergy) and
/// every group fitted with the corrections of its own (at).
struct CampaignModel {
  calib::FitGeometry geometry;    ///< with a grid: without corrections until at()
  calib::ProfileOptions profile;  ///< with the corrections' parting plane / nominal profile
  calib::SelectionOptions selection;
  std::string corrections;        ///< the corrections file or grid (empty: none), for the provenance
  std::string correctionsSha256;  ///< its SHA-256 (empty: none; a grid's: CorrectionsGrid::sha256)
  std::shared_ptr<const calib::CorrectionsGrid> grid;  ///< the corrections read (null: none)
  /// Set by at() with a grid: the interpolation (CorrectionsAt::interpolation), recorded in
  /// the fit result; and a single file's warning when used away from its energy.
  io::Json interpolation;
  std::string correctionsWarning;
  /// The systematic errors the corrections carry (a grid's interpolated by at()); none: none.
  std::shared_ptr<const calib::SystematicErrors> systematics;
  std::string detector = std::string(io::kEmbeddedDetector);
  calib::SigmaSysChoice sigmaSys;  ///< of every group's fit (calib/sigma_sys.hpp)
  /// Sets σ_sys (the profiles keep the event pairs whatever it is: the statistical errors
  /// every payload records take their correlation along).
  void setSigmaSys(const calib::SigmaSysChoice& choice) {
    sigmaSys = choice;
    profile.eventPairs = true;
  }
  /// The model of the events of one beam energy (MeV): a grid's corrections there (an energy
  /// outside the grid, or none, NaN, is an error), else this model.
  [[nodiscard]] Result<CampaignModel> at(double beamEnergy) const;
  /// The shower depth of the events of each beam energy (fillProfilesByRun).
  [[nodiscard]] geometry::DepthAtEnergy depthAtEnergy() const;
  /// Which model its fits use, with its σ_sys (calib/model_identity.hpp).
  [[nodiscard]] calib::ModelIdentity identity() const;
};

/// The event files of the inputs, as absolute paths (a batch job may run elsewhere): a
/// directory gives its *.h5, *.hdf5 and *.csv (sorted; none is an error), a file itself.
Result<std::vector<std::string>> eventFilesIn(const std::vector<std::string>& inputs);

/// The model of a campaign on this detector, with the corrections file if one is given
/// (empty: none).
Result<CampaignModel> campaignModel(const std::string& corrections, const std::string& detector,
                                    const geometry::Calorimeter& calo);

struct ScanOptions {
  int threads = 0;  ///< 0: all cores
  bool digests = true;
  std::function<void(std::size_t filesDone, std::size_t files)> progress;
};

/// Reads every file once. Files without any event, and a run with events of two beam
/// energies, are errors.
Result<CampaignScan> scanRuns(const std::vector<std::string>& files, const CampaignModel& model,
                              const ScanOptions& options);

struct CampaignGroup {
  int index = 0;
  std::int64_t iovFirst = 0, iovLast = 0;  ///< the IOV it is stored under (inclusive)
  std::vector<std::int32_t> runs;          ///< the runs whose events it holds
  std::vector<std::string> files;          ///< the files holding them
  double beamEnergy = 0.0;                 ///< MeV; NaN when the group has no selected event
  std::int64_t selected = 0;
  bool isShort = false;  ///< fewer than min_events selected events
};

/// Groups the scanned runs (see the top of this file).
std::vector<CampaignGroup> planGroups(const CampaignScan& scan, std::int64_t minEvents);

struct CampaignPlan {
  std::int64_t minEvents = 0;
  std::map<std::string, std::string> digests;  ///< file → SHA-256
  std::vector<CampaignGroup> groups;
  std::string corrections, correctionsSha256, detector;
  calib::SigmaSysChoice sigmaSys;  ///< the contract's when the plan does not say (plans made before)
  /// Where its groups are stored (the address without password) and how a new tag is
  /// described; empty: given to each group's job (campaign --plan P --group K --conditions …).
  std::string conditions, tag, description;
};
/// The campaign's part of a plan (Plan::data): the keys of planJson, plus "conditions", "tag"
/// and "description" when the plan was made with them.
Result<CampaignPlan> parseCampaignPlan(const io::Json& data, const std::string& path);
/// The campaign's part of a plan, written whole: {"format", "software", "min_events",
/// "corrections", "corrections_sha256", "detector", "sigma_sys": {"method", "value_deg"},
/// "inputs": [{"file", "sha256"}], "groups": [{"group", "iov": [first, last], "runs": [...],
/// "files": [...], "beam_energy_mev", "selected_events", "short"}]}, and "conditions", "tag"
/// and "description" when it has them (made with campaign_plan.hpp's makeCampaignPlan).
io::Json campaignPlanJson(const CampaignPlan& plan);
/// The model of a plan's fits on this detector: its corrections (the same file, by SHA-256) and σ_sys.
Result<CampaignModel> planModel(const CampaignPlan& plan, const geometry::Calorimeter& calo);
/// One group of a plan fitted and stored into `tag` of `uri` (a batch task): nothing when the
/// tag holds it from the same data already (groupStored); its files checked against the plan's
/// digests first; a copy of the same task storing it first is not an error. Returns what it
/// did, in words, and the warnings the one-process campaign gives of this group (a poor fit,
/// a fit outside the validated ranges, corrections used away from their energy).
struct StoredGroup {
  std::string said;
  std::vector<std::string> warnings;
};
Result<StoredGroup> storePlannedGroup(const CampaignPlan& plan, const CampaignModel& model, int group,
                                      const std::string& uri, const std::string& tag, const std::string& description);
/// The campaign as a plan's tasks (`campaign --plan` with --conditions and --tag): group K is
/// task K (storePlannedGroup into the plan's tag). `data`: the plan's part that parsePlan read;
/// `recordKey`: the database and tag when given to the task rather than by the plan
/// (PlannedJob::recordKey).
std::unique_ptr<PlannedJob> calibrationCampaignJob(CampaignPlan plan, CampaignModel model, io::Json data,
                                                   std::string recordKey = {});

/// The fill of one group of a plan (a batch job): its files read one by one (model: the
/// group's, CampaignModel::at), its runs kept. The files must be distinct and hold each event
/// once, and their selected events must have the plan's beam energy and count: an error names
/// the group (a plan edited by hand, or files changed since it was made).
Result<calib::ProfileFill> fillPlannedGroup(const CampaignGroup& group, const CampaignModel& model);

/// One group fitted: its result file (docs/contract.md §3) and the payload to store.
struct GroupFit {
  calib::FitResult result;
  io::Json resultJson;
  conddb::Payload payload;
};

/// Where a group's calibration comes from, for its provenance: {"campaign": {"group",
/// "groups", "min_events", "runs", "beam_energy_mev", "short"}}.
io::Json campaignOrigin(const CampaignGroup& group, std::int64_t minEvents, int groups);

/// Fits a group from the merged fills of its runs. The payload's provenance holds `origin`
/// (an object merged in), the input files' digests and the corrections.
Result<GroupFit> fitGroup(const CampaignGroup& group, const calib::ProfileFill& fill, const CampaignModel& model,
                          const std::map<std::string, std::string>& digests, const io::Json& origin);

struct CalibrationCampaignOptions {
  std::int64_t minEvents = 50000;
  int threads = 0;
  std::string description;  ///< of a new tag
  /// Called as groups finish: (done, to do, the group, its status or the reason it failed).
  std::function<void(int done, int total, const CampaignGroup& group, const std::string& status)> progress;
};

struct CampaignReport {
  int groups = 0, fitted = 0, resumed = 0;
  std::vector<std::string> failures;  ///< groups that could not be stored, in words
  std::vector<std::string> warnings;  ///< poor fits, short groups
};

/// What a campaign checks of its tag before any fit, in one place for the campaign and its
/// plan: not locked (nor retired), holding only this campaign's groups, each stored from this
/// data and model (groupStored). Returns which groups the tag holds already.
Result<std::vector<bool>> checkCampaignTag(const CampaignScan& scan, const CampaignModel& model, conddb::Database& db,
                                           const std::string& tag, const std::vector<CampaignGroup>& groups);

/// Plans the scanned runs, fits every group not yet in the tag and stores it. The tag's IOVs
/// must be a subset of the plan's (a rerun of the same campaign); anything else is refused
/// before any fit.
Result<CampaignReport> runCampaign(const CampaignScan& scan, const CampaignModel& model, conddb::Database& db,
                                   const std::string& tag, const CalibrationCampaignOptions& options);

/// Whether `tag` holds `group` made from the same data the same way: false when no IOV of the
/// tag holds its first run; true when the group's IOV is there, its payload records the
/// digests of the group's files (`digests`: file → SHA-256, compared by content whatever the
/// names now), and it was fitted with `model`'s corrections (by digest) and σ_sys choice; an
/// error naming the group otherwise (another IOV over its runs, the same runs from other
/// data or of unrecorded origin, other corrections or σ_sys). A campaign resuming a tag, and a
/// batch job finding its group stored, rely on it: one tag is one consistent calibration.
Result<bool> groupStored(conddb::Database& db, const std::string& tag, const CampaignGroup& group,
                         const std::map<std::string, std::string>& digests, const CampaignModel& model);

/// The IOVs of `groups` already in the tag, by group index; an IOV of the tag that is not
/// one of the groups' is an error (another plan was run into this tag).
Result<std::vector<bool>> groupsInTag(conddb::Database& db, const std::string& tag,
                                      const std::vector<CampaignGroup>& groups);

}  // namespace emcalign::validation
