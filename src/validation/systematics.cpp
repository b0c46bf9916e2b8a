// A systematic study (validation/systematics.hpp): the campaigns with the simulation varied,
// forward and (--reverse) through corrections derived with each variation, their shifts
// combined per parameter; in one process or as a plan's tasks.

#include "emcalign/validation/systematics.hpp"
#include "emcalign/core/text.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include <fmt/format.h>

#include "emcalign/core/paper.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/report/systematics_plot.hpp"
#include "emcalign/validation/task_plan.hpp"
#include "systematics_internal.hpp"

namespace emcalign::validation {

namespace {

namespace fs = std::filesystem;
using io::Json;

// Sample i of a varied campaign against sample i of the reference one: as a "truth" the
// reference fit, so that tabulate's bias is the mean of fit(variation) − fit(reference), its
// error their spread/√n, with ψ and τ by the shortest angle and the derived parameters
// against the reference fit's (the same conversion).
std::vector<SampleResult> pairedWith(const std::vector<SampleResult>& varied,
                                     const std::vector<SampleResult>& reference) {
  std::vector<SampleResult> out;
  for (std::size_t i = 0; i < varied.size() && i < reference.size(); ++i) {
    SampleResult s = varied[i];
    s.truth = reference[i].fit.parameters;
    out.push_back(std::move(s));
  }
  return out;
}

// The settings a reverse study's derivation records (its file is kept by a rerun only when
// they are the same): the derivation's statistics and seed, the variation, and the campaign's
// simulation settings (the corrections of the forward campaigns play no part).
Json reverseSettings(const DerivationOptions& d, const CampaignOptions& campaign, const Variation* v) {
  Json simulation = campaign.settings;
  simulation.erase("corrections");
  simulation.erase("variation");
  simulation.erase("variation_pattern");
  Json j = {{"study", "emcalign systematics --reverse"},
            {"variation", v ? Json(v->name) : Json(nullptr)},
            {"events_per_sample", d.events},
            {"seed", d.seed},
            {"shift_cm", d.shift},
            {"gap_cm", d.gap},
            {"response_samples", d.responseSamples},
            {"response_events_per_sample", d.responseEvents},
            {"beam_energy_mev", campaign.simulation.generator.beamEnergy / units::MeV},
            {"campaign", simulation}};
  if (v != nullptr && v->pattern != nullptr) j["variation_pattern"] = "one, drawn from the derivation's seed";
  return j;
}

// The corrections of the reverse study with variation `v` (none: the nominal simulation):
// those in `file` when derived with the same settings, else derived and written there.
Result<calib::ModelCorrections> reverseCorrections(const geometry::Calorimeter& calo, DerivationOptions d,
                                                   const CampaignOptions& campaign, const Variation* v,
                                                   const std::string& file,
                                                   const std::function<void(std::int64_t)>& eventsDone) {
  const Json settings = reverseSettings(d, campaign, v);
  if (fs::exists(file)) {
    auto text = io::readOwnOutput(file);
    if (!text) return text.error();
    auto j = io::parseJson(*text, file);
    if (!j) return j.error();
    const Json* recorded =
        j->contains("derived_from") && (*j)["derived_from"].is_object() ? &(*j)["derived_from"] : nullptr;
    if (recorded == nullptr || !recorded->contains("settings") || (*recorded)["settings"] != settings) {
      return Error{fmt::format(
          "{} was derived with other settings than this study's: use another directory, or remove it", file)};
    }
    return calib::parseCorrections(*j, file);
  }
  if (campaign.onlyFinished) return Error{fmt::format("{}: missing (its task has not run)", file)};
  d.simulation = campaign.simulation;
  if (v != nullptr) {
    v->apply(d.simulation);
    if (v->pattern != nullptr) v->pattern(d.simulation, d.seed, calo.size());
  }
  d.responseRanges = campaign.ranges;
  auto report = deriveCorrections(calo, d, simulatedEventsProgress(eventsDone));
  if (!report) return report.error();
  const Json content = derivationJson(*report, settings);
  if (Status s = io::writeOutputFile(file, content.dump(2) + "\n", io::Placement::InDirectory); !s) return s.error();
  return calib::parseCorrections(content, file);
}

// The reverse study's corrections of `name` ("nominal" or a variation's), and the campaign
// fitting the nominal samples with them.
std::string reverseCorrectionsFile(const std::string& dir, const std::string& name) {
  return (fs::path(dir) / "reverse" / "corrections" / (name + ".json")).string();
}
CampaignOptions reverseCampaign(const CampaignOptions& nominal, calib::ModelCorrections corrections,
                                const std::string& name) {
  CampaignOptions o = nominal;
  o.corrections = std::move(corrections);
  o.settings["corrections"] = {{"reverse", name}, {"fnv1a", calib::correctionsDigest(o.corrections)}};
  return o;
}

std::vector<const Variation*> variationsOf(const SystematicsOptions& options) {
  std::vector<const Variation*> v = options.variations;
  if (v.empty()) {
    for (const auto& each : variations()) v.push_back(&each);
  }
  return v;
}

// Keeps the larger of `envelope` and `effect`; a NaN effect makes it NaN for good (never dropped).
void widen(double& envelope, double effect) {
  if (std::isnan(envelope)) return;
  if (!(envelope >= effect)) envelope = effect;
}

}  // namespace

CampaignOptions withVariation(CampaignOptions options, const Variation& variation) {
  variation.apply(options.simulation);
  options.settings["variation"] = variation.name;
  if (variation.pattern != nullptr) {
    options.samplePattern = variation.pattern;
    options.settings["variation_pattern"] = "drawn per sample from its own stream";
  }
  return options;
}

namespace {

// The events of the whole study and of those finished, for one progress over all its parts.
class StudyProgress {
 public:
  StudyProgress(const SystematicsOptions& options, std::size_t variations, SystematicsProgress report)
      : eventsPerSample_(options.campaign.events), report_(std::move(report)) {
    campaignEvents_ = static_cast<std::int64_t>(options.campaign.samples) * options.campaign.events;
    const auto& r = options.reverse;
    derivationEvents_ = r ? 3 * r->events + r->responseSamples * r->responseEvents : 0;
    const auto runs = static_cast<std::int64_t>(variations + 1);
    total_ = runs * campaignEvents_ * (r ? 2 : 1) + runs * derivationEvents_;
  }
  [[nodiscard]] CampaignProgress campaign() const {
    return [this](int done, int) { show(finished_ + done * eventsPerSample_); };
  }
  [[nodiscard]] std::function<void(std::int64_t)> derivation() const {
    return [this](std::int64_t done) { show(finished_ + done); };
  }
  void campaignDone() { finished_ += campaignEvents_; }
  void derivationDone() { finished_ += derivationEvents_; }

