// emcalign report: one self-contained HTML page of a calibration (page/calibration_report.hpp):
//   report [--fit RESULT.json [--events EVENTS...] [--corrections C]] [--validation DIR]
//          [--compare DIR] [--trend DIR] [--conditions URI --tag T] [--checks DIR...] [--prompt STATE_DIR] [--title T]
//          -o report.html

#include <memory>
#include <string>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/page/report_given.hpp"

namespace emcalign::app {

namespace {

int run(const report::ReportGiven& g) {
  must(checkOutputs({{"-o", g.output}}, {}, report::reportInputs(g)));
  auto read = report::readReportInputs(g, [](std::size_t files) {
    say("drawing the fit's figures from {} event file{} ...\n", files, files == 1 ? "" : "s");
  });
  if (!read) return reportError(read.error());
  auto page = must(report::calibrationReport(read->inputs));
  must(io::writeOutputFile(g.output, page));
  say("wrote {} ({:.0f} kB)\n", g.output == "-" ? "the report to standard output" : g.output,
      static_cast<double>(page.size()) / 1024.0);
  return kExitOk;
}

}  // namespace

void addReportCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<report::ReportGiven>();
  auto* cmd = app.add_subcommand("report",
                                 "One self-contained HTML page of a calibration: the parameters, the profiles, the "
                                 "validation, the time evolution and the physics checks (docs/report.md)");
  addVersionFlag(*cmd);
  auto* fit = cmd->add_option("--fit", o->fit, "a fit result (emcalign fit -o)")->check(CLI::ExistingFile);
  cmd->add_option("--events", o->events,
                  "the fit's event files: the profiles with the fitted model and the residuals before and after the "
                  "correction")
      ->check(CLI::ExistingFile)
      ->needs(fit);
  cmd->add_option("--corrections", o->corrections,
                  "the corrections the fit used, when they are no longer where its result says (a file or a grid)")
      ->check(CLI::ExistingPath)
      ->needs(fit);
  cmd->add_option("--validation", o->validation, "a validation campaign's directory (emcalign validate -o)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--compare", o->compare, "a comparison of data with simulation (emcalign compare -o)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--trend", o->trend, "a trend's directory (emcalign trend -o)")->check(CLI::ExistingDirectory);
  cmd->add_option("--prompt", o->prompt, "a prompt loop's state directory (emcalign prompt -o STATE_DIR)")
      ->check(CLI::ExistingDirectory);
  auto* conditions = cmd->add_option("--conditions", o->conditions, "a conditions database: the IOVs of --tag");
  auto* tag = cmd->add_option("--tag", o->tag, "the tag of --conditions")->check(tagName());
  conditions->needs(tag);
  tag->needs(conditions);
  cmd->add_option("--checks", o->checks, "physics checks' directories (emcalign check -o)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--title", o->title, fmt::format("the page's title (default: {})", report::ReportInputs{}.title));
  addDetectorOption(*cmd, o->detector);
  cmd->add_option("-o,--output", o->output, "the HTML file; '-': standard output")->required();
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
