#pragma once
// The CSV tables of the geometry commands (docs/conventions.md; 17 significant digits, cm and
// deg): `geometry --counters` (every counter's centre), `geometry --locate` (the counter that
// contains each point) and `transform` (the alignment transform of docs/contract.md §4 on
// points). Each table starts with its header line.

#include <string>
#include <vector>

#include "emcalign/core/types.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/counter_geometry.hpp"
#include "emcalign/geometry/detector.hpp"

namespace emcalign::io {

/// `geometry --counters`: index,layer,ring,iphi,hemisphere and the centre in `system`
/// ("cartesian" x_cm,y_cm,z_cm; "cylindrical" rho_cm,phi_deg,z_cm; "spherical"
/// r_cm,theta_deg,phi_deg), or, `system` empty, the historic theta_deg,phi_deg,x_cm,y_cm,z_cm.
std::string countersCsv(const geometry::Calorimeter& calo, const geometry::CounterGeometry& geometry,
                        const std::string& system);

/// `geometry --locate`: each TS-frame point, its region, the counter that contains it (layer,
/// ring, iphi, hemisphere; the other hemisphere's counter in an overlap) and the point in the
/// nominal EMC frame (empty in the gap).
std::string locatedPointsCsv(const geometry::Calorimeter& calo, const geometry::CounterGeometry& geometry,
                             const std::vector<Vec3>& points);

/// How `transform` maps the points: forward (nominal → actual) or inverse, the hemisphere
/// ("auto", "+1", "1" or "-1") and the layer (1, 2: support sphere 1; 3: support sphere 2).
struct TransformGiven {
  bool inverse = false;
  std::string hemisphere = "auto";
  int layer = 1;
};
/// `transform`'s output: x_cm,y_cm,z_cm,hemisphere per point. Forward with "auto" takes the sign
/// of x of the point; inverse with "auto" finds the hemisphere, and a point in the gap or an
/// overlap is written with empty coordinates and "gap" or "overlap" (`warnings` counts them).
struct TransformedPoints {
  std::string csv;
  std::vector<std::string> warnings;  ///< "N point(s) lie in the gap between the hemispheres", ...
};
TransformedPoints transformPoints(const geometry::AlignmentTransform& transform, const std::vector<Vec3>& points,
                                  const TransformGiven& given);

}  // namespace emcalign::io
