// The derivation as a plan's tasks (validation/derive_corrections.hpp): each point's three
// samples, its first stage and its response samples in blocks, each kept in a file of the
// point's task directory, and the merge that reads them back.

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>

#include <fmt/format.h>

#include "derive_corrections_internal.hpp"
#include "emcalign/calib/calibration.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/io/strict_json.hpp"
#include "emcalign/validation/derive_corrections.hpp"

namespace emcalign::validation {

using derivation::firstStage;
using derivation::fitResponseSample;
using derivation::kSampleNames;
using derivation::lastStage;
using derivation::responseDraw;
using derivation::Sample;
using derivation::sampleTruth;
using derivation::simulateSample;
using geometry::AlignmentParameters;
using io::Json;

namespace {

namespace fs = std::filesystem;

// ------------------------------------------------------------------ the fan-out's files
// Each holds the point's settings (derived_from.settings of the corrections file): a file of
// other settings (an earlier plan at the same path) is done again by a task, refused by the
// merge. Every number is written as JSON's shortest exact form or as HDF5 doubles, so the
// merge computes what one process computes.

constexpr std::string_view kResponseFormat = "emcalign-derive-response/1";

std::string sampleFile(const std::string& dir, int k) {
  return (fs::path(dir) / fmt::format("{}.h5", kSampleNames[k])).string();
}
std::string firstStageFile(const std::string& dir) { return (fs::path(dir) / "first-stage.json").string(); }
std::string responseFile(const std::string& dir, const SampleBlock& b) {
  return (fs::path(dir) / fmt::format("response-{}-{}.json", b.first, b.last)).string();
}

Status writeSample(const std::string& file, int k, const Sample& s, const Json& settings) {
  io::WriterOptions wo;
  wo.attributes = {{"derivation_sample", std::string(kSampleNames[k])},
                   {"selected_events", std::to_string(s.selectedEvents)},
                   {"settings", settings.dump()}};
  wo.placement = io::Placement::InDirectory;
  auto writer = io::EventWriter::open(file, wo);
  if (!writer) return writer.error();
  if (Status st = (*writer)->append(s.particles, {}); !st) return st;
  return (*writer)->close();
}

// The sample in `file` if it holds sample k of `settings`; nullopt if it holds another.
Result<std::optional<Sample>> readSample(const std::string& file, const DerivationOptions& o, int k,
                                         const Json& settings) {
  io::ReaderOptions ro;
  ro.truth = false;
  ro.hits = false;
  auto reader = io::EventReader::open({file}, ro);
  if (!reader) return reader.error();
  std::map<std::string, std::string> attributes((*reader)->attributes().begin(), (*reader)->attributes().end());
  if (attributes["derivation_sample"] != kSampleNames[k] || attributes["settings"] != settings.dump()) {
    return std::optional<Sample>();
  }
  Sample s;
  s.truth = sampleTruth(o, k);
  try {
    std::size_t used = 0;
    s.selectedEvents = std::stoll(attributes["selected_events"], &used);
    if (used != attributes["selected_events"].size()) throw std::invalid_argument("trailing text");
  } catch (const std::exception&) {
    return Error{fmt::format("{}: attribute 'selected_events': expected an integer, got '{}'", file,
                             attributes["selected_events"])};
  }
  std::vector<ParticleRow> block;
  for (;;) {
    auto more = (*reader)->next(block);
    if (!more) return more.error();
    if (!*more) break;
    s.particles.insert(s.particles.end(), block.begin(), block.end());
  }
  return std::optional<Sample>(std::move(s));
}

double numberOrNan(const Json& j) { return j.is_null() ? std::nan("") : j.get<double>(); }

// The first stage in `file` (a corrections file with the report so far under derived_from)
// if it holds `settings`; nullopt if it holds others.
Result<std::optional<DerivationReport>> readFirstStage(const std::string& file, const Json& settings) {
  auto text = io::readOwnOutput(file);
  if (!text) return text.error();
  auto j = io::parseJson(*text, file);
  if (!j) return j.error();
  auto c = calib::parseCorrections(*j, file);
  if (!c) return c.error();
  if (!c->derivedFrom.is_object() || c->derivedFrom.value("settings", Json()) != settings) {
    return std::optional<DerivationReport>();
  }
  return io::strict::guarded([&] {
    const io::strict::StrictObject from(c->derivedFrom, "derived_from", file);
    DerivationReport r;
    r.corrections = *c;
    r.corrections.derivedFrom = Json();
    r.depthOffsetError = numberOrNan(from.at("depth_offset_error_cm")) * units::cm;
    r.depthChi2 = from.number("depth_chi2");
    r.depthBins = from.at("depth_bins").get<int>();
    r.columnWeights = from.at("column_plus_weight_measured").get<std::vector<double>>();
    r.columnWeightErrors = from.at("column_plus_weight_error").get<std::vector<double>>();
    const io::strict::StrictObject selected = from.object("selected_events");
    for (int k = 0; k < 3; ++k) r.selectedEvents[k] = selected.at(kSampleNames[k]).get<std::int64_t>();
    return std::optional<DerivationReport>(std::move(r));
  });
}

// The fitted parameters of the response samples in `file`, by sample, if it holds `settings`.
Result<std::map<int, geometry::ParamVector>> readResponseFile(const std::string& file, const Json& settings) {
  auto text = io::readOwnOutput(file);
  if (!text) return text.error();
  auto j = io::parseJson(*text, file);
  if (!j) return j.error();
  return io::strict::guarded([&] {
    const io::strict::StrictObject top(*j, "", file);
    top.allowOnly({"format", "settings", "samples"});
    if (top.string("format") != kResponseFormat) top.fail("format", fmt::format("expected '{}'", kResponseFormat));
    std::map<int, geometry::ParamVector> fits;
    if (top.at("settings") != settings) return fits;
    const Json& samples = top.at("samples");
    if (!samples.is_array()) top.fail("samples", "expected an array");
    for (std::size_t n = 0; n < samples.size(); ++n) {
      const io::strict::StrictObject one(samples[n], fmt::format("samples[{}]", n), file);
      one.allowOnly({"sample", "truth", "fitted"});
      const Json& fitted = one.at("fitted");
      if (!fitted.is_array() || fitted.size() != kNumParams) one.fail(one.pathOf("fitted"), "expected 12 numbers");
      geometry::ParamVector v;
      for (std::size_t p = 0; p < kNumParams; ++p) {
        v[static_cast<Eigen::Index>(p)] = one.numberValue(fitted[p], fmt::format("{}[{}]", one.pathOf("fitted"), p));
      }
      fits[one.at("sample").get<int>()] = v;
    }
    return fits;
  });
}

// ------------------------------------------------------------------ one point's work

// The point's work in its task directory: each piece read from its file when there with these
// settings, otherwise (`make`) done under the piece's lock and written, or (the merge) refused.
class PointWork {
 public:
  PointWork(const geometry::Calorimeter& calo, const DerivationOptions& o, std::string dir, const Json& settings,
            bool make)
      : calo_(calo), o_(o), dir_(std::move(dir)), settings_(settings), make_(make) {}

