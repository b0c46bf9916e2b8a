#pragma once
// The systematic study (docs/systematics.md): a validation campaign of the nominal
// simulation and one of each variation (validation/variations.hpp), with the same seed, all
// fitted with the same model corrections. Sample i of every campaign has the same truth and
// the same random streams, so the difference of its fits is the variation's effect on it;
// the mean of those differences (its error: their spread/√n) is how far the variation moves
// each parameter's bias — measured with a fraction of the statistical spread of the fits.
//
// A variation's effect is |shift|; for a pattern drawn anew in every sample (counter gains,
// dead counters) it is the root mean square of the samples' differences, √(shift² + spread²):
// data have one pattern, of unknown sign. A quantity's effect is the larger of its variations
// (the envelope of the pair); the systematic error of a parameter is the quadrature sum of its
// quantities' effects. An effect is counted as measured, without subtracting its own
// statistical error (conservative; the table shows each error beside it).
//
// The reverse study (optional) derives the corrections in the simulation with each variation
// and without (DIR/reverse/corrections/<name>.json, `derive-corrections` at the statistics
// given, the same seed for all), and fits the nominal campaign's samples with each
// (DIR/reverse/<name>, DIR/reverse/nominal): a variation's reverse shift is the mean of
// fit(its corrections) − fit(the nominal ones), sample by sample. A pattern variation derives
// with one pattern (the derivation's seed). A quantity's effect is then the largest of its
// variations' effects, forward and reverse.
//
// The campaigns live in DIR/nominal and DIR/<variation>, each resumable as `validate`'s;
// DIR/systematics.json and DIR/systematics.md hold the table, DIR/plots/systematics.png the
// shifts. A study needs 2 samples at least.

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/calib/corrections.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/campaign.hpp"
#include "emcalign/validation/derive_corrections.hpp"
#include "emcalign/validation/variations.hpp"

namespace emcalign::validation {

struct SystematicsOptions {
  /// The nominal campaign: samples, events, seed, ranges, simulation, corrections, settings.
  CampaignOptions campaign;
  /// The variations to run (validation::variations() order); empty: all of them.
  std::vector<const Variation*> variations;
  /// The reverse study, when given: the derivations' statistics and seed (their simulation,
  /// beam energy and response ranges are the campaign's).
  std::optional<DerivationOptions> reverse;

