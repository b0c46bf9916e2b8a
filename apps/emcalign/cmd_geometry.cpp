// emcalign geometry: the detector summary, the counter table (nominal or actual centres) and
// the detector description file.

#include <memory>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/track.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::app {

namespace {

using namespace emcalign::geometry;
using units::cm;
using units::deg;
using io::Json;

struct GeometryOptions {
  std::string detector;
  std::string params;
  bool json = false;
  bool counters = false;
  bool description = false;
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
  fmt::print("Counters: {} ({} per layer, {} rings of {:.4g} deg from {:.4g} to {:.4g} deg)\n",
             calo.size(), calo.countersPerLayer(), d.ringCount(), d.ringWidth() / deg,
             d.thetaMin / deg, d.thetaMax / deg);
  fmt::print("  {:<22} {:>10} {:>10}\n", "shell", "r_in, cm", "r_out, cm");
  const char* names[] = {"layer 1", "layer 2", "support sphere 1", "layer 3", "support sphere 2"};
  const SphericalShell* shells[] = {&d.layers[0], &d.layers[1], &d.supports[0], &d.layers[2],
                                    &d.supports[1]};
  for (int i = 0; i < 5; ++i) {
    fmt::print("  {:<22} {:>10.2f} {:>10.2f}\n", names[i], shells[i]->rInner / cm, shells[i]->rOuter / cm);
  }
  fmt::print("R0 = {:.2f} cm (EMC inner radius), R1 = {:.2f} cm, R_p3 = {:.2f} cm\n", d.r0() / cm,
             d.r1() / cm, d.rp3() / cm);
  fmt::print("Rings (counters per ring):");
  for (int n : d.countersPerRing) fmt::print(" {}", n);
  fmt::print("\nShower depth: X0 = {} cm, Ec = {} MeV, x_pre = {} X0\n", d.material.radiationLength,
             d.material.criticalEnergy, d.material.preshowerMaterial);
}

int printCounters(const Calorimeter& calo, const std::string& paramsPath) {
  std::optional<AlignmentTransform> transform;
  if (!paramsPath.empty()) {
    auto etaFile = io::readAlignmentFile(paramsPath, calo.description().r1());
    if (!etaFile) return reportError(etaFile.error());
    for (const auto& w : etaFile->warnings) reportWarning(w);
    const geometry::AlignmentParameters* eta = &etaFile->parameters;
    auto t = AlignmentTransform::create(*eta, AlignmentRadii::of(calo.description()));
    if (!t) return reportError(t.error());
    transform = std::move(*t);
  }
  std::string out = "index,layer,ring,iphi,hemisphere,theta_deg,phi_deg,x_cm,y_cm,z_cm\n";
  for (const Counter& c : calo.counters()) {
    Vec3 p = c.centre();
    if (transform) p = transform->forward(p, c.hemisphere, supportOfLayer(c.layer));
    out += fmt::format("{},{},{},{},{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}\n", c.index, c.layer,
                       c.ring, c.iphi, sign(c.hemisphere), polar(p) / deg, azimuth(p) / deg,
                       p.x() / cm, p.y() / cm, p.z() / cm);
  }
  fmt::print("{}", out);
  return 0;
}

int run(const GeometryOptions& o) {
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return reportError(calo.error());
  if (o.description) {
    fmt::print("{}\n", io::toJson(calo->description()).dump(2));
    return 0;
  }
  if (o.counters) return printCounters(*calo, o.params);
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
  auto* counters = cmd->add_flag(
      "--counters", opts->counters,
      "print every counter as CSV: index,layer,ring,iphi,hemisphere,theta_deg,phi_deg,x_cm,y_cm,z_cm");
  cmd->add_option("--params", opts->params,
                  "with --counters: actual centres in the TS frame for these alignment parameters "
                  "(layer 3 with the mu3 rule)")
      ->check(CLI::ExistingFile)
      ->needs(counters);
  auto* description = cmd->add_flag("--description", opts->description,
                                    "print the detector description JSON (the format --detector reads)");
  json->excludes(counters)->excludes(description);
  counters->excludes(description);
  cmd->callback([opts, &exitCode] { exitCode = run(*opts); });
}

}  // namespace emcalign::app
