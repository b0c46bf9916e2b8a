#pragma once
// The tracking system (TS) of the simulation: a straight-line tracker (SND has no magnetic
// field), multiple scattering in the beam pipe, 9 cylindrical drift-chamber layers with
// r-φ and z resolutions, and a least-squares line fit that returns the docs/contract.md §5 track
// parameters (z0, rho, phi, theta).
//
// Assumed values (docs/simulation.md): beam pipe of 1 mm Be at r = 2 cm; layers at
// r = 4.0, 4.9, …, 11.2 cm, half-length 20 cm; σ_rφ = 0.0316 cm and σ_z = 0.0365 cm per hit,
// chosen so that the fit of a radial track without scattering has σ_φ = 0.26° and
// σ_θ = 0.30° at θ = 90°: for 9 equally spaced layers of lever arm
// L = √Σ(r_i − r̄)² = 6.97 cm, σ_φ = σ_rφ/L and σ_θ = σ_z·sin²θ/L.

#include <optional>
#include <vector>

#include "emcalign/core/random.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/types.hpp"
#include "emcalign/geometry/track.hpp"

namespace emcalign::sim {

struct TrackingOptions {
  double beamPipeRadius = 2.0;                                                       ///< cm
  double beamPipeThickness = 0.1;                                                    ///< cm of beryllium
  double beamPipeRadiationLength = 35.28;                                            ///< cm, X0 of Be
  static constexpr std::size_t kMaxLayers = 16;                                      ///< the track fit's hit buffers
  std::vector<double> layerRadii = {4.0, 4.9, 5.8, 6.7, 7.6, 8.5, 9.4, 10.3, 11.2};  ///< cm
  double halfLength = 20.0;   ///< cm, |z| of the sensitive volume
  double sigmaRPhi = 0.0316;  ///< cm per hit
  double sigmaZ = 0.0365;     ///< cm per hit
  int minHits = 4;            ///< fewer hits: no track
  bool multipleScattering = true;

  Status validate() const;
};

/// A charged particle's straight path after the beam pipe (the line the TS sees).
struct ChargedPath {
  Vec3 point;      ///< a point of the line (cm)
  Vec3 direction;  ///< unit, outgoing
};

class TrackingSystem {
 public:
  explicit TrackingSystem(TrackingOptions options) : options_(std::move(options)) {}
  [[nodiscard]] const TrackingOptions& options() const { return options_; }

  /// The path after multiple scattering in the beam pipe for a particle of momentum p
  /// (MeV) and speed β leaving the vertex in direction d.
  ChargedPath scatter(const Vec3& vertex, const Vec3& direction, double momentum, double beta, Rng& rng) const;

  /// Hits on the layers, smeared, and the least-squares line fit; none with too few hits.
  std::optional<geometry::TrackLine> measure(const ChargedPath& path, Rng& rng) const;

 private:
  TrackingOptions options_;
};

}  // namespace emcalign::sim
