// emcalign params show: both parameter sets of an alignment file, as a table or JSON.

#include <memory>
#include <string>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::app {

namespace {

using namespace emcalign::geometry;

struct ShowOptions {
  std::string file;
  std::string detector;
  bool json = false;
};

const char* unitName(Dimension d) { return d == Dimension::Angle ? "deg" : "cm"; }

int runShow(const ShowOptions& o) {
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return reportError(calo.error());
  const double r1 = calo->description().r1();
  auto etaFile = loadAlignment(o.file, *calo);
  if (!etaFile) return reportError(etaFile.error());
  for (const auto& w : etaFile->warnings) reportWarning(w);
  const geometry::AlignmentParameters* eta = &etaFile->parameters;
  auto j = io::alignmentToJsonWithPhysical(*eta, r1);
  if (!j) return reportError(j.error());
  if (o.json) {
    fmt::print("{}\n", j->dump(2));
    return 0;
  }
  auto phys = toPhysical(*eta, r1);
  fmt::print("{:<10} {:>14}  {:<4}    {:<10} {:>14}  {:<4}\n", "fit set", "value", "unit", "physical", "value", "unit");
  for (std::size_t i = 0; i < kNumParams; ++i) {
    const auto p = kAllParams[i];
    const auto q = static_cast<Physical>(i);
    fmt::print("{:<10} {:>14}  {:<4}    {:<10} {:>14}  {:<4}\n", name(p),
               fixed((*eta)[p] / AlignmentParameters::fileUnit(p), 6), unitName(dimension(p)), name(q),
               fixed((*phys)[q] / PhysicalParameters::fileUnit(q), 6), unitName(dimension(q)));
  }
  fmt::print(
      "(beta1, beta2 are sin(beta)cos(psi), sin(beta)sin(psi) written in degrees; "
      "R1 = {} cm)\n",
      r1 / units::cm);
  auto t = AlignmentTransform::create(*eta, AlignmentRadii::of(calo->description()));
  if (t && t->layer3RuleActive()) {
    fmt::print("Layer 3: dx_rel - R_p3*sin(mu) < 0, so layer 3 uses mu3 = asin(dx_rel/R_p3) = {} deg\n",
               fixed(std::asin((*phys)[Physical::DxRel] / calo->description().rp3()) / units::deg, 6));
  }
  return 0;
}

}  // namespace

void addParamsCommand(CLI::App& app, int& exitCode) {
  auto* cmd = app.add_subcommand("params", "Alignment parameter files");
  addVersionFlag(*cmd);
  cmd->require_subcommand(1);
  auto opts = std::make_shared<ShowOptions>();
  auto* show = cmd->add_subcommand("show", "Print both parameter sets (fit set and physical set) of a file");
  addVersionFlag(*show);
  show->add_option("file", opts->file, "alignment parameter file (JSON, docs/conventions.md)")
      ->required()
      ->check(CLI::ExistingFile);
  addDetectorOption(*show, opts->detector);
  show->add_flag("--json", opts->json, "print JSON with keys \"parameters\" and \"physical\" (deg, cm)");
  show->callback([opts, &exitCode] { exitCode = runShow(*opts); });
}

}  // namespace emcalign::app
