#pragma once
// The geometry database (the paper's GeoEmcDBase, section 4): where every counter is, for
// the nominal detector or for an alignment, and which counter a point of the TS frame is in.
//
// Aligned centres follow docs/contract.md §9: the nominal centre of a counter moved by the rigid
// placement of its hemisphere on its support sphere — layers 1–2 on sphere 1 (the
// transform of docs/contract.md §4), layer 3 on sphere 2 (with the μ3 rule). The same placements, read
// backwards, locate a point: its pre-image under each of the four placements is looked up
// in the nominal calorimeter, and a placement counts only for the counters it carries
// (its hemisphere, its support sphere). So a point between the moved hemispheres is in no
// counter (a gap), and a point where they overlap is in one counter of each (an overlap).

#include <span>
#include <string_view>
#include <vector>

#include "emcalign/core/types.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/detector.hpp"

namespace emcalign::geometry {

/// Where a TS-frame point lies in the (aligned) calorimeter.
enum class PointRegion {
  Counter,        ///< in exactly one counter
  Overlap,        ///< in a counter of each hemisphere: they overlap there
  Gap,            ///< between the hemispheres (in no hemisphere's own side)
  Inside,         ///< inside the calorimeter (r < R0 of its hemisphere)
  SupportSphere,  ///< in a support sphere, or between layers
  Outside,        ///< beyond the outer support sphere
  Uncovered,      ///< at a counter radius, but θ outside the rings
};
std::string_view name(PointRegion r);

struct PointLocation {
  PointRegion region = PointRegion::Outside;
  int counter = -1;                          ///< Counter; Overlap: the counter of hemisphere +1
  int otherCounter = -1;                     ///< Overlap: the counter of hemisphere −1
  Hemisphere hemisphere = Hemisphere::Plus;  ///< whose pre-image `nominal` is (not for Gap)
  Vec3 nominal = Vec3::Zero();               ///< the point in the nominal EMC frame (not for Gap)
};

class CounterGeometry {
 public:
  /// The nominal detector (the aligned EMC frame is the TS frame). `calo` must outlive it.
  static CounterGeometry nominal(const Calorimeter& calo);
  /// The detector placed by an alignment.
  static CounterGeometry aligned(const Calorimeter& calo, const AlignmentTransform& transform);

  [[nodiscard]] const Calorimeter& calorimeter() const { return *calo_; }
  /// The centre of counter `index` in the TS frame.
  [[nodiscard]] const Vec3& centre(int index) const { return centres_[static_cast<std::size_t>(index)]; }
  [[nodiscard]] std::span<const Vec3> centres() const { return centres_; }
  /// The rigid placement of a hemisphere on a support sphere (identity when nominal).
  [[nodiscard]] const RigidTransform& placement(Hemisphere h, Support s) const;

  /// The counter (or region) containing a TS-frame point.
  [[nodiscard]] PointLocation locate(const Vec3& pointTs) const;

 private:
  CounterGeometry() = default;
  const Calorimeter* calo_ = nullptr;
  RigidTransform placements_[4];  // (+, inner), (−, inner), (+, outer), (−, outer)
  std::vector<Vec3> centres_;
};

}  // namespace emcalign::geometry