  Result<Sample> sample(int k, const std::function<void(const std::string&)>& say) const {
    const std::string file = sampleFile(dir_, k);
    return readOrMake<Sample>(
        file, [&] { return readSample(file, o_, k, settings_); },
        [&]() -> Result<Sample> {
          say(fmt::format("simulating the {} sample ({} events) into {}", kSampleNames[k], o_.events, file));
          auto s = simulateSample(calo_, o_, k, {});
          if (!s) return s.error();
          if (Status st = writeSample(file, k, *s, settings_); !st) return st.error();
          return s;
        });
  }

  Result<std::vector<Sample>> samples(const std::function<void(const std::string&)>& say) const {
    std::vector<Sample> all;
    for (int k = 0; k < 3; ++k) {
      auto s = sample(k, say);
      if (!s) return s.error();
      all.push_back(std::move(*s));
    }
    return all;
  }

  Result<DerivationReport> first(const std::function<void(const std::string&)>& say) const {
    const std::string file = firstStageFile(dir_);
    return readOrMake<DerivationReport>(
        file, [&] { return readFirstStage(file, settings_); },
        [&]() -> Result<DerivationReport> {
          auto all = samples(say);
          if (!all) return all.error();
          say(fmt::format("the first stage (depth, parting plane, nominal profile) into {}", file));
          auto report = firstStage(calib::FitGeometry::of(calo_.description()), o_, *all);
          if (!report) return report.error();
          if (Status st = io::writeOutputFile(file, derivationJson(*report, settings_).dump(2) + "\n",
                                              io::Placement::InDirectory);
              !st) {
            return st.error();
          }
          return report;
        });
  }

  Status response(const SampleBlock& block, const std::function<void(const std::string&)>& say) const {
    const std::string file = responseFile(dir_, block);
    std::error_code ec;
    if (fs::exists(file, ec)) {
      auto read = readResponseFile(file, settings_);
      bool whole = static_cast<bool>(read);
      for (int i = block.first; whole && i <= block.last; ++i) whole = read->contains(i);
      if (whole) return {};
    }
    auto stage = first(say);
    if (!stage) return stage.error();
    Json samples = Json::array();
    for (int i = block.first; i <= block.last; ++i) {
      auto fitted = fitResponseSample(calo_, o_, stage->corrections, i, {});
      if (!fitted) return fitted.error();
      Json f = Json::array(), t = Json::array();
      const AlignmentParameters truth = responseDraw(calo_, o_, i).truth;
      for (Param p : kAllParams) {
        f.push_back((*fitted)[p]);
        t.push_back(truth[p]);
      }
      samples.push_back({{"sample", i}, {"truth", t}, {"fitted", f}});
    }
    say(fmt::format("response {} fitted into {}", samplesText(block), file));
    const Json out = {{"format", kResponseFormat}, {"settings", settings_}, {"samples", samples}};
    return io::writeOutputFile(file, out.dump(2) + "\n", io::Placement::InDirectory);
  }

