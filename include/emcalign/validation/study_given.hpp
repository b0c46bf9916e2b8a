#pragma once
// The campaign of `emcalign validate` and `systematics` as their command line gives it, made
// into the library's options here (what is refused, what is only said), and their tables as
// the commands print them (docs/validation.md, docs/systematics.md).

#include <cstdint>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/validation/campaign.hpp"
#include "emcalign/validation/systematics.hpp"

namespace emcalign::validation {

/// A study's campaign as given: its samples, their simulation and their fits. The defaults are
/// the library's (CampaignOptions), but for the polar range: the generator's covers the whole
/// calorimeter, the samples only the profiles'.
struct StudyGiven {
  int samples = CampaignOptions{}.samples;
  std::int64_t events = CampaignOptions{}.events;
  std::uint64_t seed = CampaignOptions{}.seed;
  int threads = CampaignOptions{}.threads;
  std::string ranges = {}, detector = {};
  double beamEnergyMev = 0.0;  ///< 0: the simulation's default
  double thetaMinDeg = 40.0, thetaMaxDeg = 140.0;
  bool ideal = false, pointShowers = false;
  std::vector<std::string> off = {};
  double depthOffsetCm = CampaignOptions{}.corrections.depthOffset / units::cm;
  std::string corrections = {};  ///< a file, or a grid directory (taken at the beam energy)
  std::string sigmaSys = {};     ///< as given: "auto", degrees, or "" (the contract's)
  std::string variation = {};    ///< a systematic variation of the simulation (variations.hpp)
};

/// The files a study reads (ranges, corrections, detector), absolute: for its tasks' logs.
std::vector<std::string> studyInputs(const StudyGiven& given);

/// The reverse study's derivations by default: a third of the shipped file's statistics (10⁶
/// events per sample, 100 response samples of 50 000), enough for shifts measured by pairing
/// (every derivation has the same seed).
DerivationOptions reverseStudyDerivation();

/// The campaign of `given`: the ranges read, the simulation's switches applied, the
/// corrections taken at the beam energy (a single file used away from its energy is said in
/// `warnings`), and the settings each sample records.
Result<CampaignOptions> studyCampaign(const StudyGiven& given, std::vector<std::string>& warnings);

/// What `systematics --write-corrections FILE` needs, before the study: one corrections file
/// (not a grid), an output outside the study's directory `output`, and a study of the
/// conditions the file was derived for, so that the errors it will carry are its own.
Status checkCorrectionsToWrite(const std::string& file, const std::string& output, const std::string& corrections,
                               const CampaignOptions& campaign);

/// `validate`'s table: bias, spread and pulls of each parameter, and the σ_sys of the fits;
/// then what was written into `output` in `seconds`.
std::string validationTableText(const Table& table, double seconds, const std::string& output);
/// `systematics`' table: each parameter's nominal bias, spread, systematic error and its
/// largest effect; then what was written into `output` (with the reverse study when `reverse`).
std::string systematicsTableText(const SystematicsTable& table, double seconds, const std::string& output,
                                 bool reverse);

/// The study of `campaign` with the variations named (none: all) and, when `reverse` is given,
/// the reverse study with those derivations (on the campaign's threads).
SystematicsOptions systematicsStudy(CampaignOptions campaign, const std::vector<std::string>& variations,
                                    const std::optional<DerivationOptions>& reverse);
/// `--write-corrections FILE`: the corrections file `corrections` with the systematic errors of
/// the study written to `file` ("-": standard output); returns what to say.
Result<std::string> writeCorrectionsWithSystematics(const SystematicsTable& table, const CampaignOptions& campaign,
                                                    const std::string& file, const std::string& corrections);

}  // namespace emcalign::validation
