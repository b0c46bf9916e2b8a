#pragma once
// The validation campaign (the paper's Table 1): many simulated samples with truths drawn
// evenly over the expected ranges, each fitted like data; the bias (mean of fit − truth),
// spread (standard deviation of fit − truth) and pulls of every parameter.
//
// Sample i draws its truth from Rng(seed, i) and simulates with the seed derived from
// (seed, i), so a sample is the same whatever else runs; a finished sample is stored as
// one JSON file and a rerun skips it (resumable).

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "emcalign/calib/corrections.hpp"
#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/sigma_sys.hpp"
#include "emcalign/core/random.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/sim/simulation.hpp"
#include "emcalign/validation/task_plan.hpp"

namespace emcalign::validation {

/// Uniform ranges of the physical parameters (native units). μ is drawn in
/// [mu.low, min(mu.high, asin(dx_rel/R1))] when `muBelowGapless`, so that no dp_k is negative.
struct Ranges {
  std::array<std::pair<double, double>, kNumParams> physical;  ///< indexed by Physical
  bool muBelowGapless = true;

  /// The defaults of the issue: α ∈ [0°, 5°], β ∈ [0°, 0.5°], ψ ∈ [0°, 180°),
  /// dx, dy, dz ∈ [−0.5, 0.5] cm, dx_rel ∈ [0, 0.5] cm, μ ∈ [0, asin(dx_rel/R1)],
  /// τ ∈ (−180°, 180°], dy_rel, dz_rel ∈ [−0.2, 0.2] cm, β_rel ∈ [−0.2°, 0.2°].
  static Ranges defaults();
  Status validate() const;
};

/// Reads a ranges file: {"format": "emcalign-validation-ranges/1", "ranges": {"alpha":
/// [lo, hi], …}} in deg and cm; missing names keep their default; "mu_below_gapless": bool.
Result<Ranges> readRanges(const std::string& path);

/// Draws one truth.
geometry::AlignmentParameters drawTruth(const Ranges& ranges, double r1, Rng& rng);

struct CampaignOptions {
  int samples = 100;
  std::int64_t events = 50000;
  std::uint64_t seed = 1;
  int threads = 0;
  Ranges ranges = Ranges::defaults();
  sim::SimulationOptions simulation;  ///< the seed is set per sample
  /// Draws a pattern of the detector per sample (a systematic variation's counter gains or
  /// dead counters, validation/variations.hpp): called on each sample's simulation options
  /// with the sample's simulation seed and the number of counters. None: the same detector
  /// in every sample.
  std::function<void(sim::SimulationOptions&, std::uint64_t seed, int counters)> samplePattern;
  /// Model corrections of the fits (calib/corrections.hpp): depth offset, parting-plane
  /// response, nominal profile; default none (the paper's model).
  calib::ModelCorrections corrections;
  /// σ_sys of the fits (calib/sigma_sys.hpp): the contract's 0.2°, a fixed value, or auto.
  calib::SigmaSysChoice sigmaSys;
  /// Describes the settings (simulation switches, ranges, detector): stored in every sample
  /// so that a rerun resumes only a campaign made with the same settings.
  io::Json settings = io::Json::object();
  /// Use the samples already in the directory only (the merge of a plan's tasks): a missing
  /// one is an error, never simulated.
  bool onlyFinished = false;
  Status validate() const;
};

/// How a campaign was asked for, as its samples record it (CampaignOptions::settings), so that
/// a rerun with other settings is refused instead of mixed in: the simulation's switches as
/// given, the polar range as given, the detector's name; the rest is read from the options.
struct CampaignRecord {
  bool ideal = false;
  std::vector<std::string> off{};  ///< realism switches turned off, as given
  bool pointShowers = false;
  double depthOffsetCm = 0.0;
  std::string correctionsFile{};  ///< empty: none (the digest comes from the options)
  double thetaMinDeg = 40.0, thetaMaxDeg = 140.0;
  std::string detector{};  ///< io::detectorName of the detector given
  /// Recorded only when given, so that campaign directories made before these resume.
  std::string sigmaSys{};      ///< as given ("", the contract's)
  double beamEnergyMev = 0.0;  ///< 0: the simulation's default
};

/// The settings every sample of `options` records (the truth's ranges and the corrections'
/// digest from `options`, the rest from `record`).
io::Json campaignSettings(const CampaignOptions& options, const CampaignRecord& record);

/// One finished sample.
struct SampleResult {
  int index = 0;
  geometry::AlignmentParameters truth;
  calib::FitResult fit;  ///< parameters, errors, derived, correlation, χ², status
  std::int64_t selectedEvents = 0;
};

/// The quantities the table reports: the 12 fit parameters and the derived μ, dx_rel, β, ψ
/// (τ is reported too, with the shortest angular difference).
struct TableRow {
  Quantity name;                                     ///< its unit: name.unit() (deg or cm)
  double bias = 0.0, spread = 0.0, biasError = 0.0;  ///< file units
  double pullMean = 0.0, pullWidth = 0.0;
  double pullWidthError = 0.0;  ///< width/√(2(n − 1)), its standard error for normal pulls
  /// Least-squares slope of (fit − truth) against truth, a scale error of the fit (NaN for
  /// ψ and τ, directions, and where the truth does not vary).
  double slope = 0.0, slopeError = 0.0;
  int samples = 0;
};

struct Table {
  int samples = 0;
  std::int64_t events = 0;
  std::vector<TableRow> rows = {};
  calib::Covariance meanCorrelation = calib::Covariance::Zero();
  /// The σ_sys of the fits, deg: their median, lowest and highest (one value unless auto).
  double sigmaSysMedian = 0.0, sigmaSysMin = 0.0, sigmaSysMax = 0.0;
};

/// Progress: samples done (including resumed ones), total.
using CampaignProgress = std::function<void(int done, int total)>;

/// Runs (or resumes) the campaign into `dir`: dir/samples/sample_NNN.json per sample,
/// then dir/table.json, dir/table.md and the figures dir/plots/{pulls,residuals_vs_truth}.png.
/// Returns the table.
/// `samples`, when given, receives the finished samples (as the table saw them).
Result<Table> runCampaign(const geometry::Calorimeter& calo, const CampaignOptions& options, const std::string& dir,
                          const CampaignProgress& progress = {}, std::vector<SampleResult>* samples = nullptr);

/// Sample i of the campaign into dir/samples/ (a plan's task): kept when it is there from the
/// same campaign, else simulated, fitted and written.
Status runSample(const geometry::Calorimeter& calo, const CampaignOptions& options, const std::string& dir, int i);
/// dir/samples/sample_NNNN.json
std::string sampleFile(const std::string& dir, int i);

/// The campaign as a plan's tasks (`validate --plan`): each task `samplesPerTask` samples
/// (runSample; 0: one, or more to keep within kMaxPlanTasks); the merge is runCampaign with
/// onlyFinished. `inputs`: the files the campaign reads, for the logs. Options the campaign
/// refuses are refused here (CampaignOptions::validate), before a plan is written.
/// Whether DIR's sample i is a finished sample of this campaign (what a rerun keeps).
bool isFinishedSample(const geometry::Calorimeter& calo, const CampaignOptions& o, const std::string& dir, int i);

/// What a campaign's plan checks before it is written (`validate --plan`), as the campaign does
/// when it runs: the options (validate, and the simulation's for this detector: validationJob
/// checks those too) and the samples already in DIR (each a finished sample of this campaign,
/// as a rerun would keep it; a task checks only its own).
Status checkPlannedCampaign(const geometry::Calorimeter& calo, const CampaignOptions& o, const std::string& dir);

Result<std::unique_ptr<PlannedJob>> validationJob(geometry::Calorimeter calo, CampaignOptions options, std::string dir,
                                                  std::vector<std::string> inputs, int samplesPerTask = 0);

/// The table from finished samples.
Table tabulate(const std::vector<SampleResult>& samples, std::int64_t events, double r1);

/// table.json: {"samples", "events", "parameters": {name: {"unit", "bias", "spread",
/// "bias_error", "pull_mean", "pull_width", "pull_width_error", "slope", "slope_error"}},
/// "sigma_sys_deg": {"median", "min", "max"}, "mean_correlation": {"order", "matrix"}}; NaN
/// written as null. The one writer and (below) the one reader of the file.
io::Json tableJson(const Table& table);
/// Reads table.json (`source` names it in messages): a key missing or of the wrong type, or a
/// parameter it does not know, refused naming the key. (A row's `samples` is not in the file: 0.)
Result<Table> parseTable(const io::Json& j, std::string_view source);
/// Markdown with the paper's Table 1 numbers in adjacent columns.
std::string tableMarkdown(const Table& table);
/// A row's slope as a table shows it: "+0.0123 ± 0.0045", "— (a direction)" for ψ and τ
/// (a direction has no scale), "— (the truth does not vary)" otherwise without one.
std::string slopeText(const TableRow& row);

}  // namespace emcalign::validation