  /// What a study needs (2 samples at least, valid campaign and reverse options): checked by
  /// runSystematics and by systematicsJob alike, so a plan is refused where the command is.
  [[nodiscard]] Status validate() const;
};

/// The campaign with a variation: its simulation changed, and the variation recorded in the
/// settings of every sample (so that a directory of another campaign is refused).
CampaignOptions withVariation(CampaignOptions options, const Variation& variation);

/// One parameter (the 12 and the derived, as the validation table names them).
struct SystematicsRow {
  Quantity name;                ///< its unit: name.unit() (deg or cm)
  double bias = 0.0;            ///< nominal campaign: mean of fit − truth (file units)
  double biasError = 0.0;       ///< its statistical error
  double spread = 0.0;          ///< nominal campaign: the fits' spread about the truth
  std::vector<double> shift{};  ///< per variation: mean of fit(variation) − fit(nominal)
  std::vector<double> shiftError{};
  std::vector<double> shiftSpread{};  ///< per variation: the spread of fit(variation) − fit(nominal)
  std::vector<double> effect{};       ///< per variation: |shift|, or √(shift² + spread²) for a pattern
  /// The reverse study (empty when not run): the nominal samples fitted with the corrections
  /// derived without variation (bias and its error), and per variation the mean of
  /// fit(its corrections) − fit(the nominal ones) with its error.
  double reverseBias = 0.0, reverseBiasError = 0.0;
  std::vector<double> reverseShift{}, reverseShiftError{};
  std::vector<double> envelope{};  ///< per quantity: the largest effect of its variations (and reverse shifts)
  double systematic = 0.0;         ///< quadrature sum of the envelopes
};

// clang-tidy cannot prove the destructor of its io::Json member non-throwing (nlohmann::json
// asserts its invariant there); it does not throw.
// NOLINTNEXTLINE(bugprone-exception-escape)
struct SystematicsTable {
  int samples = 0;
  std::int64_t events = 0;
  std::vector<const Variation*> variations;
  std::vector<std::string> quantities;  ///< in the order of first appearance
  std::vector<SystematicsRow> rows;
  /// The reverse study's derivations (settings as their files record them); null: not run.
  io::Json reverse = nullptr;
};

/// What the campaigns of a study measured, before they are combined: the nominal campaign's
/// table, per variation the table of its samples paired with the nominal ones (each row's
/// bias is the shift, its spread the spread of the differences), and with the reverse study
/// the nominal samples fitted with the corrections derived without variation and, per
/// variation, those fitted with its corrections paired with them.
struct SystematicShifts {
  Table nominal;
  std::vector<Table> shifts;
  std::optional<Table> reverseNominal;  ///< none: no reverse study
  std::vector<Table> reverseShifts;
};

/// The combination of the header's rules, the numbers users quote: per parameter of the
/// nominal table each variation's effect (|shift|, or √(shift² + spread²) for a pattern),
/// each quantity's envelope (the largest effect of its variations and their reverse shifts;
/// a NaN stays NaN), the systematic error (their quadrature sum). `quantities` lists every
/// variation's quantity; the tables must have the nominal table's parameters, one per variation.
Result<std::vector<SystematicsRow>> combineSystematics(const std::vector<const Variation*>& variations,
                                                       const std::vector<std::string>& quantities,
                                                       const SystematicShifts& measured);

/// Called with the events simulated over all campaigns and derivations, and their total.
using SystematicsProgress = std::function<void(std::int64_t done, std::int64_t total)>;

/// Runs (or resumes) the campaigns into `dir` and writes the table.
Result<SystematicsTable> runSystematics(const geometry::Calorimeter& calo, const SystematicsOptions& options,
                                        const std::string& dir, const SystematicsProgress& progress = {});

/// The study as a plan's tasks (`systematics --plan`): each sample of each campaign, and with
/// the reverse study each derivation and each sample of its campaign; the merge is
/// runSystematics with campaign.onlyFinished. `inputs`: the files it reads, for the logs;
/// `samplesPerTask`: as validationJob's (0: one, or more to keep within kMaxPlanTasks). Options
/// runSystematics refuses are refused here (SystematicsOptions::validate).
/// What a study's plan checks before it is written (`systematics --plan`): the options, and each
/// forward campaign as checkPlannedCampaign checks it.
Status checkPlannedSystematics(const geometry::Calorimeter& calo, const SystematicsOptions& options,
                               const std::string& dir);

Result<std::unique_ptr<PlannedJob>> systematicsJob(geometry::Calorimeter calo, SystematicsOptions options,
                                                   std::string dir, std::vector<std::string> inputs,
                                                   int samplesPerTask = 0);

/// {"samples", "events", "variations": [{"name", "quantity", "change", "why", "pattern"}],
/// "reverse": {derivation settings} or null, "parameters": {name: {"unit", "bias",
/// "bias_error", "spread", "shifts": {variation: [shift, error, spread of the differences]},
/// "effects": {variation: value}, "reverse_bias": [bias, error], "reverse_shifts":
/// {variation: [shift, error]}, "envelopes": {quantity: value}, "systematic"}}} (the
/// reverse keys only with the reverse study).
io::Json systematicsJson(const SystematicsTable& table);
/// The table in Markdown: per parameter the nominal bias and spread, each quantity's
/// envelope and the total, and the paper's Table 1 bias beside it.
std::string systematicsMarkdown(const SystematicsTable& table);

/// The "systematic_errors" block of `corrections` (calib::SystematicErrors), the file the
/// study was run with: per parameter of the table but ψ and τ its systematic error in quadrature with
/// the statistical errors of the derivation the file records (response, nominal profile:
/// common to every fit with the file; recorded for the 12 fit parameters only, so β, μ and
/// dx_rel have the variations' part alone), each part under "components"; `study` says how.
io::Json systematicErrorsJson(const SystematicsTable& table, const calib::ModelCorrections& corrections,
                              const io::Json& study);

/// How combineSystematics and systematicErrorsJson combine, in words: the "combination" a
/// corrections file's study records.
inline constexpr std::string_view kSystematicsCombination =
    "per parameter the quadrature sum over the varied quantities of the largest effect of each (a pattern's "
    "root mean square; the reverse shifts included), in quadrature with the derivation's statistical errors";

/// The corrections the study fitted with (`campaign.corrections`, one file's) carrying its
/// systematic errors (calib::SystematicErrors): what `systematics --write-corrections` writes
/// (to `destination`, for the messages), and `fit --corrections` then reports beside the
/// statistical errors. The record of the study: the command, samples, events, seed, its
/// conditions (the campaign's settings but its corrections, and the beam energy), the
/// variations, the reverse study, kSystematicsCombination and the corrections' digest.
/// Whether a study measures the systematic errors its corrections (`campaign.corrections`, the
/// file `name`) may carry: the realistic simulation (no "ideal", "point_showers" or "off" in the
/// campaign's settings), the beam energy the file was derived at, and the polar range its
/// derivation recorded. The error says which differs and what to give.
Status studyMatchesItsCorrections(const CampaignOptions& campaign, const std::string& name);

Result<calib::ModelCorrections> correctionsWithSystematics(const SystematicsTable& table,
                                                           const CampaignOptions& campaign,
                                                           const std::string& destination);

}  // namespace emcalign::validation