 private:
  void show(std::int64_t done) const {
    if (report_) report_(done, total_);
  }
  std::int64_t eventsPerSample_, campaignEvents_ = 0, derivationEvents_ = 0, total_ = 0, finished_ = 0;
  SystematicsProgress report_;
};

// The forward study: the nominal campaign and one per variation, each variation's samples
// paired with the nominal ones.
Status runForward(const geometry::Calorimeter& calo, const SystematicsOptions& options,
                  const std::vector<const Variation*>& variations, const std::string& dir, StudyProgress& progress,
                  SystematicShifts& measured) {
  const CampaignOptions& nominalOptions = options.campaign;
  std::vector<SampleResult> nominal;
  auto nominalTable =
      runCampaign(calo, nominalOptions, (fs::path(dir) / "nominal").string(), progress.campaign(), &nominal);
  if (!nominalTable) return Error{fmt::format("the nominal campaign: {}", nominalTable.error().message)};
  progress.campaignDone();
  measured.nominal = std::move(*nominalTable);
  const double r1 = calo.description().r1();
  for (const Variation* v : variations) {
    const CampaignOptions o = withVariation(nominalOptions, *v);
    std::vector<SampleResult> varied;
    auto table = runCampaign(calo, o, (fs::path(dir) / v->name).string(), progress.campaign(), &varied);
    if (!table) return Error{fmt::format("variation {}: {}", v->name, table.error().message)};
    progress.campaignDone();
    measured.shifts.push_back(tabulate(pairedWith(varied, nominal), o.events, r1));
  }
  return {};
}

// The reverse study: the nominal samples fitted with corrections derived with each variation
// and without, paired with the latter. Returns the derivations' settings.
Result<Json> runReverse(const geometry::Calorimeter& calo, const SystematicsOptions& options,
                        const std::vector<const Variation*>& variations, const std::string& dir,
                        StudyProgress& progress, SystematicShifts& measured) {
  const CampaignOptions& nominalOptions = options.campaign;
  const fs::path base = fs::path(dir) / "reverse";
  std::error_code ec;
  if (!nominalOptions.onlyFinished) fs::create_directories(base / "corrections", ec);
  if (ec)
    return Error{fmt::format("{}: cannot create the directory: {}", (base / "corrections").string(), ec.message())};
  const double r1 = calo.description().r1();
  std::vector<SampleResult> reference;
  for (std::size_t j = 0; j <= variations.size(); ++j) {
    const Variation* v = j == 0 ? nullptr : variations[j - 1];
    const std::string name = v ? v->name : "nominal";
    auto corrections = reverseCorrections(calo, *options.reverse, nominalOptions, v, reverseCorrectionsFile(dir, name),
                                          progress.derivation());
    if (!corrections) return Error{fmt::format("the reverse study, {}: {}", name, corrections.error().message)};
    progress.derivationDone();
    const CampaignOptions o = reverseCampaign(nominalOptions, std::move(*corrections), name);
    std::vector<SampleResult> fitted;
    auto table = runCampaign(calo, o, (base / name).string(), progress.campaign(), &fitted);
    if (!table) return Error{fmt::format("the reverse study, {}: {}", name, table.error().message)};
    progress.campaignDone();
    if (v == nullptr) {
      measured.reverseNominal = std::move(*table);
      reference = std::move(fitted);
    } else {
      measured.reverseShifts.push_back(tabulate(pairedWith(fitted, reference), o.events, r1));
    }
  }
  Json settings = reverseSettings(*options.reverse, nominalOptions, nullptr);
  settings.erase("variation");
  return settings;
}

// Table k of `tables` (one per variation) has the rows of `nominal`, in its order.
Status sameRows(const Table& nominal, const std::vector<Table>& tables, std::size_t variations, const char* what) {
  if (tables.size() != variations) {
    return Error{fmt::format("{}: {} tables for {}", what, tables.size(), counted(variations, "variation"))};
  }
  for (const Table& t : tables) {
    bool same = t.rows.size() == nominal.rows.size();
    for (std::size_t k = 0; same && k < t.rows.size(); ++k) same = t.rows[k].name == nominal.rows[k].name;
    if (!same) return Error{fmt::format("{}: a table's parameters differ from the nominal campaign's", what)};
  }
  return {};
}

}  // namespace

Result<std::vector<SystematicsRow>> combineSystematics(const std::vector<const Variation*>& variations,
                                                       const std::vector<std::string>& quantities,
                                                       const SystematicShifts& measured) {
  if (Status s = sameRows(measured.nominal, measured.shifts, variations.size(), "the shifts"); !s) return s.error();
  if (measured.reverseNominal) {
    if (Status s = sameRows(measured.nominal, measured.reverseShifts, variations.size(), "the reverse shifts"); !s)
      return s.error();
    if (Status s = sameRows(measured.nominal, {*measured.reverseNominal}, 1, "the reverse nominal fits"); !s)
      return s.error();
  }
  std::vector<std::size_t> quantityOf;
  for (const Variation* v : variations) {
    auto q = std::find(quantities.begin(), quantities.end(), v->quantity);
    if (q == quantities.end())
      return Error{fmt::format("variation {}: its quantity {} is not listed", v->name, v->quantity)};
    quantityOf.push_back(static_cast<std::size_t>(q - quantities.begin()));
  }
  std::vector<SystematicsRow> rows;
  for (std::size_t k = 0; k < measured.nominal.rows.size(); ++k) {
    const TableRow& n = measured.nominal.rows[k];
    SystematicsRow row{n.name};
    row.bias = n.bias;
    row.biasError = n.biasError;
    row.spread = n.spread;
    row.envelope.assign(quantities.size(), 0.0);
    for (std::size_t j = 0; j < variations.size(); ++j) {
      const TableRow& s = measured.shifts[j].rows[k];
      row.shift.push_back(s.bias);
      row.shiftError.push_back(s.biasError);
      row.shiftSpread.push_back(s.spread);
      row.effect.push_back(variations[j]->pattern != nullptr ? std::hypot(s.bias, s.spread) : std::abs(s.bias));
      widen(row.envelope[quantityOf[j]], row.effect.back());
    }
    if (measured.reverseNominal) {
      row.reverseBias = measured.reverseNominal->rows[k].bias;
      row.reverseBiasError = measured.reverseNominal->rows[k].biasError;
      for (std::size_t j = 0; j < variations.size(); ++j) {
        const TableRow& s = measured.reverseShifts[j].rows[k];
        row.reverseShift.push_back(s.bias);
        row.reverseShiftError.push_back(s.biasError);
        widen(row.envelope[quantityOf[j]], std::abs(s.bias));
      }
    }
    double sum2 = 0.0;
    for (double e : row.envelope) sum2 += e * e;
    row.systematic = std::sqrt(sum2);
    rows.push_back(std::move(row));
  }
  return rows;
}

Status SystematicsOptions::validate() const {
  if (campaign.samples < 2) {
    return Error{"a systematic study needs 2 samples at least: a shift's error and a pattern's spread come from them"};
  }
  if (Status s = campaign.validate(); !s) return s.error();
  if (reverse) {
    if (Status s = reverse->validate(); !s) {
      // Its options, as systematics names them: --reverse-events, --reverse-response-samples, ...
      std::string message = s.error().message;
      for (auto at = message.find("--"); at != std::string::npos; at = message.find("--", at + 10)) {
        message.insert(at + 2, "reverse-");
      }
      return Error{fmt::format("the reverse study: {}", message)};
    }
  }
  return {};
}

Result<SystematicsTable> runSystematics(const geometry::Calorimeter& calo, const SystematicsOptions& options,
                                        const std::string& dir, const SystematicsProgress& progress) {
  SystematicsTable t;
  t.variations = variationsOf(options);
  t.samples = options.campaign.samples;
  t.events = options.campaign.events;
  if (Status s = options.validate(); !s) return s.error();
  for (const Variation* v : t.variations) {
    if (std::find(t.quantities.begin(), t.quantities.end(), v->quantity) == t.quantities.end())
      t.quantities.push_back(v->quantity);
  }
  StudyProgress studyProgress(options, t.variations.size(), progress);
  SystematicShifts measured;
  if (Status s = runForward(calo, options, t.variations, dir, studyProgress, measured); !s) return s.error();
  if (options.reverse) {
    auto settings = runReverse(calo, options, t.variations, dir, studyProgress, measured);
    if (!settings) return settings.error();
    t.reverse = std::move(*settings);
  }
  auto rows = combineSystematics(t.variations, t.quantities, measured);
  if (!rows) return rows.error();
  t.rows = std::move(*rows);
  if (Status s = writeSystematics(t, dir); !s) return s.error();
  return t;
}

namespace {

// The study as a plan's tasks: the reverse derivations first (the longest), then every sample
// of every campaign. A reverse campaign's sample needs its derivation: it takes the
// derivation's lock and derives it itself when no task has yet (the work of the derivation's
// own task, which then finds it done).
class SystematicsJob final : public PlannedJob {
 public:
  SystematicsJob(geometry::Calorimeter calo, SystematicsOptions o, std::string dir, std::vector<std::string> inputs,
                 int samplesPerTask)
      : calo_(std::move(calo)), o_(std::move(o)), dir_(std::move(dir)), inputs_(std::move(inputs)) {
    variations_ = variationsOf(o_);
    forward_.push_back({"nominal", nullptr});
    for (const Variation* v : variations_) forward_.push_back({v->name, v});
    const int derivations = o_.reverse ? static_cast<int>(forward_.size()) : 0;
    const int campaigns = static_cast<int>(forward_.size()) * (o_.reverse ? 2 : 1);
    blocks_ = sampleBlocks(o_.campaign.samples, samplesPerTask, campaigns, derivations);
  }

