#include "emcalign/geometry/alignment_transform.hpp"

namespace emcalign::geometry {

Result<AlignmentTransform> AlignmentTransform::create(const AlignmentParameters& eta, const AlignmentRadii& radii) {
  if (Status s = validate(eta, radii.r1); !s) return s.error();
  AlignmentTransform t;
  t.eta_ = eta;
  for (Support support : {Support::Inner, Support::Outer}) {
    for (Hemisphere h : {Hemisphere::Plus, Hemisphere::Minus}) {
      t.placements_[(h == Hemisphere::Plus ? 0 : 1) + (support == Support::Outer ? 2 : 0)] =
          hemisphereTransform<double>(eta.values, h, radii, support);
    }
  }
  double dxRel = 0.0;
  const Vec3 sinMuN = separationSineVector<double>(eta.values, radii.r1, &dxRel);
  t.layer3Rule_ = layer3RuleApplies<double>(sinMuN, dxRel, radii.rp3);
  return t;
}

InverseResult AlignmentTransform::inverseAuto(const Vec3& p1, Support support) const {
  const Vec3 plus = inverse(p1, Hemisphere::Plus, support);
  const Vec3 minus = inverse(p1, Hemisphere::Minus, support);
  const bool plusOk = hemisphereOf(plus.x()) == Hemisphere::Plus;
  const bool minusOk = hemisphereOf(minus.x()) == Hemisphere::Minus;
  if (plusOk && minusOk) return {InverseKind::Overlap, Hemisphere::Plus, Vec3::Zero()};
  if (plusOk) return {InverseKind::Unique, Hemisphere::Plus, plus};
  if (minusOk) return {InverseKind::Unique, Hemisphere::Minus, minus};
  return {InverseKind::Gap, Hemisphere::Plus, Vec3::Zero()};
}

}  // namespace emcalign::geometry
