// emcalign geometry: the detector summary, the counter table (nominal or actual centres) and
// the detector description file.

#include <iostream>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "common.hpp"
#include "console.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/counter_geometry.hpp"
#include "emcalign/io/geometry_text.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/io/point_tables.hpp"
#include "emcalign/io/points_csv.hpp"

namespace emcalign::app {

namespace {

using namespace emcalign::geometry;

struct GeometryOptions {
  std::string detector;
  std::string params;
  bool json = false;
  bool counters = false;
  bool description = false;
  bool locate = false;
  std::string coordinates;  // empty: the historic columns
};

int run(const GeometryOptions& o) {
  if (!o.params.empty() && !o.counters && !o.locate) {
    eprint("emcalign: usage error: --params goes with --counters or --locate\n");
    return kExitUsage;
  }
  auto calo = must(loadCalorimeter(o.detector));
  if (o.description) {
    fmt::print("{}\n", io::toJson(calo.description()).dump(2));
    return 0;
  }
  if (o.counters || o.locate) {
    auto geometry = mustSaying([&](auto& w) { return apply::countersOf(calo, o.params, w); });
    // --locate: x_cm,y_cm,z_cm rows on stdin (TS frame) → the counter that contains each.
    fmt::print("{}", o.locate ? io::locatedPointsCsv(calo, geometry, must(io::readPointsCsv(std::cin, "stdin")))
                              : io::countersCsv(calo, geometry, o.coordinates));
    return 0;
  }
  fmt::print("{}", o.json ? io::detectorSummaryJson(calo).dump(2) + "\n" : io::detectorSummaryText(calo));
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
