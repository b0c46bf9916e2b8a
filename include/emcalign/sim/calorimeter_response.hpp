#pragma once
// The misaligned calorimeter of the simulation: where particles deposit energy.
//
// The simulation is deliberately richer than the fit model (docs/contract.md §5), because the paper's
// biases come from what the model leaves out:
// * Each hemisphere sits where the *truth* parameters put it (the docs/contract.md §4 transform);
//   layer 3 sits on support sphere 2 with the μ3 rule plus an independent small offset
//   that the fit model ignores, as the paper's does.
// * A shower is not a point: an electromagnetic shower is a set of energy spots with a
//   longitudinal Gamma profile dE/dt ∝ t^(a−1)·e^(−bt) (t in X0 from the shower start,
//   t_max = (a−1)/b = ln(E/Ec) + C, C = −0.5 for e±, +0.5 for γ, PDG), whose t_max
//   fluctuates event by event (log-normal, GFLASH width σ(ln t_max) = 1/(1.26·ln y − 1.4));
//   the shower starts in the material before the EMC (x_pre/sinθ X0, whose energy is lost),
//   and spreads laterally with a core and a tail in Molière radii (NaI: 4.13 cm).
// * Every spot is taken to the nominal frame through the inverse transform of the
//   hemisphere that physically contains it and added to the counter (docs/contract.md §2) containing
//   it; spots in the gap, in a support sphere, in a dead counter or beyond the EMC are lost.
// * Charged pions and muons leave ionisation (MIP, dE/dx of NaI) along their path; pions
//   may interact (λ_I of NaI) and leave a hadronic blob.
// * Per-shower energy resolution, per-counter noise and threshold, beam background hits.
// Every effect can be switched off (`EmcOptions`), and `pointShowers` +
// `showerFluctuations = false` put all energy at the model depth R(E, θ).

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "emcalign/core/event_record.hpp"
#include "emcalign/core/random.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/types.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/detector.hpp"

namespace emcalign::sim {

struct EmcOptions {
  // Shower shape
  double moliereRadius = 4.13;            ///< cm, NaI (PDG)
  double profileB = 0.5;                  ///< b of the Gamma profile (PDG, typical)
  double coreFraction = 0.75;             ///< lateral profile: fraction of energy in the core
  double coreRadius = 0.2;                ///< in Molière radii, f(r) ∝ r·R²/(r² + R²)² (assumed)
  double tailRadius = 0.8;                ///< in Molière radii (assumed; 88% inside 1 R_M)
  double maxRadius = 2.0;                 ///< in Molière radii: spots beyond are not made (the
                                          ///< ~4% of energy there is in the containment)
  double supportRadiationLength = 8.897;  ///< cm, X0 of the aluminium support spheres (PDG)
  int spotsLongitudinal = 8;              ///< depths drawn per shower
  int spotsLateral = 4;                   ///< spots per depth
  bool showerFluctuations = true;         ///< t_max fluctuates event by event
  /// Added to t_max = ln(E/Ec) + C, in X0 (0: PDG's C; a systematic variation moves it).
  double tMaxShift = 0.0;
  /// Scales the width σ(ln t_max) of the fluctuation (1: GFLASH's).
  double tMaxFluctuationScale = 1.0;
  /// The material before the EMC crossed by the simulated showers, X0 at normal incidence;
  /// none: the detector's (DetectorDescription::preshowerMaterial). The fit's R(E, θ) keeps
  /// the detector's: a value here is a difference between the simulation and the model.
  std::optional<double> preshowerMaterial;
  bool pointShowers = false;  ///< all energy in one spot at the model depth R(E, θ)

  // Energy response
  bool energyResolution = true;     ///< per-shower Gaussian smearing
  double resolutionAt1GeV = 0.042;  ///< σE/E = 4.2%/E(GeV)^¼ in all (SND design)
  double smearingShare = 0.85;      ///< share of it given by the smearing (the rest comes
                                    ///< from leakage and sampling; tuned, docs/simulation.md)
  bool noise = true;
  double noiseSigma = 0.3;        ///< MeV per counter (assumed)
  double counterThreshold = 2.0;  ///< MeV (assumed)
  /// Counter-to-counter gain non-uniformity: each counter's deposits scaled by a fixed gain
  /// 1 + σ·N(0, 1) drawn from Rng(gainSeed, counter) (0: uniform, the default).
  double counterGainSpread = 0.0;
  std::uint64_t gainSeed = 1;

