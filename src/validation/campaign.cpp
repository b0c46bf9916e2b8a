// A validation campaign (validation/campaign.hpp): its ranges and truths, each sample simulated,
// fitted and kept in a file (in one process or as a plan's tasks), and the whole campaign run.

#include "emcalign/validation/campaign.hpp"
#include "emcalign/core/text.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numbers>
#include <optional>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "campaign_internal.hpp"
#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/fit_notes.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/strict_json.hpp"
#include "emcalign/report/campaign_plots.hpp"

namespace emcalign::validation {

namespace fs = std::filesystem;
using geometry::AlignmentParameters;
using geometry::PhysicalParameters;
using io::Json;
using io::strict::StrictObject;
using units::deg;

namespace {

constexpr std::string_view kRangesFormat = "emcalign-validation-ranges/1";
constexpr std::string_view kSampleFormat = "emcalign-validation-sample/1";

std::uint64_t sampleSeed(std::uint64_t seed, int index) {
  Rng rng(seed ^ 0x5EEDULL, static_cast<std::uint64_t>(index) + (1ULL << 40));
  return rng.next();
}

}  // namespace

Ranges Ranges::defaults() {
  Ranges r;
  r.physical = calib::validatedRanges();  // the ranges the fit's notes check against
  return r;
}

Status Ranges::validate() const {
  for (std::size_t k = 0; k < kNumParams; ++k) {
    const auto [lo, hi] = physical[k];
    const auto p = static_cast<Physical>(k);
    if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi) {
      return Error{fmt::format("range of '{}': need finite low <= high, got [{}, {}]", name(p), lo / fileUnitOf(p),
                               hi / fileUnitOf(p))};
    }
  }
  const auto beta = physical[index(Physical::Beta)], mu = physical[index(Physical::Mu)];
  if (beta.first < 0.0 || beta.second >= 90.0 * deg) return Error{"range of 'beta' must lie in [0, 90) deg"};
  if (mu.first < 0.0 || mu.second >= 90.0 * deg) return Error{"range of 'mu' must lie in [0, 90) deg"};
  return {};
}

Result<Ranges> readRanges(const std::string& path) {
  auto text = io::readTextFile(path);
  if (!text) return text.error();
  auto j = io::parseJson(*text, path);
  if (!j) return j.error();
  Ranges r = Ranges::defaults();
  if (!j->is_object()) return Error{fmt::format("{}: expected a JSON object", path)};
  if (Status s = io::strict::checkKeys(*j, {"format", "ranges", "mu_below_gapless"}, {.source = path}); !s)
    return s.error();
  if (!j->contains("format") || (*j)["format"] != kRangesFormat) {
    return Error{fmt::format("{}: key 'format': expected \"{}\"", path, kRangesFormat)};
  }
  if (j->contains("mu_below_gapless")) {
    if (!(*j)["mu_below_gapless"].is_boolean())
      return Error{fmt::format("{}: key 'mu_below_gapless': expected true or false", path)};
    r.muBelowGapless = (*j)["mu_below_gapless"].get<bool>();
  }
  if (j->contains("ranges")) {
    const Json& ranges = (*j)["ranges"];
    if (!ranges.is_object()) return Error{fmt::format("{}: key 'ranges': expected an object", path)};
    for (const auto& [key, value] : ranges.items()) {
      std::optional<Physical> p;
      for (std::size_t k = 0; k < kNumParams; ++k) {
        if (kPhysicalNames[k] == key) p = static_cast<Physical>(k);
      }
      if (!p) {
        return Error{fmt::format("{}: key 'ranges.{}': unknown parameter (the physical set: {})", path, key,
                                 fmt::join(kPhysicalNames, ", "))};
      }
      if (!value.is_array() || value.size() != 2 || !value[0].is_number() || !value[1].is_number()) {
        return Error{fmt::format("{}: key 'ranges.{}': expected [low, high] in deg or cm", path, key)};
      }
      r.physical[index(*p)] = {value[0].get<double>() * fileUnitOf(*p), value[1].get<double>() * fileUnitOf(*p)};
    }
  }
  if (Status s = r.validate(); !s) return Error{fmt::format("{}: {}", path, s.error().message)};
  return r;
}

