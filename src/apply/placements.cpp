#include "emcalign/apply/placements.hpp"

#include <cmath>

#include <fmt/format.h>

#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/strict_json.hpp"

namespace emcalign::apply {

using geometry::Hemisphere;
using geometry::Support;
using io::Json;

namespace {

constexpr double kMmPerCm = 10.0;
constexpr double kTolerance = 1e-9;

Mat3 rotationAbout(int axis, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  Mat3 r = Mat3::Identity();
  const int i = (axis + 1) % 3, j = (axis + 2) % 3;
  r(i, i) = c;
  r(i, j) = -s;
  r(j, i) = s;
  r(j, j) = c;
  return r;
}

}  // namespace

std::string Placement::name() const {
  return fmt::format("sphere{}_{}", support, hemisphere == Hemisphere::Plus ? "plus" : "minus");
}

Placements placementsOf(const geometry::AlignmentTransform& transform) {
  Placements p;
  p.alignment = transform.parameters();
  int k = 0;
  for (int support : {1, 2}) {
    for (Hemisphere h : {Hemisphere::Plus, Hemisphere::Minus}) {
      p.placements[static_cast<std::size_t>(k++)] = {
          support, h, transform.placement(h, support == 1 ? Support::Inner : Support::Outer)};
    }
  }
  return p;
}

Vec3 gdmlAngles(const Mat3& m) {
  const double cosb = std::sqrt(m(0, 0) * m(0, 0) + m(1, 0) * m(1, 0));
  if (cosb > 1e-9) {
    return {std::atan2(m(2, 1), m(2, 2)), std::atan2(-m(2, 0), cosb), std::atan2(m(1, 0), m(0, 0))};
  }
  return {std::atan2(-m(1, 2), m(1, 1)), std::atan2(-m(2, 0), cosb), 0.0};
}

Mat3 gdmlMatrix(const Vec3& angles) {
  return rotationAbout(2, angles.z()) * rotationAbout(1, angles.y()) * rotationAbout(0, angles.x());
}

Json placementsJson(const Placements& p) {
  Json list = Json::array();
  for (const Placement& q : p.placements) {
    Json rotation = Json::array();
    for (int i = 0; i < 3; ++i) {
      rotation.push_back({q.transform.rotation(i, 0), q.transform.rotation(i, 1), q.transform.rotation(i, 2)});
    }
    const Vec3 t = q.transform.translation / units::cm;
    list.push_back({{"support", q.support},
                    {"hemisphere", geometry::sign(q.hemisphere)},
                    {"name", q.name()},
                    {"rotation", rotation},
                    {"translation_cm", {t.x(), t.y(), t.z()}}});
  }
  return Json{{"format", kPlacementsFormat},
              {"software", fmt::format("emcalign {}", kVersion)},
              {"convention", "p1 = rotation * p0 + translation: p0 in the nominal EMC frame, p1 in the TS frame (cm)"},
              {"alignment", io::alignmentToJson(p.alignment)},
              {"placements", list}};
}

std::string placementsGdml(const Placements& p, const geometry::DetectorDescription& d) {
  using units::deg;
  std::string out =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<gdml xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" "
      "xsi:noNamespaceSchemaLocation=\"http://service-spi.web.cern.ch/service-spi/app/releases/GDML/schema/"
      "gdml.xsd\">\n";
  out += fmt::format(
      "  <!-- emcalign {}: the four hemisphere placements of an alignment (docs/apply.md).\n"
      "       Each physvol places its shell with rotation M = Rz(z)*Ry(y)*Rx(x) of its angles as Geant4 reads\n"
      "       them: a point p of the shell goes to M^-1 * p + position (G4GDMLReadStructure::PhysvolRead).\n"
      "       The alignment: {} -->\n",
      kVersion, io::alignmentToJson(p.alignment)["parameters"].dump());
  out += "  <define/>\n  <materials/>\n  <solids>\n";
  const double world = 4.0 * d.rp3() * kMmPerCm;
  out += fmt::format("    <box name=\"world_box\" x=\"{:.17g}\" y=\"{:.17g}\" z=\"{:.17g}\" lunit=\"mm\"/>\n", world,
                     world, world);
  const double radii[2][2] = {{d.r0(), d.r1()}, {d.layers[2].rInner, d.rp3()}};
  for (const Placement& q : p.placements) {
    const bool plus = q.hemisphere == Hemisphere::Plus;
    out += fmt::format(
        "    <sphere name=\"{}_solid\" rmin=\"{:.17g}\" rmax=\"{:.17g}\" startphi=\"{}\" deltaphi=\"180\" "
        "starttheta=\"{:.17g}\" deltatheta=\"{:.17g}\" aunit=\"deg\" lunit=\"mm\"/>\n",
        q.name(), radii[q.support - 1][0] * kMmPerCm, radii[q.support - 1][1] * kMmPerCm, plus ? -90 : 90,
        d.thetaMin / deg, (d.thetaMax - d.thetaMin) / deg);
  }
  out += "  </solids>\n  <structure>\n";
  for (const Placement& q : p.placements) {
    out += fmt::format(
        "    <volume name=\"{0}_volume\">\n      <materialref ref=\"G4_NaI\"/>\n      <solidref ref=\"{0}_solid\"/>\n"
        "    </volume>\n",
        q.name());
  }
  out += "    <volume name=\"world\">\n      <materialref ref=\"G4_Galactic\"/>\n      <solidref ref=\"world_box\"/>\n";
  for (const Placement& q : p.placements) {
    const Vec3 a = gdmlAngles(q.transform.rotation.transpose()) / deg;
    const Vec3 t = q.transform.translation * kMmPerCm;
    out += fmt::format(
        "      <physvol name=\"{0}\">\n        <volumeref ref=\"{0}_volume\"/>\n"
        "        <position name=\"{0}_position\" x=\"{1:.17g}\" y=\"{2:.17g}\" z=\"{3:.17g}\" unit=\"mm\"/>\n"
        "        <rotation name=\"{0}_rotation\" x=\"{4:.17g}\" y=\"{5:.17g}\" z=\"{6:.17g}\" unit=\"deg\"/>\n"
        "      </physvol>\n",
        q.name(), t.x(), t.y(), t.z(), a.x(), a.y(), a.z());
  }
  out +=
      "    </volume>\n  </structure>\n  <setup name=\"Default\" version=\"1.0\">\n    <world ref=\"world\"/>\n"
      "  </setup>\n</gdml>\n";
  return out;
}

bool isPlacementsJson(const Json& j) {
  return j.is_object() && j.contains("format") && j["format"].is_string() &&
         j["format"].get<std::string>() == kPlacementsFormat;
}

Result<Placements> readPlacements(const std::string& path, const geometry::Calorimeter& calo) {
  auto text = io::readTextFile(path);
  if (!text) return text.error();
  auto j = io::parseJson(*text, path);
  if (!j) return j.error();
  if (!isPlacementsJson(*j)) return Error{fmt::format("{}: key 'format': expected \"{}\"", path, kPlacementsFormat)};
  if (Status s =
          io::strict::checkKeys(*j, {"format", "software", "convention", "alignment", "placements"}, {.source = path});
      !s) {
    return s.error();
  }
  if (!j->contains("alignment")) return Error{fmt::format("{}: key 'alignment': missing", path)};
  auto alignment = io::parseAlignment((*j)["alignment"], calo.description().r1(), path);
  if (!alignment) return alignment.error();
  auto transform = geometry::AlignmentTransform::create(*alignment, geometry::AlignmentRadii::of(calo.description()));
  if (!transform) return Error{fmt::format("{}: {}", path, transform.error().message)};
  Placements expected = placementsOf(*transform);
  const Json& list = (*j)["placements"];
  if (!list.is_array() || list.size() != 4) {
    return Error{fmt::format("{}: key 'placements': expected the four placements", path)};
  }
  for (std::size_t k = 0; k < 4; ++k) {
    const Json& q = list[k];
    const Placement& e = expected.placements[k];
    const std::string where = fmt::format("placements[{}]", k);
    const auto number = [](const Json& v) { return v.is_number() ? v.get<double>() : std::nan(""); };
    if (!q.is_object() || !q.contains("support") || !q.contains("hemisphere") || !q.contains("rotation") ||
        !q.contains("translation_cm") || !q["rotation"].is_array() || q["rotation"].size() != 3 ||
        !q["translation_cm"].is_array() || q["translation_cm"].size() != 3) {
      return Error{
          fmt::format("{}: key '{}': expected support, hemisphere, rotation (3x3), translation_cm (3)", path, where)};
    }
    if (Status s = io::strict::checkKeys(q, {"support", "hemisphere", "name", "rotation", "translation_cm"},
                                         {.source = path, .path = where});
        !s) {
      return s.error();
    }
    if (number(q["support"]) != e.support || number(q["hemisphere"]) != geometry::sign(e.hemisphere)) {
      return Error{fmt::format("{}: key '{}': expected support {} hemisphere {} (the order of the export)", path, where,
                               e.support, geometry::sign(e.hemisphere))};
    }
    double worst = 0.0;
    for (int r = 0; r < 3; ++r) {
      const Json& row = q["rotation"][static_cast<std::size_t>(r)];
      if (!row.is_array() || row.size() != 3)
        return Error{fmt::format("{}: key '{}.rotation': expected 3x3", path, where)};
      for (int c = 0; c < 3; ++c) {
        const double d = std::abs(number(row[static_cast<std::size_t>(c)]) - e.transform.rotation(r, c));
        worst = std::isnan(d) ? INFINITY : std::max(worst, d);
      }
      const double d =
          std::abs(number(q["translation_cm"][static_cast<std::size_t>(r)]) * units::cm - e.transform.translation[r]);
      worst = std::isnan(d) ? INFINITY : std::max(worst, d);
    }
    if (!(worst <= kTolerance)) {
      return Error{
          fmt::format("{}: key '{}': the placement differs from the one its alignment gives (by {:.3g}): was "
                      "it edited? Export the placements of the alignment you mean (emcalign export)",
                      path, where, worst)};
    }
  }
  return expected;
}

Result<io::AlignmentFile> loadAlignment(const std::string& path, const geometry::Calorimeter& calo) {
  auto text = io::readTextFile(path);
  if (!text) return text.error();
  auto j = io::parseJson(*text, path);
  if (!j) return j.error();
  if (apply::isPlacementsJson(*j)) {
    auto placements = apply::readPlacements(path, calo);
    if (!placements) return placements.error();
    io::AlignmentFile file;
    file.parameters = placements->alignment;
    for (const auto& w : geometry::warnings(file.parameters)) file.warnings.push_back(fmt::format("{}: {}", path, w));
    return file;
  }
  return io::parseAlignmentFile(*j, calo.description().r1(), path);
}

std::string placementsFile(const geometry::AlignmentTransform& transform, const geometry::DetectorDescription& d,
                           std::string_view format) {
  const Placements placements = placementsOf(transform);
  return format == "gdml" ? placementsGdml(placements, d) : placementsJson(placements).dump(2) + "\n";
}

std::string placementsWrittenText(const std::string& output, std::string_view format, bool layer3Rule) {
  return fmt::format("wrote {} ({} placements: sphere1_plus, sphere1_minus, sphere2_plus, sphere2_minus{})\n",
                     output == "-" ? "the placements to standard output" : output, format,
                     layer3Rule ? "; layer 3 with the mu3 rule" : "");
}

Result<geometry::CounterGeometry> countersOf(const geometry::Calorimeter& calo, const std::string& path,
                                             std::vector<std::string>& warnings) {
  if (path.empty()) return geometry::CounterGeometry::nominal(calo);
  auto file = loadAlignment(path, calo);
  if (!file) return file.error();
  warnings.insert(warnings.end(), file->warnings.begin(), file->warnings.end());
  auto t = geometry::AlignmentTransform::create(file->parameters, geometry::AlignmentRadii::of(calo.description()));
  if (!t) return t.error();
  return geometry::CounterGeometry::aligned(calo, *t);
}

}  // namespace emcalign::apply
