// emcalign transform: the alignment transform of docs/contract.md §4 on points read from stdin.
//
//   stdin:  x_cm,y_cm,z_cm            (header line required; '#' lines are comments)
//   stdout: x_cm,y_cm,z_cm,hemisphere (17 significant digits)
// Forward (nominal → actual): the hemisphere is --hemisphere, or the sign of x of the input.
// Inverse (actual → nominal): the hemisphere is --hemisphere, or found (auto); points in the
// gap or in an overlap of the hemispheres are written with empty coordinates and the word
// "gap" or "overlap" in the hemisphere column.

#include <iostream>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/io/point_tables.hpp"
#include "emcalign/io/points_csv.hpp"

namespace emcalign::app {

namespace {

struct TransformOptions {
  std::string params;
  std::string detector;
  io::TransformGiven given;
};

int run(const TransformOptions& o) {
  auto calo = must(loadCalorimeter(o.detector));
  auto etaFile = must(loadAlignment(o.params, calo));
  for (const auto& w : etaFile.warnings) reportWarning(w);
  auto transform =
      must(geometry::AlignmentTransform::create(etaFile.parameters, geometry::AlignmentRadii::of(calo.description())));
  auto points = must(io::readPointsCsv(std::cin, "stdin"));
  const io::TransformedPoints out = io::transformPoints(transform, points, o.given);
  fmt::print("{}", out.csv);
  for (const auto& w : out.warnings) reportWarning(w);
  return 0;
}

}  // namespace

void addTransformCommand(CLI::App& app, int& exitCode) {
  auto opts = std::make_shared<TransformOptions>();
  auto* cmd = app.add_subcommand("transform",
                                 "Apply the alignment transform to points read as CSV x_cm,y_cm,z_cm on stdin "
                                 "(forward: nominal EMC -> actual position in the TS frame)");
  addVersionFlag(*cmd);
  cmd->add_option("--params", opts->params, "alignment parameter file (JSON, docs/conventions.md)")
      ->required()
      ->check(CLI::ExistingFile);
  addDetectorOption(*cmd, opts->detector);
  cmd->add_flag("--inverse", opts->given.inverse, "actual (TS frame) -> nominal EMC frame");
  cmd->add_option("--hemisphere", opts->given.hemisphere,
                  "auto (default: forward takes the sign of x of the input point, inverse finds "
                  "the hemisphere whose pre-image lies on its own side), +1 or -1")
      ->check(CLI::IsMember({"auto", "+1", "1", "-1"}));
  cmd->add_option("--layer", opts->given.layer, "1 or 2 (support sphere 1), 3 (support sphere 2, mu3 rule)")
      ->check(CLI::Range(1, 3));
  cmd->callback([opts, &exitCode] { exitCode = run(*opts); });
}

}  // namespace emcalign::app