AlignmentParameters drawTruth(const Ranges& ranges, double r1, Rng& rng) {
  PhysicalParameters phys;
  for (std::size_t k = 0; k < kNumParams; ++k) {
    const auto [lo, hi] = ranges.physical[k];
    phys.values[k] = rng.uniform(lo, hi);
  }
  if (ranges.muBelowGapless) {
    // μ ≤ asin(dx_rel/R1) keeps every dp_k = 2·dx_rel + 2·R1·sinμ·cos(γ_k + τ) ≥ 0.
    const double dxRel = phys[Physical::DxRel];
    const double cap = dxRel > 0.0 ? std::asin(std::min(1.0, dxRel / r1)) : 0.0;
    const auto [lo, hi] = ranges.physical[index(Physical::Mu)];
    const double top = std::min(hi, cap), bottom = std::min(lo, top);
    phys[Physical::Mu] = bottom + (top - bottom) * rng.uniform();
  }
  return geometry::fromPhysical(phys, r1);
}

Status CampaignOptions::validate() const {
  if (samples < 1) return Error{"--samples must be at least 1"};
  if (events < 1) return Error{"--events must be at least 1"};
  if (Status s = calib::checkDepthOffset(corrections.depthOffset); !s) return s;
  // The simulation's settings as its samples check them (the counters: where the detector is known).
  if (Status s = simulation.generator.validate(); !s) return s;
  if (Status s = simulation.tracking.validate(); !s) return s;
  if (Status s = simulation.reconstruction.validate(); !s) return s;
  return ranges.validate();
}

namespace {

// The SHA-256 of a sample's content (its JSON without "sha256", compact): a sample changed
// since it was written (its fit, its counts) is not a finished sample, even without the
// task's record that holds the file's digest.
std::string contentDigest(Json j) {
  j.erase("sha256");
  return sha256(j.dump());
}

Json sampleJson(const SampleResult& s, const CampaignOptions& o) {
  Json fit = calib::fitResultJson(s.fit, calib::FitInput{});
  fit.erase("input");
  Json j = {{"format", kSampleFormat},
            {"index", s.index},
            {"campaign", {{"seed", o.seed}, {"events", o.events}, {"settings", o.settings}}},
            {"selected_events", s.selectedEvents},
            {"truth", io::alignmentToJson(s.truth)},
            {"fit", fit}};
  j["sha256"] = contentDigest(j);
  return j;
}

// Reads back what the table needs from a sample file; none if it is not a finished sample
// of this campaign.
std::optional<SampleResult> readSample(const std::string& path, int sampleIndex, const CampaignOptions& o, double r1) {
  auto text = io::readOwnOutput(path);
  if (!text) return std::nullopt;
  auto j = io::parseJson(*text, path);
  if (!j || !j->is_object() || !j->contains("format") || (*j)["format"] != kSampleFormat) return std::nullopt;
  // Its content as written (a sample without its digest, as an earlier version wrote it, is
  // simulated again once removed: the message says so).
  if (!j->contains("sha256") || (*j)["sha256"] != contentDigest(*j)) return std::nullopt;
  try {
    Json& c = (*j)["campaign"];  // not const: a missing key reads as null, never undefined behaviour
    // Integers exactly as written (a wrapped or truncated number is not this campaign's).
    const bool sameSeed = c["seed"].is_number_unsigned() && c["seed"].get<std::uint64_t>() == o.seed;
    const auto events =
        io::integerIn(c["events"], 1, std::numeric_limits<std::int64_t>::max(), path, "campaign.events");
    const auto stored = io::integerIn((*j)["index"], 0, std::numeric_limits<int>::max(), path, "index");
    const auto selected =
        io::integerIn((*j)["selected_events"], 0, std::numeric_limits<std::int64_t>::max(), path, "selected_events");
    if (!sameSeed || !events || *events != o.events || c["settings"] != o.settings || !stored ||
        *stored != sampleIndex || !selected) {
      return std::nullopt;
    }
    SampleResult s;
    s.index = sampleIndex;
    s.selectedEvents = *selected;
    auto truth = io::parseAlignment((*j)["truth"], r1, path, io::AlignmentUse::Record);
    auto fit = io::parseAlignment((*j)["fit"], r1, path, io::AlignmentUse::Record);
    if (!truth || !fit) return std::nullopt;
    // The truth is the sample's own draw (the seed and the index give it): a file edited since,
    // or another campaign's, is not this sample.
    Rng truthRng(o.seed, static_cast<std::uint64_t>(sampleIndex));
    const AlignmentParameters drawn = drawTruth(o.ranges, r1, truthRng);
    for (std::size_t p = 0; p < kNumParams; ++p) {
      const auto i = static_cast<Eigen::Index>(p);
      if (std::abs(truth->values[i] - drawn.values[i]) > 1e-9 * std::max(1.0, std::abs(drawn.values[i]))) {
        return std::nullopt;
      }
    }
    s.truth = *truth;
    s.fit.parameters = *fit;
    Json& f = (*j)["fit"];
    const auto status = fitStatusFromName(f["status"].get<std::string>());
    if (!status) return std::nullopt;
    s.fit.status = *status;
    s.fit.chi2 = f["chi2"].is_null() ? std::nan("") : f["chi2"].get<double>();
    const auto ndf = io::integerIn(f["ndf"], -1000000, 1000000, path, "fit.ndf");
    if (!ndf) return std::nullopt;
    s.fit.ndf = static_cast<int>(*ndf);
    for (Param p : kAllParams) {
      const Json& e = f["errors"][std::string(name(p))];
      s.fit.errors[p] = e.is_null() ? std::nan("") : e.get<double>() * AlignmentParameters::fileUnit(p);
    }
    for (Physical p : kDerivedParams) {
      Json& d = f["derived"][std::string(name(p))];
      const double unit = fileUnitOf(p);
      calib::DerivedValue& v = s.fit.derived[p];
      v.value = d["value"].get<double>() * unit;
      v.error = d["error"].is_null() ? std::nan("") : d["error"].get<double>() * unit;
    }
    if (f.contains("sigma_sys")) s.fit.sigmaSys.value = f["sigma_sys"]["value_deg"].get<double>() * units::deg;
    if (f.contains("correlation")) {
      for (int row = 0; row < static_cast<int>(kNumParams); ++row) {
        for (int col = 0; col < static_cast<int>(kNumParams); ++col) {
          s.fit.correlation(row, col) = f["correlation"][row][col].get<double>();
        }
      }
    }
    return s;
  } catch (const Json::exception&) {
    return std::nullopt;
  }
}

}  // namespace

