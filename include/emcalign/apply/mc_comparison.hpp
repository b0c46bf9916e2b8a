#pragma once
// Data against simulation, as the paper judges its simulation (Fig. 6 of the paper: the Δφ
// and Δθ of uncorrected data and of the realistic MC with the measured alignment): the
// residual distributions of the selected e+e- → e+e- particles and the 16×10 profiles of
// docs/contract.md §7 (ȳ_φ, ȳ_θ per bin), each compared by a χ² of their difference (docs/apply.md,
// "MC against data").
//
// The statistics. Every quantity compared is a ratio of sums over events — a histogram
// bin's fraction of the particles, a profile bin's mean — so its error, and the covariance
// between any two of them, is that of the events' influences (the delta method):
//   fraction f_i = n_i / N:   influence of event e = (c_ei − k_e·f_i) / N
//   bin mean m_b = S_b / n_b: influence of event e = (s_eb − c_eb·m_b) / n_b
// (c_ei: the event's particles in bin i, k_e: its particles in the histogram, s_eb: the sum
// of their residuals in bin b), and Cov = Σ_e infl_e·infl_eᵀ. This keeps what independent
// bins would lose: the two particles of an event are back to back and their residuals
// correlate (+0.55 in y_φ), y_φ and y_θ of one bin correlate, and a histogram's fractions
// sum to 1. Data and MC are independent: the difference d = data − MC has Cov_data + Cov_MC,
// so the MC's own statistical error is counted. χ² = dᵀ·Cov⁺·d over the covariance's rank
// (a histogram loses one degree of freedom to its normalisation), each distribution alone
// and all four together (their correlations included). With `sigmaSys`, σ_sys² is added
// once to each profile mean's variance.
// Small bins. A histogram's bins are merged from each tail inwards until every bin has at
// least `minEntries` particles in each sample; a profile bin is compared when both samples
// have `minEntries` particles in it (docs/contract.md §7's rule). For a simulation that is the data's
// twin, the p-values are uniform (unit test McComparison.PValuesOfTwinSamplesAreUniform;
// docs/apply.md shows it on simulated pairs).

#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/calib/profiles.hpp"
#include "emcalign/calib/selection.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::apply {

/// One selected particle inside the profiles' θ range, as the comparison sees it.
struct ComparedParticle {
  std::int64_t event = 0;           ///< the particles of one event are consecutive
  double dPhiDeg = 0.0;             ///< asin(y_φ) in degrees
  double dThetaDeg = 0.0;           ///< y_θ in degrees
  int bin = -1;                     ///< profile bin (i_phi-major), −1 outside the profiles
  double yPhi = 0.0, yTheta = 0.0;  ///< rad
};

struct ComparisonOptions {
  int histogramBins = 48;  ///< over centre ± rangeDeg, before merging small tails
  double rangeDeg = 6.0;   ///< Δφ and Δθ; beyond, a particle counts in the last bin
  /// The histograms' centres, deg; NaN (the default): the data's mean, to 0.25° (uncorrected
  /// data sit ~3° off in Δφ). The Comparison's options hold the centres used.
  double phiCentreDeg = std::numeric_limits<double>::quiet_NaN();
  double thetaCentreDeg = std::numeric_limits<double>::quiet_NaN();
  int profilePhiBins = 16, profileThetaBins = 10;
  std::int64_t minEntries = 10;  ///< per sample, in a histogram bin (after merging) and a profile bin
  double sigmaSys = 0.0;         ///< rad, added (squared) once to each profile mean's variance
};

/// One distribution compared: the bins as drawn and the χ² of the difference.
struct ComparedDistribution {
  std::string name;  ///< dphi, dtheta, profile_phi, profile_theta
  double chi2 = 0.0;
  int ndf = 0;
  double pValue = 1.0;
  /// Per bin: the data's and the MC's value (a fraction of the particles, or a profile mean
  /// in degrees), their errors, and the pull (data − MC)/σ of the difference. Histograms:
  /// `low`, `high` the (merged) bin's edges in degrees; profiles: `low` the bin index, `high`
  /// the same. Bins left out (too few entries) are not listed.
  struct Bin {
    double low = 0.0, high = 0.0;
    double data = 0.0, dataError = 0.0, mc = 0.0, mcError = 0.0, pull = 0.0;
  };
  std::vector<Bin> bins = {};
};

