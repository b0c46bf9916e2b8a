#pragma once
// The cluster correction of docs/contract.md §9 (the paper's section 4): a cluster's direction (φ, θ)
// and energy E, reconstructed in the nominal EMC frame, become the direction of the point
// where that shower really is in the TS frame:
//
//   p0 = R(E, θ)·(sinθ cosφ, sinθ sinφ, cosθ)      the shower point, nominal frame
//   p1 = forward(p0), hemisphere s = sign(cos φ)   (layers 1–2: support sphere 1)
//   (φ', θ') = angles of p1 seen from the TS origin
//
// R is the shower depth of docs/contract.md §5 (geometry/shower_depth.hpp), with its offset when the
// caller sets one (the model corrections of the fit). A cluster so soft that R(E, θ) ≤ 0
// (E below ~1e-4 MeV; never a reconstructed cluster) is placed at the inner radius R0.

#include <utility>

#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/shower_depth.hpp"

namespace emcalign::apply {

/// The corrected (φ', θ') of a cluster, rad; φ' in [0, 2π), θ' in [0, π].
std::pair<double, double> correctDirection(const geometry::AlignmentTransform& transform,
                                           const geometry::ShowerDepth& depth, double phi, double theta, double energy);

/// The largest cluster energy taken (MeV): a collider's beams are a few GeV; 1e300 is a
/// unit or a column mistake.
inline constexpr double kMaxClusterEnergyMeV = 1e5;

/// A cluster as the correction takes it from columns a caller filled (Python): energy finite
/// in (0, 1e5] MeV, θ in [0, π], φ in [0, 2π] (rad, as event files hold them). The error
/// names the value and its field; NaN energy (no cluster) is the caller's to skip.
Status checkCluster(double phi, double theta, double energy);

}  // namespace emcalign::apply