namespace {

std::string samplePath(const std::string& dir, int i) {
  return (fs::path(dir) / "samples" / fmt::format("sample_{:04d}.json", i)).string();
}

// What every sample of a campaign is fitted with.
struct SampleModel {
  calib::FitGeometry geometry;
  calib::ProfileOptions profile;
};

Result<SampleModel> sampleModelOf(const geometry::Calorimeter& calo, const CampaignOptions& o) {
  SampleModel m{calib::FitGeometry::of(calo.description()), {}};
  m.geometry.apply(o.corrections);
  m.profile.apply(o.corrections);
  m.profile.eventPairs = true;  // the statistical errors take the event pairs' correlation along
  if (Status s = m.profile.validate(); !s) return Error{fmt::format("the corrections: {}", s.error().message)};
  return m;
}

// Sample i: read back when its file is there (a file of another campaign is an error), else —
// unless only finished samples may be used — simulated, fitted and written, and read back, so
// that a resumed campaign, which reads its finished samples, gives the same table to the last
// digit.
Result<SampleResult> sampleOf(const geometry::Calorimeter& calo, const CampaignOptions& o, const SampleModel& m,
                              const std::string& dir, int i) {
  const double r1 = calo.description().r1();
  const std::string path = samplePath(dir, i);
  if (fs::exists(path)) {
    if (auto done = readSample(path, i, o, r1)) return std::move(*done);
    return Error{
        fmt::format("{} is not a finished sample of this campaign (another seed, number of events or "
                    "simulation setting?): use another directory, or remove it",
                    path)};
  }
  if (o.onlyFinished) return Error{fmt::format("{}: missing (its task has not run)", path)};
  std::error_code ec;
  fs::create_directories(fs::path(dir) / "samples", ec);
  if (ec) return Error{fmt::format("{}: cannot create the directory: {}", dir, ec.message())};
  Rng truthRng(o.seed, static_cast<std::uint64_t>(i));
  SampleResult s;
  s.index = i;
  s.truth = drawTruth(o.ranges, r1, truthRng);
  sim::SimulationOptions so = o.simulation;
  so.seed = sampleSeed(o.seed, i);
  if (o.samplePattern) o.samplePattern(so, so.seed, calo.size());
  auto simulation = sim::Simulation::create(calo, s.truth, so);
  if (!simulation) return simulation.error();
  calib::ProfileFiller filler(m.geometry.depth, calib::SelectionOptions{}, m.profile);
  const Status run = simulation->run(
      o.events, o.threads, [&](std::span<const ParticleRow> rows, std::span<const TruthRow>, std::span<const Hit>) {
        filler.addEvents(rows);
        return Status{};
      });
  if (!run) return run.error();
  if (Status sel = filler.checkSelected(); !sel) return Error{fmt::format("sample {}: {}", i, sel.error().message)};
  auto fit = calib::fitProfiles(filler.fill().profiles, m.geometry, o.sigmaSys);
  if (!fit) return Error{fmt::format("sample {}: {}", i, fit.error().message)};
  s.fit = std::move(*fit);
  s.selectedEvents = filler.fill().cutFlow.events.back();
  if (Status w = io::writeOutputFile(path, sampleJson(s, o).dump(1) + "\n", io::Placement::InDirectory); !w) {
    return w.error();
  }
  auto stored = readSample(path, i, o, r1);
  if (!stored) return Error{fmt::format("{}: written but not readable back", path)};
  return std::move(*stored);
}

}  // namespace

