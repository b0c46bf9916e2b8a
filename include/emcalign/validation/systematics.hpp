#pragma once
// The systematic study (docs/systematics.md): a validation campaign of the nominal
// simulation and one of each variation (validation/variations.hpp), with the same seed, all
// fitted with the same model corrections. Sample i of every campaign has the same truth and
// the same random streams, so the difference of its fits is the variation's effect on it;
// the mean of those differences (its error: their spread/√n) is how far the variation moves
// each parameter's bias — measured with a fraction of the statistical spread of the fits.
//
// A quantity's shift is the larger |shift| of its variations (the envelope of the pair); the
// systematic error of a parameter is the quadrature sum of its quantities' shifts. A shift
// is counted as measured, without subtracting its own statistical error (conservative; the
// table shows each error beside it).
//
// The campaigns live in DIR/nominal and DIR/<variation>, each resumable as `validate`'s;
// DIR/systematics.json and DIR/systematics.md hold the table.

#include <functional>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/campaign.hpp"
#include "emcalign/validation/variations.hpp"

namespace emcalign::validation {

struct SystematicsOptions {
  /// The nominal campaign: samples, events, seed, ranges, simulation, corrections, settings.
  CampaignOptions campaign;
  /// The variations to run (validation::variations() order); empty: all of them.
  std::vector<const Variation*> variations;
};

/// The campaign with a variation: its simulation changed, and the variation recorded in the
/// settings of every sample (so that a directory of another campaign is refused).
CampaignOptions withVariation(CampaignOptions options, const Variation& variation);

/// One parameter (the 12 and the derived, as the validation table names them).
struct SystematicsRow {
  std::string name;
  std::string unit;           ///< "deg" or "cm"
  double bias = 0.0;          ///< nominal campaign: mean of fit − truth (file units)
  double biasError = 0.0;     ///< its statistical error
  double spread = 0.0;        ///< nominal campaign: the fits' spread about the truth
  std::vector<double> shift;  ///< per variation: mean of fit(variation) − fit(nominal)
  std::vector<double> shiftError;
  std::vector<double> envelope;  ///< per quantity: the largest |shift| of its variations
  double systematic = 0.0;       ///< quadrature sum of the envelopes
};

struct SystematicsTable {
  int samples = 0;
  std::int64_t events = 0;
  std::vector<const Variation*> variations;
  std::vector<std::string> quantities;  ///< in the order of first appearance
  std::vector<SystematicsRow> rows;
};

/// Called with the samples done over all campaigns and their total.
using SystematicsProgress = std::function<void(int done, int total)>;

/// Runs (or resumes) the campaigns into `dir` and writes the table.
Result<SystematicsTable> runSystematics(const geometry::Calorimeter& calo, const SystematicsOptions& options,
                                        const std::string& dir, const SystematicsProgress& progress = {});

/// {"samples", "events", "variations": [{"name", "quantity", "change", "why"}], "parameters":
/// {name: {"unit", "bias", "bias_error", "spread", "shifts": {variation: [shift, error]},
/// "envelopes": {quantity: value}, "systematic"}}}.
io::Json systematicsJson(const SystematicsTable& table);
/// The table in Markdown: per parameter the nominal bias and spread, each quantity's
/// envelope and the total, and the paper's Table 1 bias beside it.
std::string systematicsMarkdown(const SystematicsTable& table);

}  // namespace emcalign::validation
