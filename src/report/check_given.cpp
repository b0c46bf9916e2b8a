#include "emcalign/report/check_given.hpp"

#include <filesystem>

#include <fmt/format.h>

#include "emcalign/apply/check_record.hpp"
#include "emcalign/conddb/database_to_write.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/report/check_plots.hpp"

namespace emcalign::report {

namespace {

namespace fs = std::filesystem;

// The numbers of the check and its figure, of either process.
// clang-tidy cannot prove the destructor of its io::Json member non-throwing (nlohmann::json
// asserts its invariant there); it does not throw.
// NOLINTNEXTLINE(bugprone-exception-escape)
struct CheckFound {
  apply::CheckRecord record;
  CheckFigure figure;
};

template <typename Check>
Result<CheckFound> found(const Result<Check>& check, apply::CheckProcess process) {
  if (!check) return check.error();
  if (Status st = check->cutFlow.requireSelected(process); !st) return st.error();
  CheckFound f;
  f.record = apply::checkRecord(*check);
  f.figure = checkFigure(*check, f.record);
  return f;
}

}  // namespace

std::vector<io::NamedPath> checkInputs(const CheckGiven& given) {
  std::vector<io::NamedPath> inputs;
  for (const auto& e : given.events) inputs.push_back({"", e});
  inputs.push_back({"--alignment", given.alignment});
  inputs.push_back({"--corrections", given.corrections});
  inputs.push_back({"--detector", given.detector});
  for (auto& c : conddb::databaseFiles(given.conditions)) inputs.push_back(std::move(c));
  return inputs;
}

Result<apply::CorrectOptions> checkCorrectOptions(const CheckGiven& given, const io::Json& alignment,
                                                  const geometry::Calorimeter& calo) {
  auto options = apply::correctOptionsOf(given.method, 0.0, given.corrections, calo);
  if (!options) return options.error();
  io::Json record = apply::correctionRecord(alignment, given.method, *options, given.events, given.corrections);
  record["purpose"] = fmt::format("emcalign check {}", name(given.process));
  options->description = record.dump();
  return options;
}

Result<std::unique_ptr<io::OutputFile>> reserveCheckScratch(const std::string& outputDir) {
  std::error_code ec;
  fs::create_directories(outputDir, ec);
  if (ec) return Error{fmt::format("{}: cannot create the directory: {}", outputDir, ec.message())};
  return io::OutputFile::reserve((fs::path(outputDir) / "corrected.h5").string(), io::Placement::InDirectory);
}

Result<std::string> writeCheck(const CheckGiven& given, const std::string& corrected,
                               const apply::CorrectOptions& options, const apply::CorrectReport& report,
                               const io::Json& alignment) {
  // The kinematic fit's R(E, θ), of each event's beam energy with a corrections grid.
  auto f =
      given.process == apply::CheckProcess::GammaGamma
          ? found(apply::checkGammaGamma(given.events, {corrected}), given.process)
          : found(apply::checkThreePion(given.events, {corrected},
                                        options.depthAt ? options.depthAt : geometry::atEveryEnergy(options.depth)),
                  given.process);
  if (!f) return f.error();
  f->record.alignment = alignment;
  f->record.correctionMethod = std::string(name(report.method));
  f->record.inputs = given.events;
  f->record.software = fmt::format("emcalign {}", kVersion);
  const CheckFigure& figure = f->figure;
  auto png = writeBeforeAfterPlot(given.output, figure.name, figure.title, figure.panels);
  if (!png) return Error{fmt::format("{} (check.json not written)", png.error().message)};
  if (Status s = io::writeFileIn(given.output, "check.json", apply::checkJson(f->record).dump(1) + "\n"); !s) {
    return s.error();
  }
  return fmt::format("{}\nwrote {}/check.json and {}\n", figure.summary, given.output, *png);
}

}  // namespace emcalign::report
