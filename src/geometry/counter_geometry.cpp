#include "emcalign/geometry/counter_geometry.hpp"

namespace emcalign::geometry {

namespace {

int slot(Hemisphere h, Support s) { return (h == Hemisphere::Plus ? 0 : 1) + (s == Support::Outer ? 2 : 0); }

PointRegion fromNominal(Region r) {
  switch (r) {
    case Region::Inside:
      return PointRegion::Inside;
    case Region::Outside:
      return PointRegion::Outside;
    case Region::Uncovered:
      return PointRegion::Uncovered;
    case Region::SupportSphere:
    case Region::Counter:  // a counter its placement does not carry: between the layers
      return PointRegion::SupportSphere;
  }
  return PointRegion::Outside;
}

}  // namespace

std::string_view name(PointRegion r) {
  switch (r) {
    case PointRegion::Counter:
      return "counter";
    case PointRegion::Overlap:
      return "overlap";
    case PointRegion::Gap:
      return "gap";
    case PointRegion::Inside:
      return "inside";
    case PointRegion::SupportSphere:
      return "support";
    case PointRegion::Outside:
      return "outside";
    case PointRegion::Uncovered:
      return "uncovered";
  }
  return "?";
}

CounterGeometry CounterGeometry::nominal(const Calorimeter& calo) {
  CounterGeometry g;
  g.calo_ = &calo;
  g.centres_.reserve(static_cast<std::size_t>(calo.size()));
  for (const Counter& c : calo.counters()) g.centres_.push_back(c.centre());
  return g;
}

CounterGeometry CounterGeometry::aligned(const Calorimeter& calo, const AlignmentTransform& transform) {
  CounterGeometry g;
  g.calo_ = &calo;
  for (Hemisphere h : {Hemisphere::Plus, Hemisphere::Minus}) {
    for (Support s : {Support::Inner, Support::Outer}) g.placements_[slot(h, s)] = transform.placement(h, s);
  }
  g.centres_.reserve(static_cast<std::size_t>(calo.size()));
  for (const Counter& c : calo.counters()) {
    g.centres_.push_back(g.placement(c.hemisphere, supportOfLayer(c.layer)).apply(c.centre()));
  }
  return g;
}

const RigidTransform& CounterGeometry::placement(Hemisphere h, Support s) const { return placements_[slot(h, s)]; }

PointLocation CounterGeometry::locate(const Vec3& p1) const {
  // The counters each placement carries: those of its hemisphere on its support sphere.
  PointLocation found[2];
  bool has[2] = {false, false};
  for (Hemisphere h : {Hemisphere::Plus, Hemisphere::Minus}) {
    const int k = h == Hemisphere::Plus ? 0 : 1;
    for (Support s : {Support::Inner, Support::Outer}) {
      if (has[k]) break;
      const Vec3 p0 = placement(h, s).applyInverse(p1);
      const Location loc = calo_->locate(p0);
      if (loc.region != Region::Counter) continue;
      const Counter& c = calo_->counter(loc.counter);
      if (c.hemisphere != h || supportOfLayer(c.layer) != s) continue;
      found[k] = {PointRegion::Counter, loc.counter, -1, h, p0};
      has[k] = true;
    }
  }
  if (has[0] && has[1]) {
    PointLocation out = found[0];
    out.region = PointRegion::Overlap;
    out.otherCounter = found[1].counter;
    return out;
  }
  if (has[0]) return found[0];
  if (has[1]) return found[1];
  // In no counter: which side, and what is there.
  const Vec3 plus = placement(Hemisphere::Plus, Support::Inner).applyInverse(p1);
  const Vec3 minus = placement(Hemisphere::Minus, Support::Inner).applyInverse(p1);
  const bool plusOwn = hemisphereOf(plus.x()) == Hemisphere::Plus;
  const bool minusOwn = hemisphereOf(minus.x()) == Hemisphere::Minus;
  if (!plusOwn && !minusOwn) return {PointRegion::Gap, -1, -1, Hemisphere::Plus, Vec3::Zero()};
  const Hemisphere h = plusOwn ? Hemisphere::Plus : Hemisphere::Minus;
  const Vec3& p0 = plusOwn ? plus : minus;
  return {fromNominal(calo_->locate(p0).region), -1, -1, h, p0};
}

}  // namespace emcalign::geometry