  // The tasks in order: the reverse derivations, then each forward campaign's blocks of
  // samples, then each reverse campaign's.
  [[nodiscard]] std::vector<PlannedTask> tasks() const override {
    std::vector<PlannedTask> t;
    if (o_.reverse) {
      for (const auto& [name, v] : forward_) {
        t.push_back({fmt::format("the reverse study's corrections derived with {}", v ? name : "no variation"),
                     {absolute(reverseCorrectionsFile(dir_, name))},
                     inputs_});
      }
    }
    for (int reverse = 0; reverse <= (o_.reverse ? 1 : 0); ++reverse) {
      for (const auto& [name, v] : forward_) {
        const std::string campaign = reverse != 0 ? reverseDirOf(name) : dirOf(name);
        for (const SampleBlock& b : blocks_) {
          PlannedTask task{fmt::format("{} of {}", samplesText(b), campaign), {}, inputs_};
          // A reverse sample fits with its derivation's corrections (instead of --corrections).
          if (reverse != 0) task.inputs.push_back(absolute(reverseCorrectionsFile(dir_, name)));
          for (int i = b.first; i <= b.last; ++i) task.writes.push_back(absolute(sampleFile(campaign, i)));
          t.push_back(std::move(task));
        }
      }
    }
    return t;
  }

