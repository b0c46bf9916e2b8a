#include "emcalign/io/point_tables.hpp"

#include <cmath>
#include <optional>

#include <fmt/format.h>

#include "emcalign/core/units.hpp"
#include "emcalign/geometry/track.hpp"

namespace emcalign::io {

namespace {

using namespace emcalign::geometry;
using units::cm;
using units::deg;

// The three coordinate columns of a point: header and values.
std::string coordinateHeader(const std::string& system) {
  if (system == "cylindrical") return "rho_cm,phi_deg,z_cm";
  if (system == "spherical") return "r_cm,theta_deg,phi_deg";
  return "x_cm,y_cm,z_cm";
}

std::string coordinates(const Vec3& p, const std::string& system) {
  if (system == "cylindrical") {
    return fmt::format("{:.17g},{:.17g},{:.17g}", std::hypot(p.x(), p.y()) / cm, azimuth(p) / deg, p.z() / cm);
  }
  if (system == "spherical") {
    return fmt::format("{:.17g},{:.17g},{:.17g}", p.norm() / cm, polar(p) / deg, azimuth(p) / deg);
  }
  return fmt::format("{:.17g},{:.17g},{:.17g}", p.x() / cm, p.y() / cm, p.z() / cm);
}

std::string counterColumns(const Counter& c) {
  return fmt::format("{},{},{},{},{},", c.index, c.layer, c.ring, c.iphi, sign(c.hemisphere));
}

}  // namespace

std::string countersCsv(const Calorimeter& calo, const CounterGeometry& geometry, const std::string& system) {
  // Without a system: the historic columns (angles, then Cartesian).
  const bool both = system.empty();
  std::string out = fmt::format("index,layer,ring,iphi,hemisphere,{}\n",
                                both ? "theta_deg,phi_deg,x_cm,y_cm,z_cm" : coordinateHeader(system));
  for (const Counter& c : calo.counters()) {
    const Vec3& p = geometry.centre(c.index);
    out += counterColumns(c);
    out += both ? fmt::format("{:.17g},{:.17g},{}\n", polar(p) / deg, azimuth(p) / deg, coordinates(p, "cartesian"))
                : coordinates(p, system) + "\n";
  }
  return out;
}

std::string locatedPointsCsv(const Calorimeter& calo, const CounterGeometry& geometry,
                             const std::vector<Vec3>& points) {
  std::string out =
      "x_cm,y_cm,z_cm,region,counter,layer,ring,iphi,hemisphere,other_counter,nominal_x_cm,nominal_y_cm,"
      "nominal_z_cm\n";
  for (const Vec3& p : points) {
    const PointLocation loc = geometry.locate(p);
    out += fmt::format("{},{},", coordinates(p, "cartesian"), name(loc.region));
    if (loc.counter >= 0) {
      out += counterColumns(calo.counter(loc.counter));
    } else {
      out += loc.region == PointRegion::Gap ? ",,,,," : fmt::format(",,,,{},", sign(loc.hemisphere));
    }
    out += loc.otherCounter >= 0 ? fmt::format("{},", loc.otherCounter) : ",";
    out += loc.region == PointRegion::Gap ? ",,\n" : coordinates(loc.nominal, "cartesian") + "\n";
  }
  return out;
}

TransformedPoints transformPoints(const AlignmentTransform& transform, const std::vector<Vec3>& points,
                                  const TransformGiven& given) {
  const Support support = supportOfLayer(given.layer);
  std::optional<Hemisphere> fixed;
  if (given.hemisphere == "+1" || given.hemisphere == "1") fixed = Hemisphere::Plus;
  if (given.hemisphere == "-1") fixed = Hemisphere::Minus;
  TransformedPoints t{"x_cm,y_cm,z_cm,hemisphere\n", {}};
  long gaps = 0, overlaps = 0;
  for (const Vec3& p : points) {
    Vec3 q;
    Hemisphere h = Hemisphere::Plus;
    if (!given.inverse) {
      h = fixed.value_or(hemisphereOf(p.x()));
      q = transform.forward(p, h, support);
    } else if (fixed) {
      h = *fixed;
      q = transform.inverse(p, h, support);
    } else {
      const InverseResult r = transform.inverseAuto(p, support);
      if (r.kind != InverseKind::Unique) {
        const bool gap = r.kind == InverseKind::Gap;
        (gap ? gaps : overlaps) += 1;
        t.csv += gap ? ",,,gap\n" : ",,,overlap\n";
        continue;
      }
      h = r.hemisphere;
      q = r.point;
    }
    t.csv += fmt::format("{:.17g},{:.17g},{:.17g},{}\n", q.x() / cm, q.y() / cm, q.z() / cm, sign(h));
  }
  if (gaps > 0) t.warnings.push_back(fmt::format("{} point(s) lie in the gap between the hemispheres", gaps));
  if (overlaps > 0) t.warnings.push_back(fmt::format("{} point(s) lie where the hemispheres overlap", overlaps));
  return t;
}

}  // namespace emcalign::io