  // The merge: every response sample from the files of these settings.
  Result<std::vector<geometry::ParamVector>> responseFits() const {
    std::map<int, geometry::ParamVector> fits;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(dir_, ec)) {
      const std::string name = entry.path().filename().string();
      if (name.rfind("response-", 0) != 0 || entry.path().extension() != ".json") continue;
      auto read = readResponseFile(entry.path().string(), settings_);
      if (!read) return read.error();
      fits.merge(*read);
    }
    if (ec) return Error{fmt::format("{}: cannot list the directory: {}", dir_, ec.message())};
    std::vector<geometry::ParamVector> out;
    std::vector<std::size_t> absent;
    for (int i = 0; i < o_.responseSamples; ++i) {
      const auto it = fits.find(i);
      if (it == fits.end()) {
        absent.push_back(static_cast<std::size_t>(i));
      } else {
        out.push_back(it->second);
      }
    }
    if (!absent.empty()) {
      return Error{
          fmt::format("{}: response samples {} are not there with these settings (their tasks' "
                      "response-*.json files)",
                      dir_, taskRanges(absent))};
    }
    return out;
  }

 private:
  // The piece in `file`: read when it is there with these settings (`read` gives nullopt for
  // other settings); otherwise made and written under its lock (`make`), or, for the merge,
  // refused.
  template <typename T, typename Read, typename Make>
  Result<T> readOrMake(const std::string& file, Read&& read, Make&& make) const {
    std::optional<FileLock> lock;
    if (make_) {
      if (Status s = makeDirectory(); !s) return s.error();
      lock.emplace(file + ".lock");
      if (!lock->error().empty()) return Error{lock->error()};
    }
    std::error_code ec;
    if (fs::exists(file, ec)) {
      Result<std::optional<T>> got = read();
      if (!got && !make_) return got.error();
      if (got && *got) return std::move(**got);
    }
    if (!make_) return missing(file);
    return make();
  }
  Status makeDirectory() const {
    std::error_code ec;
    fs::create_directories(dir_, ec);
    if (ec) return Error{fmt::format("{}: cannot create the directory: {}", dir_, ec.message())};
    return {};
  }
  [[nodiscard]] Error missing(const std::string& file) const {
    return Error{
        fmt::format("{}: not there with this plan's settings (its task's output was removed or replaced)", file)};
  }

  const geometry::Calorimeter& calo_;
  const DerivationOptions& o_;
  std::string dir_;
  const Json& settings_;
  bool make_;
};

// The tasks of each point not yet derived: its three samples, its first stage, its response
// samples in blocks; a point already derived: one task that keeps it.
class DerivationJob final : public PlannedJob {
 public:
  DerivationJob(geometry::Calorimeter calo, DerivationOptions o, std::vector<GridPoint> points,
                std::vector<Json> settings, std::vector<std::string> inputs, std::string workDirectory,
                int samplesPerTask)
      : calo_(std::move(calo)),
        o_(std::move(o)),
        points_(std::move(points)),
        settings_(std::move(settings)),
        inputs_(std::move(inputs)),
        work_(std::move(workDirectory)) {
    std::size_t todo = 0;
    for (const auto& p : points_) todo += p.done ? 0 : 1;
    const int others = static_cast<int>(points_.size() + 3 * todo);
    blocks_ = o_.responseSamples > 0 ? sampleBlocks(o_.responseSamples, samplesPerTask,
                                                    static_cast<int>(std::max<std::size_t>(todo, 1)), others)
                                     : std::vector<SampleBlock>{};
    for (std::size_t p = 0; p < points_.size(); ++p) {
      if (points_[p].done) {
        refs_.push_back({p, Kind::Kept, 0, {}});
        continue;
      }
      for (int k = 0; k < 3; ++k) refs_.push_back({p, Kind::Sample, k, {}});
      refs_.push_back({p, Kind::FirstStage, 0, {}});
      for (const auto& b : blocks_) refs_.push_back({p, Kind::Response, 0, b});
    }
  }