Status runSample(const geometry::Calorimeter& calo, const CampaignOptions& o, const std::string& dir, int i) {
  if (Status s = o.validate(); !s) return s.error();
  if (i < 0 || i >= o.samples)
    return Error{fmt::format("sample {}: the campaign has samples 0 to {}", i, o.samples - 1)};
  auto m = sampleModelOf(calo, o);
  if (!m) return m.error();
  auto s = sampleOf(calo, o, *m, dir, i);
  if (!s) return s.error();
  return {};
}

std::string sampleFile(const std::string& dir, int i) { return samplePath(dir, i); }

namespace {

class ValidationJob final : public PlannedJob {
 public:
  ValidationJob(geometry::Calorimeter calo, CampaignOptions o, std::string dir, std::vector<std::string> inputs,
                int samplesPerTask)
      : calo_(std::move(calo)),
        o_(std::move(o)),
        dir_(std::move(dir)),
        inputs_(std::move(inputs)),
        blocks_(sampleBlocks(o_.samples, samplesPerTask, 1, 0)) {}

  [[nodiscard]] std::vector<PlannedTask> tasks() const override {
    std::vector<PlannedTask> t;
    for (const SampleBlock& b : blocks_) {
      PlannedTask task{
          fmt::format("{} of the campaign {} ({} events each)", samplesText(b), dir_, o_.events), {}, inputs_};
      for (int i = b.first; i <= b.last; ++i)
        task.writes.push_back(fs::absolute(samplePath(dir_, i)).lexically_normal().string());
      t.push_back(std::move(task));
    }
    return t;
  }
  Status runTask(std::size_t k, const TaskContext&) const override {
    for (int i = blocks_[k].first; i <= blocks_[k].last; ++i) {
      if (Status s = runSample(calo_, o_, dir_, i); !s) return s;
    }
    return {};
  }
  [[nodiscard]] std::optional<bool> keeps(std::size_t k, const std::string& output) const override {
    for (int i = blocks_[k].first; i <= blocks_[k].last; ++i) {
      if (fs::absolute(samplePath(dir_, i)).lexically_normal().string() == output) {
        return readSample(samplePath(dir_, i), i, o_, calo_.description().r1()).has_value();
      }
    }
    return std::nullopt;
  }

 private:
  geometry::Calorimeter calo_;
  CampaignOptions o_;
  std::string dir_;
  std::vector<std::string> inputs_;
  std::vector<SampleBlock> blocks_;
};

}  // namespace

