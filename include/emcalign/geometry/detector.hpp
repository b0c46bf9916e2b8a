#pragma once
// Detector description of the calorimeter (docs/contract.md §2) and the table of its counters.
//
// The EMC is three spherical layers of NaI(Tl) counters around the TS centre, covering
// θ ∈ [18°, 162°] in 16 rings of 9°. Rings inside 36°–144° have 40 counters (Δφ = 9°),
// the four outer rings 16 (Δφ = 22.5°); φ cell edges start at φ = 0, so the parting plane
// x = 0 (φ = 90°, 270°) is always a cell boundary and every counter belongs to exactly one
// hemisphere. Layers 1–2 are held by support sphere 1 (outer radius R1), layer 3 by support
// sphere 2 (outer radius R_p3). Radii other than the documented totals are assumptions
// (docs/conventions.md); they live in `DetectorDescription`, overridable by a JSON file.
//
// Numbering (docs/contract.md §2): layer 1..3, ring 0..15 counted from θ = 18°, iphi 0.. counted from
// φ = 0 upward, index = 544·(layer−1) + (counters in the lower rings of the layer) + iphi.
// A counter's nominal centre is at its θ, φ mid-angles and its layer's mid-radius.

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/core/types.hpp"

namespace emcalign::geometry {

/// The two EMC halves, split by the vertical plane x = 0 (they move apart along X).
/// The value is the sign s of docs/contract.md §4.
enum class Hemisphere : int { Minus = -1, Plus = +1 };

inline constexpr int sign(Hemisphere h) { return static_cast<int>(h); }

/// Hemisphere of a nominal-frame point: x ≥ 0 belongs to s = +1 (docs/contract.md §4, §5).
inline Hemisphere hemisphereOf(double x) { return x >= 0.0 ? Hemisphere::Plus : Hemisphere::Minus; }

/// Which support sphere a layer hangs on: its outer radius enters the transform
/// (R1 for dp_k, R_p3 for the layer-3 μ3 rule of docs/contract.md §4).
enum class Support { Inner, Outer };

inline constexpr Support supportOfLayer(int layer) { return layer == 3 ? Support::Outer : Support::Inner; }

struct SphericalShell {
  double rInner = 0.0;  ///< cm
  double rOuter = 0.0;  ///< cm
  [[nodiscard]] double rMid() const { return 0.5 * (rInner + rOuter); }
  [[nodiscard]] bool contains(double r) const { return r >= rInner && r < rOuter; }
};

/// Material constants of the shower-depth formula R(E, θ) (docs/contract.md §5, from the paper).
struct ShowerMaterial {
  double radiationLength = 2.56;    ///< X0 of NaI, cm
  double criticalEnergy = 13.16;    ///< Ec of NaI, MeV
  double preshowerMaterial = 0.13;  ///< x_pre, material before the EMC at normal incidence, in X0
};

/// Everything the library knows about the detector shape. Plain numbers, native units.
struct DetectorDescription {
  std::string name;
  std::array<SphericalShell, 3> layers;    ///< layers 1, 2, 3
  std::array<SphericalShell, 2> supports;  ///< sphere 1 (layers 1–2), sphere 2 (layer 3)
  double thetaMin = 0.0;                   ///< rad, lower edge of ring 0
  double thetaMax = 0.0;                   ///< rad, upper edge of the last ring
  std::vector<int> countersPerRing;        ///< the same in every layer
  ShowerMaterial material;

  /// The SND-like default of docs/contract.md §2 (embedded; overridden by `--detector FILE`).
  static DetectorDescription sndDefault();

  /// Checks the description is a usable calorimeter; the error names the file key at fault.
  /// Beyond consistency, plausibility: a calorimeter of this kind is a few metres at most
  /// (radii in [kMinRadius, kMaxRadius]), so radii given in mm are refused with that hint;
  /// X0 in [0.1, 50] cm, Ec in [1, 100] MeV, x_pre in [0, 10] X0; at most kMaxRings rings of
  /// at most kMaxCountersPerRing counters.
  Status validate() const;

  static constexpr double kMinRadius = 1.0;    ///< cm
  static constexpr double kMaxRadius = 500.0;  ///< cm
  static constexpr int kMaxRings = 180;
  static constexpr int kMaxCountersPerRing = 3600;