  [[nodiscard]] std::vector<PlannedTask> tasks() const override {
    std::vector<PlannedTask> t;
    for (const auto& r : refs_) {
      const GridPoint& p = points_[r.point];
      const double mev = p.beamEnergy / units::MeV;
      const std::string dir = directoryOf(r.point);
      switch (r.kind) {
        case Kind::Kept:
          t.push_back({fmt::format("the corrections at {} MeV: derived with these settings already, kept", mev),
                       {absolute(p.file)},
                       inputs_});
          break;
        case Kind::Sample:
          t.push_back({fmt::format("the {} sample at {} MeV ({} events)", kSampleNames[r.sample], mev, o_.events),
                       {sampleFile(dir, r.sample)},
                       inputs_});
          break;
        case Kind::FirstStage:
          t.push_back({fmt::format("the first stage at {} MeV (depth, parting plane, nominal profile)", mev),
                       {firstStageFile(dir)},
                       inputs_});
          break;
        case Kind::Response:
          t.push_back(
              {fmt::format("response {} at {} MeV ({} events each)", samplesText(r.block), mev, o_.responseEvents),
               {responseFile(dir, r.block)},
               inputs_});
          break;
      }
    }
    return t;
  }

  Status runTask(std::size_t k, const TaskContext& context) const override {
    const Ref& r = refs_[k];
    const GridPoint& p = points_[r.point];
    if (derivedWith(p.file, settings_[r.point])) {
      context.say(fmt::format("{} holds corrections derived with the same settings: kept", p.file));
      return {};
    }
    if (r.kind == Kind::Kept) {
      return Error{fmt::format("{}: no longer holds the corrections derived with this plan's settings", p.file)};
    }
    DerivationOptions o = o_;
    o.simulation.generator.beamEnergy = p.beamEnergy;
    const PointWork work(calo_, o, directoryOf(r.point), settings_[r.point], true);
    Status done;
    switch (r.kind) {
      case Kind::Sample: {
        auto s = work.sample(r.sample, context.say);
        done = s ? Status{} : Status{s.error()};
        break;
      }
      case Kind::FirstStage: {
        auto f = work.first(context.say);
        if (f) {
          context.say(fmt::format("depth offset {:+.3f} ± {:.3f} cm", f->corrections.depthOffset / units::cm,
                                  f->depthOffsetError / units::cm));
        }
        done = f ? Status{} : Status{f.error()};
        break;
      }
      case Kind::Response:
        done = work.response(r.block, context.say);
        break;
      case Kind::Kept:
        break;
    }
    if (!done) return Error{fmt::format("at {} MeV: {}", p.beamEnergy / units::MeV, done.error().message)};
    return {};
  }

 private:
  enum class Kind { Kept, Sample, FirstStage, Response };
  struct Ref {
    std::size_t point;
    Kind kind;
    int sample;
    SampleBlock block;
  };
  static std::string absolute(const std::string& p) { return fs::absolute(p).lexically_normal().string(); }
  [[nodiscard]] std::string directoryOf(std::size_t point) const {
    return derivationTaskDirectory(work_, points_[point].beamEnergy);
  }

  geometry::Calorimeter calo_;
  DerivationOptions o_;
  std::vector<GridPoint> points_;
  std::vector<Json> settings_;
  std::vector<std::string> inputs_;
  std::string work_;
  std::vector<SampleBlock> blocks_;
  std::vector<Ref> refs_;
};

}  // namespace

Result<std::unique_ptr<PlannedJob>> derivationJob(geometry::Calorimeter calo, DerivationOptions options,
                                                  std::vector<GridPoint> points, std::vector<io::Json> settings,
                                                  std::vector<std::string> inputs, std::string workDirectory,
                                                  int samplesPerTask) {
  if (Status s = options.validate(); !s) return s.error();
  if (Status s = options.simulation.validate(calo.size()); !s) return s.error();
  return std::unique_ptr<PlannedJob>(
      std::make_unique<DerivationJob>(std::move(calo), std::move(options), std::move(points), std::move(settings),
                                      std::move(inputs), std::move(workDirectory), samplesPerTask));
}

Result<DerivationReport> mergeDerivation(const geometry::Calorimeter& calo, const DerivationOptions& o,
                                         const std::string& directory, const Json& settings) {
  if (Status s = o.validate(); !s) return s.error();
  const PointWork work(calo, o, directory, settings, false);
  auto report = work.first([](const std::string&) {});
  if (!report) return report.error();
  auto samples = work.samples([](const std::string&) {});
  if (!samples) return samples.error();
  std::vector<geometry::ParamVector> fits;
  if (o.responseSamples > 0) {
    auto read = work.responseFits();
    if (!read) return read.error();
    fits = std::move(*read);
  }
  if (Status s = lastStage(calo, calib::FitGeometry::of(calo.description()), o, *samples, fits, *report, {}); !s) {
    return s.error();
  }
  return report;
}

}  // namespace emcalign::validation