  Status runTask(std::size_t k, const TaskContext& context) const override {
    const std::size_t derivations = o_.reverse ? forward_.size() : 0;
    if (k < derivations) {
      auto c = corrections(k, context);
      return c ? Status{} : Status{c.error()};
    }
    k -= derivations;
    const std::size_t campaign = k / blocks_.size();
    const SampleBlock& b = blocks_[k % blocks_.size()];
    const bool reverse = campaign >= forward_.size();
    const auto& [name, v] = forward_[campaign % forward_.size()];
    CampaignOptions o;
    if (reverse) {
      auto c = corrections(campaign % forward_.size(), context);
      if (!c) return c.error();
      o = reverseCampaign(o_.campaign, std::move(*c), name);
    } else {
      o = v ? withVariation(o_.campaign, *v) : o_.campaign;
    }
    for (int i = b.first; i <= b.last; ++i) {
      if (Status s = runSample(calo_, o, reverse ? reverseDirOf(name) : dirOf(name), i); !s) return s;
    }
    return {};
  }

  // A forward campaign's sample: kept when it is a finished sample of that campaign. (A reverse
  // one depends on its derivation's corrections, a derivation on its settings: not told.)
  [[nodiscard]] std::optional<bool> keeps(std::size_t k, const std::string& output) const override {
    const std::size_t derivations = o_.reverse ? forward_.size() : 0;
    if (k < derivations || (k - derivations) / blocks_.size() >= forward_.size()) return std::nullopt;
    const auto& [name, v] = forward_[(k - derivations) / blocks_.size()];
    const SampleBlock& b = blocks_[(k - derivations) % blocks_.size()];
    const CampaignOptions o = v ? withVariation(o_.campaign, *v) : o_.campaign;
    for (int i = b.first; i <= b.last; ++i) {
      if (absolute(sampleFile(dirOf(name), i)) == output) return isFinishedSample(calo_, o, dirOf(name), i);
    }
    return std::nullopt;
  }