  // Ionisation of charged hadrons and muons in NaI
  double mipDedx = 4.8;                    ///< MeV/cm (PDG: 1.305 MeV cm²/g × 3.667 g/cm³)
  double nuclearInteractionLength = 41.3;  ///< cm (PDG, NaI)

  // Imperfections
  bool deadCountersOn = true;
  std::vector<int> deadCounters = {51, 230, 377, 612, 845, 1002, 1290};  ///< assumed
  bool beamBackground = true;
  double backgroundHitsPerEvent = 0.3;  ///< Poisson mean (assumed)
  double backgroundMeanEnergy = 6.0;    ///< MeV, exponential (assumed)
  bool layer3OffsetOn = true;
  Vec3 layer3Offset{0.05, -0.04, 0.06};  ///< cm, independent shift of layer 3 (assumed)

  Status validate(int counters) const;
};

/// Where the hemispheres really are: the truth transform's four rigid placements, layer 3
/// with its own offset.
class ActualPlacement {
 public:
  ActualPlacement(const geometry::AlignmentTransform& truth, const Vec3& layer3Offset);
  [[nodiscard]] const geometry::RigidTransform& placement(geometry::Hemisphere h, geometry::Support s) const {
    return placements_[(h == geometry::Hemisphere::Plus ? 0 : 1) + (s == geometry::Support::Outer ? 2 : 0)];
  }

 private:
  geometry::RigidTransform placements_[4];
};

/// Energy deposited in the counters by one event, with who deposited it. Reused across
/// events (one per thread): only touched counters are reset.
class CounterHits {
 public:
  static constexpr int kMaxSources = 8;  ///< generated particles 0..6, background = 7
  static constexpr int kBackground = kMaxSources - 1;

  explicit CounterHits(int counters);
  void clear();
  /// Adds energy at a TS-frame point `where`, which is `nominal` in the counter's own frame.
  void add(int counter, int source, double energy, const Vec3& where, const Vec3& nominal);
  /// add's two halves: the counter's energy (and its share and moment), and the source's
  /// energy and Σ energy·where (`moment`), which a shower adds once for all its spots.
  void addToCounter(int counter, int source, double energy, const Vec3& nominal);
  void addToSource(int source, double energy, const Vec3& moment);
  /// Adds a counter's energy as a random-trigger event recorded it (source kBackground, at
  /// the counter's centre `centre`): a measured energy, which digitize neither scales by a
  /// gain nor gives noise (the record has the counter's noise). After every deposit.
  void addRecorded(int counter, double energy, const Vec3& centre);
  /// Noise and threshold; afterwards `fired()` lists counters above the threshold. `gains`
  /// (one per counter, or empty) scale each counter's deposits first; a counter with a
  /// recorded energy gets it added and no noise of its own.
  void digitize(const EmcOptions& o, std::span<const double> gains, Rng& rng);

  [[nodiscard]] double energy(int counter) const { return energy_[static_cast<std::size_t>(counter)]; }
  [[nodiscard]] const std::array<float, kMaxSources>& contributions(int counter) const {
    return contrib_[static_cast<std::size_t>(counter)];
  }
  [[nodiscard]] const std::vector<int>& fired() const { return fired_; }
  /// Σ energy·(nominal-frame position) of the deposits in a counter (idealised directions).
  [[nodiscard]] const Vec3& nominalMoment(int counter) const {
    return nominalMoment_[static_cast<std::size_t>(counter)];
  }
  /// Energy-weighted centre (TS frame) of what a source deposited; NaN if nothing.
  [[nodiscard]] Vec3 sourceCentre(int source) const;
  [[nodiscard]] double sourceEnergy(int source) const { return sourceEnergy_[static_cast<std::size_t>(source)]; }

 private:
  std::vector<double> energy_;
  std::vector<std::array<float, kMaxSources>> contrib_;
  std::vector<Vec3> nominalMoment_;
  std::vector<double> recorded_;           ///< addRecorded's energy per counter
  std::vector<std::uint8_t> hasRecorded_;  ///< whether a counter has one
  std::vector<int> touched_;
  std::vector<int> fired_;
  std::array<Vec3, kMaxSources> sourceSum_;
  std::array<double, kMaxSources> sourceEnergy_{};
};

/// Deposits particles' energy into `CounterHits` for one actual placement.
class CalorimeterResponse {
 public:
  CalorimeterResponse(const geometry::Calorimeter& calo, const geometry::AlignmentTransform& truth, EmcOptions options);
  [[nodiscard]] const EmcOptions& options() const { return options_; }
  [[nodiscard]] const geometry::Calorimeter& calorimeter() const { return *calo_; }
  [[nodiscard]] bool isDead(int counter) const { return dead_[static_cast<std::size_t>(counter)] != 0; }
  /// The counters' gains (EmcOptions::counterGainSpread), empty when uniform.
  [[nodiscard]] std::span<const double> gains() const { return gains_; }

