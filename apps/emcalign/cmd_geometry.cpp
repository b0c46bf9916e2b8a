// emcalign geometry: the detector summary, the counter table (nominal or actual centres) and
// the detector description file.

#include <cmath>
#include <iostream>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common.hpp"
#include "console.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/counter_geometry.hpp"
#include "emcalign/geometry/track.hpp"
#include "emcalign/io/csv.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/io/points_csv.hpp"

namespace emcalign::app {

namespace {

using namespace emcalign::geometry;
using io::Json;
using units::cm;
using units::deg;

struct GeometryOptions {
  std::string detector;
  std::string params;
  bool json = false;
  bool counters = false;
  bool description = false;
  bool locate = false;
  std::string coordinates;  // empty: the historic columns
};

Json summaryJson(const Calorimeter& calo) {
  const auto& d = calo.description();
  Json layers = Json::array();
  for (int l = 1; l <= 3; ++l) {
    const auto& s = d.layers[static_cast<std::size_t>(l - 1)];
    layers.push_back({{"layer", l},
                      {"counters", calo.countersPerLayer()},
                      {"r_inner_cm", s.rInner / cm},
                      {"r_outer_cm", s.rOuter / cm}});
  }
  Json rings = Json::array();
  for (int r = 0; r < d.ringCount(); ++r) {
    const int n = d.countersPerRing[static_cast<std::size_t>(r)];
    rings.push_back({{"ring", r},
                     {"theta_min_deg", (d.thetaMin + r * d.ringWidth()) / deg},
                     {"theta_max_deg", (d.thetaMin + (r + 1) * d.ringWidth()) / deg},
                     {"counters", n},
                     {"dphi_deg", 360.0 / n}});
  }
  return {{"name", d.name},
          {"counters", calo.size()},
          {"layers", layers},
          {"r0_cm", d.r0() / cm},
          {"r1_cm", d.r1() / cm},
          {"rp3_cm", d.rp3() / cm},
          {"theta_min_deg", d.thetaMin / deg},
          {"theta_max_deg", d.thetaMax / deg},
          {"rings", rings}};
}

void printSummary(const Calorimeter& calo) {
  const auto& d = calo.description();
  fmt::print("Detector: {}\n", d.name);
  fmt::print("Counters: {} ({} per layer, {} of {:.4g} deg from {:.4g} to {:.4g} deg)\n", calo.size(),
             calo.countersPerLayer(), counted(d.ringCount(), "ring"), d.ringWidth() / deg, d.thetaMin / deg,
             d.thetaMax / deg);
  fmt::print("  {:<22} {:>10} {:>10}\n", "shell", "r_in, cm", "r_out, cm");
  const char* names[] = {"layer 1", "layer 2", "support sphere 1", "layer 3", "support sphere 2"};
  const SphericalShell* shells[] = {&d.layers[0], &d.layers[1], &d.supports[0], &d.layers[2], &d.supports[1]};
  for (int i = 0; i < 5; ++i) {
    fmt::print("  {:<22} {:>10.2f} {:>10.2f}\n", names[i], shells[i]->rInner / cm, shells[i]->rOuter / cm);
  }
  fmt::print("R0 = {:.2f} cm (EMC inner radius), R1 = {:.2f} cm, R_p3 = {:.2f} cm\n", d.r0() / cm, d.r1() / cm,
             d.rp3() / cm);
  fmt::print("Rings (counters per ring):");
  for (int n : d.countersPerRing) fmt::print(" {}", n);
  fmt::print("\nShower depth: X0 = {} cm, Ec = {} MeV, x_pre = {} X0\n", d.material.radiationLength,
             d.material.criticalEnergy, d.material.preshowerMaterial);
}

// The geometry of --params (or the nominal one).
Result<CounterGeometry> geometryFor(const Calorimeter& calo, const std::string& paramsPath) {
  if (paramsPath.empty()) return CounterGeometry::nominal(calo);
  auto file = loadAlignment(paramsPath, calo);
  if (!file) return file.error();
  for (const auto& w : file->warnings) reportWarning(w);
  auto t = AlignmentTransform::create(file->parameters, AlignmentRadii::of(calo.description()));
  if (!t) return t.error();
  return CounterGeometry::aligned(calo, *t);
}

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
  if (system == "spherical")
    return fmt::format("{:.17g},{:.17g},{:.17g}", p.norm() / cm, polar(p) / deg, azimuth(p) / deg);
  return fmt::format("{:.17g},{:.17g},{:.17g}", p.x() / cm, p.y() / cm, p.z() / cm);
}

int printCounters(const Calorimeter& calo, const std::string& paramsPath, const std::string& system) {
  auto geometry = geometryFor(calo, paramsPath);
  if (!geometry) return reportError(geometry.error());
  // Without --coordinates: the historic columns (angles, then Cartesian).
  const bool both = system.empty();
  std::string out = fmt::format("index,layer,ring,iphi,hemisphere,{}\n",
                                both ? "theta_deg,phi_deg,x_cm,y_cm,z_cm" : coordinateHeader(system));
  for (const Counter& c : calo.counters()) {
    const Vec3& p = geometry->centre(c.index);
    out += fmt::format("{},{},{},{},{},", c.index, c.layer, c.ring, c.iphi, sign(c.hemisphere));
    out += both ? fmt::format("{:.17g},{:.17g},{}\n", polar(p) / deg, azimuth(p) / deg, coordinates(p, "cartesian"))
                : coordinates(p, system) + "\n";
  }
  fmt::print("{}", out);
  return 0;
}

// --locate: x_cm,y_cm,z_cm rows on stdin (TS frame) → the counter that contains each.
int locatePoints(const Calorimeter& calo, const std::string& paramsPath) {
  auto geometry = geometryFor(calo, paramsPath);
  if (!geometry) return reportError(geometry.error());
  std::string out =
      "x_cm,y_cm,z_cm,region,counter,layer,ring,iphi,hemisphere,other_counter,nominal_x_cm,nominal_y_cm,"
      "nominal_z_cm\n";
  auto points = io::readPointsCsv(std::cin, "stdin");
  if (!points) return reportError(points.error());
  for (const Vec3& p : *points) {
    const PointLocation loc = geometry->locate(p);
    out += fmt::format("{},{},", coordinates(p, "cartesian"), name(loc.region));
    if (loc.counter >= 0) {
      const Counter& c = calo.counter(loc.counter);
      out += fmt::format("{},{},{},{},{},", c.index, c.layer, c.ring, c.iphi, sign(c.hemisphere));
    } else {
      out += loc.region == PointRegion::Gap ? ",,,,," : fmt::format(",,,,{},", sign(loc.hemisphere));
    }
    out += loc.otherCounter >= 0 ? fmt::format("{},", loc.otherCounter) : ",";
    out += loc.region == PointRegion::Gap ? ",,\n" : coordinates(loc.nominal, "cartesian") + "\n";
  }
  fmt::print("{}", out);
  return 0;
}

int run(const GeometryOptions& o) {
  if (!o.params.empty() && !o.counters && !o.locate) {
    eprint("emcalign: usage error: --params goes with --counters or --locate\n");
    return kExitUsage;
  }
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return reportError(calo.error());
  if (o.description) {
    fmt::print("{}\n", io::toJson(calo->description()).dump(2));
    return 0;
  }
  if (o.counters) return printCounters(*calo, o.params, o.coordinates);
  if (o.locate) return locatePoints(*calo, o.params);
  if (o.json) {
    fmt::print("{}\n", summaryJson(*calo).dump(2));
  } else {
    printSummary(*calo);
  }
  return 0;
}

}  // namespace

