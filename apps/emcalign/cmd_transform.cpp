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
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/io/points_csv.hpp"

namespace emcalign::app {

namespace {

using namespace emcalign::geometry;
using units::cm;

struct TransformOptions {
  std::string params;
  std::string detector;
  bool inverse = false;
  std::string hemisphere = "auto";
  int layer = 1;
};

int run(const TransformOptions& o) {
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return reportError(calo.error());
  auto etaFile = loadAlignment(o.params, *calo);
  if (!etaFile) return reportError(etaFile.error());
  for (const auto& w : etaFile->warnings) reportWarning(w);
  const geometry::AlignmentParameters* eta = &etaFile->parameters;
  auto transform = AlignmentTransform::create(*eta, AlignmentRadii::of(calo->description()));
  if (!transform) return reportError(transform.error());
  const Support support = supportOfLayer(o.layer);
  std::optional<Hemisphere> fixed;
  if (o.hemisphere == "+1" || o.hemisphere == "1") fixed = Hemisphere::Plus;
  if (o.hemisphere == "-1") fixed = Hemisphere::Minus;

  std::string out = "x_cm,y_cm,z_cm,hemisphere\n";
  auto points = io::readPointsCsv(std::cin, "stdin");
  if (!points) return reportError(points.error());
  long gaps = 0, overlaps = 0;
  for (const Vec3& p : *points) {
    Vec3 q;
    Hemisphere h = Hemisphere::Plus;
    if (!o.inverse) {
      h = fixed.value_or(hemisphereOf(p.x()));
      q = transform->forward(p, h, support);
    } else if (fixed) {
      h = *fixed;
      q = transform->inverse(p, h, support);
    } else {
      const InverseResult r = transform->inverseAuto(p, support);
      if (r.kind != InverseKind::Unique) {
        const bool gap = r.kind == InverseKind::Gap;
        (gap ? gaps : overlaps) += 1;
        out += gap ? ",,,gap\n" : ",,,overlap\n";
        continue;
      }
      h = r.hemisphere;
      q = r.point;
    }
    out += fmt::format("{:.17g},{:.17g},{:.17g},{}\n", q.x() / cm, q.y() / cm, q.z() / cm, sign(h));
  }
  fmt::print("{}", out);
  if (gaps > 0) reportWarning(fmt::format("{} point(s) lie in the gap between the hemispheres", gaps));
  if (overlaps > 0) reportWarning(fmt::format("{} point(s) lie where the hemispheres overlap", overlaps));
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
  cmd->add_flag("--inverse", opts->inverse, "actual (TS frame) -> nominal EMC frame");
  cmd->add_option("--hemisphere", opts->hemisphere,
                  "auto (default: forward takes the sign of x of the input point, inverse finds "
                  "the hemisphere whose pre-image lies on its own side), +1 or -1")
      ->check(CLI::IsMember({"auto", "+1", "1", "-1"}));
  cmd->add_option("--layer", opts->layer, "1 or 2 (support sphere 1), 3 (support sphere 2, mu3 rule)")
      ->check(CLI::Range(1, 3));
  cmd->callback([opts, &exitCode] { exitCode = run(*opts); });
}

}  // namespace emcalign::app