  /// What showers: an e± or a γ (a γ's shower starts half a radiation length later).
  enum class Showering { Electron, Photon };
  /// What leaves a track: a muon, or a pion (which may interact in the crystals).
  enum class Tracking { Muon, Pion };

  /// An electromagnetic shower of an e± or γ along the line p + s·d.
  void shower(CounterHits& hits, int source, double energy, Showering particle, const Vec3& point,
              const Vec3& direction, Rng& rng) const;
  /// Ionisation (and, for pions, a possible nuclear interaction) along the line.
  void track(CounterHits& hits, int source, double kineticEnergy, Tracking particle, const Vec3& point,
             const Vec3& direction, Rng& rng) const;
  /// Beam-background hits in random counters (the Poisson model; EmcOptions::beamBackground).
  void background(CounterHits& hits, Rng& rng) const;
  /// A recorded random-trigger event's counters added to the event (instead of `background`;
  /// nothing when EmcOptions::beamBackground is off); those of dead counters are dropped.
  void mergeRecorded(CounterHits& hits, std::span<const Hit> recorded) const;

  /// Counter containing a TS-frame point of the actual detector, or -1 (gap, support
  /// sphere, dead counter, outside). `hint` is tried first (the hemisphere a shower entered).
  /// `nominal` receives the point in the counter's nominal frame.
  int counterAt(const Vec3& point, geometry::Hemisphere hint, Vec3* nominal = nullptr) const;

 private:
  // Where the line enters the EMC (actual inner surface) and through which hemisphere.
  double entry(const Vec3& point, const Vec3& direction, geometry::Hemisphere& hemisphere) const;
  void deposit(CounterHits& hits, int source, double energy, const Vec3& where, geometry::Hemisphere hint) const;
  [[nodiscard]] bool nearCoverage(const Vec3& point) const;

  // A shower spot: at `along` from the shower start on its axis, `radius` off it at the
  // azimuth (cosine, sine) about the axis.
  struct Spot {
    double along, radius, cosine, sine;
  };
  static constexpr std::size_t kSpotBatch = 32;
  // A shower's start, axis and two unit vectors across it, in one frame.
  struct Basis {
    Vec3 start, axis, e1, e2;
    [[nodiscard]] Vec3 at(const Spot& s) const {
      return (start + s.along * axis) + s.radius * (s.cosine * e1 + s.sine * e2);
    }
  };
  // The basis in the TS frame and in the nominal frames of the entered hemisphere's two
  // supports (the inner for layers 1–2, the outer for layer 3).
  struct ShowerFrame {
    Basis ts, inner, outer;
  };
  [[nodiscard]] ShowerFrame showerFrame(geometry::Hemisphere h, const Vec3& start, const Vec3& axis, const Vec3& e1,
                                        const Vec3& e2) const;
  // The counter of a point that `inner` places in hemisphere h's inner-support frame;
  // `outer()` places it in the frame of h's layer 3. None when the point is not on h's side
  // of the parting plane; −1 when it is, but in no live counter (counterAt's steps).
  template <typename OuterFrame>
  std::optional<int> counterOnSide(geometry::Hemisphere h, const Vec3& inner, OuterFrame outer, Vec3& nominal) const;
  // Adds each spot's energy to the counter containing it (counterAt, hint h).
  void depositSpots(CounterHits& hits, int source, double energy, const ShowerFrame& frame, geometry::Hemisphere h,
                    std::span<const Spot> spots) const;

  const geometry::Calorimeter* calo_;
  ActualPlacement actual_;
  EmcOptions options_;
  std::vector<std::uint8_t> dead_;
  std::vector<double> gains_;
  double r1Squared_ = 0.0;
  double coreCdfMax_ = 1.0, tailCdfMax_ = 1.0;  ///< F(r_max) of the lateral components
  double cosCoverageMin_ = 1.0, cosCoverageMax_ = -1.0;
  double lateralCos_ = 1.0, lateralSin_ = 0.0;  ///< the turn between lateral spots
};

}  // namespace emcalign::sim