 private:
  static std::string absolute(const std::string& p) { return fs::absolute(p).lexically_normal().string(); }
  [[nodiscard]] std::string dirOf(const std::string& name) const { return (fs::path(dir_) / name).string(); }
  [[nodiscard]] std::string reverseDirOf(const std::string& name) const {
    return (fs::path(dir_) / "reverse" / name).string();
  }

  // Derivation j's corrections, derived under its lock when not yet there.
  Result<calib::ModelCorrections> corrections(std::size_t j, const TaskContext& context) const {
    const auto& [name, v] = forward_[j];
    const std::string file = reverseCorrectionsFile(dir_, name);
    std::error_code ec;
    fs::create_directories(fs::path(file).parent_path(), ec);
    if (ec)
      return Error{
          fmt::format("{}: cannot create the directory: {}", fs::path(file).parent_path().string(), ec.message())};
    if (!fs::exists(file)) {
      context.say(fmt::format("the reverse study's corrections {}: waiting for them, or deriving them", file));
    }
    // The lock lives in the plan's work directory: the study's directory holds what the
    // one-process study writes, nothing else.
    const FileLock lock((fs::path(context.workDirectory) / ("reverse-" + name + ".lock")).string());
    if (!lock.error().empty()) return Error{lock.error()};
    auto c = reverseCorrections(calo_, *o_.reverse, o_.campaign, v, file, [](std::int64_t) {});
    if (!c) return Error{fmt::format("the reverse study, {}: {}", name, c.error().message)};
    return c;
  }

  geometry::Calorimeter calo_;
  SystematicsOptions o_;
  std::string dir_;
  std::vector<std::string> inputs_;
  std::vector<const Variation*> variations_;
  std::vector<std::pair<std::string, const Variation*>> forward_;  // nominal, then each variation
  std::vector<SampleBlock> blocks_;                                // of each campaign
};

}  // namespace

Status checkPlannedSystematics(const geometry::Calorimeter& calo, const SystematicsOptions& options,
                               const std::string& dir) {
  if (Status s = options.validate(); !s) return s;
  // Each forward campaign as its plan is checked (a reverse one fits with corrections its tasks
  // derive: its samples are checked when they run).
  if (Status s = checkPlannedCampaign(calo, options.campaign, (fs::path(dir) / "nominal").string()); !s) return s;
  for (const Variation* v : variationsOf(options)) {
    const CampaignOptions o = withVariation(options.campaign, *v);
    if (Status s = checkPlannedCampaign(calo, o, (fs::path(dir) / v->name).string()); !s) return s;
  }
  return {};
}

Result<std::unique_ptr<PlannedJob>> systematicsJob(geometry::Calorimeter calo, SystematicsOptions options,
                                                   std::string dir, std::vector<std::string> inputs,
                                                   int samplesPerTask) {
  if (Status s = options.validate(); !s) return s.error();
  if (Status s = options.campaign.simulation.validate(calo.size()); !s) return s.error();
  return std::unique_ptr<PlannedJob>(std::make_unique<SystematicsJob>(
      std::move(calo), std::move(options), std::move(dir), std::move(inputs), samplesPerTask));
}

}  // namespace emcalign::validation
