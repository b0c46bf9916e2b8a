// emcalign params show: both parameter sets of an alignment file, as a table or JSON.

#include <memory>
#include <string>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/calib/fit_notes.hpp"
#include "emcalign/io/geometry_text.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::app {

namespace {

struct ShowOptions {
  std::string file;
  std::string detector;
  bool json = false;
};

int runShow(const ShowOptions& o) {
  auto calo = must(loadCalorimeter(o.detector));
  auto etaFile = must(loadAlignment(o.file, calo));
  for (const auto& w : etaFile.warnings) reportWarning(w);
  if (auto w = calib::parametersRangeWarning(etaFile.parameters, calo.description().r1())) reportWarning(*w);
  auto j = must(io::alignmentToJsonWithPhysical(etaFile.parameters, calo.description().r1()));
  if (o.json) {
    fmt::print("{}\n", j.dump(2));
    return 0;
  }
  auto table = must(io::alignmentTableText(etaFile.parameters, calo.description()));
  fmt::print("{}", table);
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