struct Comparison {
  std::int64_t dataParticles = 0, mcParticles = 0;
  std::int64_t dataEvents = 0, mcEvents = 0;
  /// Each sample's selected events and their beam energies (MeV, distinct, ascending), where
  /// known (compareSamples; empty for particles compared as they are).
  std::int64_t dataSelectedEvents = 0, mcSelectedEvents = 0;
  std::vector<double> dataBeamEnergiesMev = {}, mcBeamEnergiesMev = {};
  /// The θ slices of the profiles in which no bin had minEntries in both samples (not drawn).
  std::vector<int> emptyThetaSlices = {};
  /// The particles of each sample in those slices: which sample is thin there.
  std::int64_t dataParticlesInEmptySlices = 0, mcParticlesInEmptySlices = 0;
  std::vector<ComparedDistribution> distributions = {};  ///< dphi, dtheta, profile_phi, profile_theta
  double chi2 = 0.0;                                     ///< all together (their correlations kept)
  int ndf = 0;
  double pValue = 1.0;
  ComparisonOptions options = {};
};

/// Compares two samples of particles (each an event's particles consecutive). Fails when a
/// sample has fewer than 2·minEntries particles, or no bin can be compared.
Result<Comparison> compareParticles(const std::vector<ComparedParticle>& data, const std::vector<ComparedParticle>& mc,
                                    const ComparisonOptions& options = {});

/// A sample as the comparison sees it: its particles and what it is.
struct ComparedSample {
  std::vector<ComparedParticle> particles;
  std::int64_t selectedEvents = 0;
  std::vector<double> beamEnergiesMev;  ///< of its selected events, distinct, ascending
};

/// The particles of event files, selected as the fit selects them (calib/selection.hpp),
/// with their residuals at the shower depth `depth`; events are told apart by (run, event).
Result<ComparedSample> comparedSampleOf(const std::vector<std::string>& files, const geometry::ShowerDepth& depth,
                                        const calib::SelectionOptions& selection,
                                        const ComparisonOptions& options = {});

/// As comparedSampleOf, from rows in memory (checked as a file's rows; `source` names them).
Result<ComparedSample> comparedSampleOfRows(std::span<const ParticleRow> rows, const std::string& source,
                                            const geometry::ShowerDepth& depth,
                                            const calib::SelectionOptions& selection,
                                            const ComparisonOptions& options = {});

/// Two beam energies are the same point when they differ by at most this share of them: about
/// 2.5 times VEPP-2000's energy spread (≈ 4·10⁻⁴), well below its scan steps (≥ 12.5 MeV).
inline constexpr double kSameBeamEnergy = 1e-3;

/// Whether two samples can be compared: every beam energy of each within kSameBeamEnergy of
/// one of the other's. The residuals depend on the energy (the shower depth, the radiation),
/// so data and MC of different energies differ whatever the simulation: refused, naming both
/// samples' energies.
Status checkCombinable(const ComparedSample& data, const ComparedSample& mc);

/// compareParticles of two samples found combinable, recording what each is.
Result<Comparison> compareSamples(const ComparedSample& data, const ComparedSample& mc,
                                  const ComparisonOptions& options = {});

inline constexpr std::string_view kComparisonFormat = "emcalign-compare/1";

/// A comparison as compare.json records it: the result and where it came from.
struct ComparisonRecord {
  Comparison comparison;
  std::vector<std::string> dataFiles = {}, mcFiles = {};  ///< empty: not recorded (rows in memory)
  std::string software = {};                              ///< empty: not recorded
  std::optional<double> depthOffsetCm = {};               ///< the shower depth's offset, cm
};

/// compare.json (docs/contract.md §12): {"format", "p_value", "chi2", "ndf", "distributions": [{"name",
/// "chi2", "ndf", "p_value", "unit", "bins": [...]}], "data", "mc" ({"events", "particles",
/// "selected_events", "beam_energies_mev", "files"}), "empty_theta_slices", "options", "method",
/// "software", "depth_offset_cm"}; what is not recorded is not written. The one writer and
/// (below) the one reader of the file.
io::Json comparisonJson(const ComparisonRecord& record);
inline io::Json comparisonJson(const Comparison& c) { return comparisonJson(ComparisonRecord{c}); }
/// Reads compare.json (`source` names it in messages): not a comparison, or a value of the
/// wrong type, refused naming the key.
Result<ComparisonRecord> parseComparison(const io::Json& j, std::string_view source);
/// compare.md: the verdict and a table per distribution.
/// What the empty θ slices of `c` say, for a warning: how many, and which sample is thin there
/// (a small sample, or one simulated or selected over a narrower θ range); empty when none.
std::string emptySlicesText(const Comparison& c);

std::string comparisonMarkdown(const Comparison& c, const std::vector<std::string>& dataFiles,
                               const std::vector<std::string>& mcFiles, const std::string& depth = "");

}  // namespace emcalign::apply