  [[nodiscard]] double r0() const { return layers[0].rInner; }     ///< EMC inner radius
  [[nodiscard]] double r1() const { return supports[0].rOuter; }   ///< outer radius of support sphere 1
  [[nodiscard]] double rp3() const { return supports[1].rOuter; }  ///< outer radius of support sphere 2
  [[nodiscard]] int ringCount() const { return static_cast<int>(countersPerRing.size()); }
  [[nodiscard]] double ringWidth() const { return (thetaMax - thetaMin) / ringCount(); }
};

struct Counter {
  int index = 0;
  int layer = 0;  ///< 1..3
  int ring = 0;   ///< 0-based from θ = thetaMin
  int iphi = 0;   ///< 0-based from φ = 0
  Hemisphere hemisphere = Hemisphere::Plus;
  double thetaMin = 0.0, thetaMax = 0.0;  ///< rad
  double phiMin = 0.0, phiMax = 0.0;      ///< rad, within [0, 2π]
  double rInner = 0.0, rOuter = 0.0;      ///< cm
  Vec3 position = Vec3::Zero();           ///< the nominal centre, see centre()

  [[nodiscard]] double theta() const { return 0.5 * (thetaMin + thetaMax); }
  [[nodiscard]] double phi() const { return 0.5 * (phiMin + phiMax); }
  [[nodiscard]] double radius() const { return 0.5 * (rInner + rOuter); }
  /// Nominal centre: mid-angles at the layer's mid-radius, nominal EMC frame.
  [[nodiscard]] const Vec3& centre() const { return position; }
};

/// Where a nominal-frame point lies.
enum class Region {
  Counter,        ///< inside a counter (see `Location::counter`)
  Inside,         ///< r < R0: the TS side of the calorimeter
  SupportSphere,  ///< in a support sphere (or any radial gap between shells)
  Outside,        ///< beyond the outer support sphere
  Uncovered,      ///< at a counter radius but θ outside the rings
};

struct Location {
  Region region = Region::Outside;
  int counter = -1;  ///< index when region == Counter
};

/// The counters of a validated description, indexed as docs/contract.md §2.
class Calorimeter {
 public:
  static Result<Calorimeter> create(DetectorDescription description);

  [[nodiscard]] const DetectorDescription& description() const { return description_; }
  [[nodiscard]] int size() const { return static_cast<int>(counters_.size()); }
  [[nodiscard]] int countersPerLayer() const { return countersPerLayer_; }
  [[nodiscard]] const Counter& counter(int index) const { return counters_.at(static_cast<std::size_t>(index)); }
  [[nodiscard]] std::span<const Counter> counters() const { return counters_; }

  /// Index of (layer 1..3, ring, iphi); -1 when out of range.
  [[nodiscard]] int counterIndex(int layer, int ring, int iphi) const;

  /// The counter that contains a point of the nominal EMC frame, or why none does.
  [[nodiscard]] Location locate(const Vec3& pointNominal) const;

 private:
  explicit Calorimeter(DetectorDescription description);

  DetectorDescription description_;
  std::vector<int> ringOffsets_;  ///< counters in the lower rings of a layer
  /// cos θ·|cos θ| of the ring edges, decreasing: locate compares them with z·|z|/r².
  std::vector<double> ringEdgeKeys_;
  /// locate's first guesses, so that it needs no search with unpredictable branches: per
  /// bin of cos θ·|cos θ| (kCosBins over [−1, 1]) a ring at or below the point's; per ring
  /// and bin of the in-quadrant pseudo-angle v/(u + v) (kPhiBins over [0, 1]) a count of φ
  /// edges at or below the point's. locate then steps up while the next edge is passed
  /// (for the SND-like detector at most once), with the comparisons a search would make.
  static constexpr int kCosBins = 1024;
  static constexpr int kPhiBins = 256;
  std::vector<std::int16_t> ringGuess_;
  std::vector<std::int16_t> phiGuess_;  ///< ring-major, kPhiBins per ring
  double layerR2_[3][2] = {};           ///< squared inner and outer radii of the layers
  double outerR2_ = 0.0;                ///< squared outer radius of support sphere 2
  /// Per ring: (cos, sin) of the φ edges inside the first quadrant, 1..n/4−1 (locate).
  std::vector<std::vector<std::pair<double, double>>> quadrantEdges_;
  int countersPerLayer_ = 0;
  std::vector<Counter> counters_;
};

}  // namespace emcalign::geometry