bool isFinishedSample(const geometry::Calorimeter& calo, const CampaignOptions& o, const std::string& dir, int i) {
  return readSample(samplePath(dir, i), i, o, calo.description().r1()).has_value();
}

Status checkPlannedCampaign(const geometry::Calorimeter& calo, const CampaignOptions& o, const std::string& dir) {
  if (Status s = o.validate(); !s) return s;
  if (Status s = o.simulation.validate(calo.size()); !s) return s;
  for (int i = 0; i < o.samples; ++i) {
    const std::string path = samplePath(dir, i);
    if (std::error_code ec; fs::exists(path, ec) && !isFinishedSample(calo, o, dir, i)) {
      return Error{
          fmt::format("{} is not a finished sample of this campaign (another seed, number of events or "
                      "simulation setting?): use another directory, or remove it",
                      path)};
    }
  }
  return {};
}

Result<std::unique_ptr<PlannedJob>> validationJob(geometry::Calorimeter calo, CampaignOptions options, std::string dir,
                                                  std::vector<std::string> inputs, int samplesPerTask) {
  if (Status s = options.validate(); !s) return s.error();
  if (Status s = options.simulation.validate(calo.size()); !s) return s.error();
  return std::unique_ptr<PlannedJob>(std::make_unique<ValidationJob>(
      std::move(calo), std::move(options), std::move(dir), std::move(inputs), samplesPerTask));
}

Result<Table> runCampaign(const geometry::Calorimeter& calo, const CampaignOptions& o, const std::string& dir,
                          const CampaignProgress& progress, std::vector<SampleResult>* samplesOut) {
  if (Status s = o.validate(); !s) return s.error();
  std::error_code ec;
  fs::create_directories(fs::path(dir) / "samples", ec);
  if (ec) return Error{fmt::format("{}: cannot create the directory: {}", dir, ec.message())};
  const double r1 = calo.description().r1();
  auto model = sampleModelOf(calo, o);
  if (!model) return model.error();
  std::vector<SampleResult> samples;
  for (int i = 0; i < o.samples; ++i) {
    auto s = sampleOf(calo, o, *model, dir, i);
    if (!s) return s.error();
    samples.push_back(std::move(*s));
    if (progress) progress(i + 1, o.samples);
  }
  Table table = tabulate(samples, o.events, r1);
  if (Status w = io::writeFileIn(dir, "table.json", tableJson(table).dump(2) + "\n"); !w) {
    return w.error();
  }
  if (Status w = io::writeFileIn(dir, "table.md", tableMarkdown(table)); !w) {
    return w.error();
  }
  if (auto plots = report::writeCampaignPlots((fs::path(dir) / "plots").string(), campaignSeries(samples, r1));
      !plots) {
    return plots.error();
  }
  if (samplesOut != nullptr) *samplesOut = std::move(samples);
  return table;
}

Json campaignSettings(const CampaignOptions& o, const CampaignRecord& r) {
  Json ranges = Json::object();
  for (Physical p : kAllPhysical) {
    const double unit = PhysicalParameters::fileUnit(p);
    ranges[std::string(name(p))] = {o.ranges.physical[index(p)].first / unit,
                                    o.ranges.physical[index(p)].second / unit};
  }
  // What the corrections were, so that a rerun with another file is refused.
  const Json corrections = r.correctionsFile.empty()
                               ? Json()
                               : Json{{"file", r.correctionsFile}, {"fnv1a", calib::correctionsDigest(o.corrections)}};
  Json settings = {{"ideal", r.ideal},
                   {"off", r.off},
                   {"point_showers", r.pointShowers},
                   {"depth_offset_cm", r.depthOffsetCm},
                   {"corrections", corrections},
                   {"theta_range_deg", {r.thetaMinDeg, r.thetaMaxDeg}},
                   {"ranges", ranges},
                   {"mu_below_gapless", o.ranges.muBelowGapless},
                   {"detector", r.detector}};
  if (!r.sigmaSys.empty()) settings["sigma_sys"] = r.sigmaSys;
  if (r.beamEnergyMev > 0.0) settings["beam_energy_mev"] = r.beamEnergyMev;
  return settings;
}

}  // namespace emcalign::validation
