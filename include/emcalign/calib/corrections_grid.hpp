#pragma once
// Model corrections across a beam-energy scan (docs/validation.md, "The beam-energy scan").
//
// A corrections file (calib/corrections.hpp) is derived at one beam energy: the shower is
// deeper and wider at higher energy, so the depth offset, the parting-plane shares W₊, the
// nominal profile and the fit's response all move with it. A grid is a directory of
// corrections files, one per beam energy (each says its "beam_energy_mev"; `emcalign
// derive-corrections --beam-energy E1,E2,… -o DIR` writes them). At a sample's beam energy E
// between two points E_a < E < E_b the corrections are interpolated linearly in E, every
// number of the two files alike:
//   c(E) = (1 − w)·c(E_a) + w·c(E_b),   w = (E − E_a)/(E_b − E_a),
// the depth offset, each W₊, each bin of the nominal profile (its σ interpolated alike: the
// two points' errors are taken as fully correlated, the larger of the two assumptions) and
// every element of the response. A nominal-profile bin missing at either point is missing
// between them (it is kept only at the point that has it). An energy outside
// [E_first, E_last] is refused: nothing is extrapolated.
//
// A single file is a grid of one point: it applies at any energy, as before the grid
// existed, with a warning when the sample is more than 1 % away from the energy the file
// says it was derived at.
//
// Every point of a grid must have the same pieces (a response in all or none) and, when the
// files record them, the same θ range, detector, realism switches and derivation samples
// (shift, gap): a grid mixing them would interpolate between different things.

#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "emcalign/calib/corrections.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::calib {

/// How far (relative) a sample's beam energy may lie from the energy its corrections are
/// for: a single file's own energy (a warning beyond), or the energy a grid was
/// interpolated to (a sample whose events spread wider is refused).
inline constexpr double kCorrectionsEnergyTolerance = 0.01;

struct CorrectionsPoint {
  std::string file;
  ModelCorrections corrections;  ///< with its beamEnergy (NaN only in a single file)
};

/// The corrections for one beam energy, and where they came from.
struct CorrectionsAt {
  ModelCorrections corrections = {};
  std::string path = {};    ///< the file or the grid's directory
  double beamEnergy = 0.0;  ///< MeV, the energy they were asked for
  /// Null for a single file; for a grid {"directory", "beam_energy_mev", "points": [{"file",
  /// "beam_energy_mev", "weight"}]} (one point when E is a grid point, else the two around it).
  io::Json interpolation = {};
  std::string warning = {};  ///< a single file used away from its own energy (empty: none)
  std::string sha256 = {};   ///< of the file or the grid's listing (CorrectionsGrid::sha256)
};

/// What a profile filled with `c` says of them, in its first line ("# filled with the
/// corrections sha256 <hex> (PATH)", a grid's " at <E> MeV" after the digest): a fit of the
/// saved profile must take the same (checkFilledWith).
std::string filledWithLine(const CorrectionsAt& c);
/// A saved profile's text against the corrections `c` a fit of it is given: refused, naming
/// both, when its first line says others (a digest or a grid's energy); a profile that says
/// none (written before it did) is taken.
Status checkFilledWith(const std::string& profileText, const std::string& profilePath, const CorrectionsAt& c);

/// A grid's interpolation (CorrectionsAt::interpolation, a fit result's
/// "model_corrections.interpolation") in words: "612.5 MeV (500 MeV × 0.550, 750 MeV × 0.450)";
/// empty for null (a single file).
std::string interpolationText(const io::Json& interpolation);

class CorrectionsGrid {
 public:
  /// A corrections file, or a directory of them (its *.json files; at least two, each with
  /// beam_energy_mev, no energy twice). The error names the file and what is wrong.
  static Result<CorrectionsGrid> read(const std::string& path);
  /// A grid of these points (sorted here), for tests and programs that derive them; one
  /// point without an energy is a single file.
  static Result<CorrectionsGrid> of(std::vector<CorrectionsPoint> points, std::string path);

  [[nodiscard]] const std::string& path() const { return path_; }
  /// The SHA-256 of the file, or of a directory's listing "<sha256>  <name>\n" per file
  /// in name order (sha256sum's format), for the provenance.
  [[nodiscard]] const std::string& sha256() const { return sha256_; }
  /// Whether it interpolates (a directory), rather than being one file for every energy.
  [[nodiscard]] bool isGrid() const { return grid_; }
  [[nodiscard]] const std::vector<CorrectionsPoint>& points() const { return points_; }

  /// The corrections at `beamEnergy` (MeV). A grid fails outside its energies.
  [[nodiscard]] Result<CorrectionsAt> at(double beamEnergy) const;
  /// Only their depth offset (cm), at the cost of one interpolation: for every run or event.
  [[nodiscard]] Result<double> depthOffsetAt(double beamEnergy) const;

 private:
  /// The index k of the grid point above `beamEnergy` and its weight w (the one below,
  /// k − 1, has 1 − w); an error outside the grid.
  [[nodiscard]] Result<std::pair<std::size_t, double>> around(double beamEnergy) const;
  std::string path_, sha256_;
  bool grid_ = false;
  std::vector<CorrectionsPoint> points_;  ///< by beam energy
};

/// The file name of a grid's point: "ee-<E>MeV.json" (derive-corrections writes them so).
std::string gridPointName(double beamEnergy);

/// `depth` with the grid's depth offset at each beam energy (a single file's at every one).
geometry::DepthAtEnergy depthAtEnergy(std::shared_ptr<const CorrectionsGrid> grid, const geometry::ShowerDepth& depth);

/// The corrections of a sample of event files: a grid's at `beamEnergy` (MeV) when given
/// (the selection's override), else at the beam energy of the files' first event; a single
/// file's as they are (no event read: checkSampleEnergies looks at them all after the fill).
Result<CorrectionsAt> correctionsForSample(const CorrectionsGrid& grid, const std::vector<std::string>& files,
                                           std::optional<double> beamEnergy);
/// The selected events' beam energies (MeV) against the corrections they were filled with:
/// a grid's, interpolated to one energy, refuse events more than
/// kCorrectionsEnergyTolerance away (a sample of several energies is fitted energy by
/// energy, or by `emcalign campaign`); a single file's return a warning for events that far
/// from its own energy (empty: none).
Result<std::string> checkSampleEnergies(const CorrectionsAt& corrections, const std::set<double>& energies);

/// (1 − w)·a + w·b of every number of two corrections with the same pieces (w in [0, 1]);
/// the result's beamEnergy is interpolated alike and derivedFrom is left empty.
Result<ModelCorrections> interpolateCorrections(const ModelCorrections& a, const ModelCorrections& b, double w);

/// The SHA-256 of a corrections path as CorrectionsGrid::sha256 gives it, without
/// parsing the files (a campaign job checking that its corrections are the plan's).
Result<std::string> correctionsDigest(const std::string& path);

}  // namespace emcalign::calib