void addGeometryCommand(CLI::App& app, int& exitCode) {
  auto opts = std::make_shared<GeometryOptions>();
  auto* cmd = app.add_subcommand("geometry", "Describe the calorimeter: summary, counters, description file");
  addVersionFlag(*cmd);
  addDetectorOption(*cmd, opts->detector);
  auto* json = cmd->add_flag("--json", opts->json, "print the summary as JSON");
  auto* counters =
      cmd->add_flag("--counters", opts->counters,
                    "print every counter as CSV: index,layer,ring,iphi,hemisphere,theta_deg,phi_deg,x_cm,y_cm,z_cm");
  auto* locate =
      cmd->add_flag("--locate", opts->locate,
                    "read x_cm,y_cm,z_cm rows (TS frame) on stdin and print the counter that contains each "
                    "(or the region: gap, overlap, inside, support, outside, uncovered) and the point in the "
                    "nominal EMC frame");
  auto* params = cmd->add_option("--params", opts->params,
                                 "with --counters or --locate: the detector placed by these alignment parameters (a "
                                 "parameter file or a fit result; layer 3 with the mu3 rule)")
                     ->check(CLI::ExistingFile);
  cmd->add_option("--coordinates", opts->coordinates,
                  "with --counters: cartesian (x_cm,y_cm,z_cm), cylindrical (rho_cm,phi_deg,z_cm) or "
                  "spherical (r_cm,theta_deg,phi_deg) instead of theta_deg,phi_deg,x_cm,y_cm,z_cm")
      ->check(CLI::IsMember({"cartesian", "cylindrical", "spherical"}))
      ->needs(counters);
  auto* description = cmd->add_flag("--description", opts->description,
                                    "print the detector description JSON (the format --detector reads)");
  json->excludes(counters)->excludes(description)->excludes(locate);
  counters->excludes(description)->excludes(locate);
  locate->excludes(description);
  params->excludes(description)->excludes(json);
  cmd->callback([opts, &exitCode] { exitCode = run(*opts); });
}

}  // namespace emcalign::app
