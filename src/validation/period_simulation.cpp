// A period simulated (validation/period.hpp): its directory claimed (or resumed), its runs
// simulated in parallel pieces and written in order, one file per run, and its truth file.

#include <atomic>
#include <filesystem>
#include <memory>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/validation/period.hpp"

namespace emcalign::validation {

namespace fs = std::filesystem;
using io::Json;

namespace {

// What differs between the period a directory holds and the one asked for, in words: the
// scenario, the hits, each setting by name with both values.
std::vector<std::string> periodDifferences(const Json& held, const Json& asked) {
  std::vector<std::string> out;
  const auto value = [](const Json& j, const std::string& key) {
    return j.is_object() && j.contains(key) ? j[key] : Json();
  };
  if (value(held, "scenario") != value(asked, "scenario")) out.emplace_back("another scenario");
  if (value(held, "hits") != value(asked, "hits")) {
    out.push_back(value(asked, "hits") == Json(false) ? "--no-hits now, hits then" : "hits now, --no-hits then");
  }
  const Json before = value(held, "settings"), now = value(asked, "settings");
  std::set<std::string> keys;
  for (const Json* j : {&before, &now}) {
    if (j->is_object()) {
      for (const auto& [k, v] : j->items()) keys.insert(k);
    }
  }
  for (const std::string& k : keys) {
    const Json a = value(before, k), b = value(now, k);
    if (a == b) continue;
    const auto shown = [](const Json& v) {
      const std::string d = v.is_null() ? std::string("none") : v.dump();
      return d.size() > 60 ? d.substr(0, 57) + "..." : d;
    };
    out.push_back(fmt::format("{}: {} then, {} now", k, shown(a), shown(b)));
  }
  return out;
}

// Claims `dir` for the period: a new directory gets its period.json; one that holds this
// very period (scenario, hits, settings) is resumed; anything else is refused.
Status claimPeriodDirectory(const std::string& dir, const PeriodScenario& s, const PeriodOptions& o) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Error{fmt::format("{}: cannot create the directory: {}", dir, ec.message())};
  const Json state = {{"format", "emcalign-period-state/1"},
                      {"scenario", s.source},
                      {"hits", o.hits},
                      {"settings", o.settings},
                      {"software", fmt::format("emcalign {}", kVersion)}};
  const std::string statePath = (fs::path(dir) / "period.json").string();
  if (fs::exists(statePath)) {
    auto text = io::readOwnOutput(statePath);
    if (!text) return text.error();
    auto old = io::parseJson(*text, statePath);
    if (!old || !old->is_object()) {
      return Error{
          fmt::format("{}: not a period's state (emcalign-period-state/1): choose another directory", statePath)};
    }
    const std::vector<std::string> differ = periodDifferences(*old, state);
    if (!differ.empty()) {
      return Error{
          fmt::format("{}: this directory holds another period ({}): choose another directory, or remove this one", dir,
                      fmt::join(differ, "; "))};
    }
    return {};
  }
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().filename().string().rfind("run_", 0) == 0) {
      return Error{fmt::format("{}: holds run files but no period.json: choose another directory", dir)};
    }
  }
  return io::writeOutputFile(statePath, state.dump(2) + "\n", io::Placement::InDirectory);
}

// The runs still to simulate, cut into pieces of at most kPiece events: simulated in
// parallel, written in order, one file per run (libhdf5 is used by one thread at a time).
// The three stages of the TBB pipeline are next(), simulate() and write().
class PeriodPipeline {
 public:
  static constexpr std::int64_t kPiece = 16384;

  struct Piece {
    std::size_t run = 0;  // index in runs
    std::int64_t first = 0, last = 0;
    std::vector<ParticleRow> rows;
    std::vector<TruthRow> truth;
    std::vector<Hit> hits;
    std::shared_ptr<const sim::Simulation> simulation;
    Status status;
  };

  PeriodPipeline(const PeriodScenario& s, const geometry::Calorimeter& calo, const std::string& dir,
                 const PeriodOptions& o, const std::vector<PeriodRun>& runs, std::vector<std::size_t> todo,
                 PeriodReport& report)
      : s_(s),
        calo_(calo),
        dir_(dir),
        o_(o),
        runs_(runs),
        todo_(std::move(todo)),
        report_(report),
        runsDone_(report.resumed),
        scratch_([&calo] { return sim::EventScratch(calo.size()); }) {}

  Status run() {
    const int threads = o_.threads > 0 ? o_.threads : tbb::this_task_arena::max_concurrency();
    tbb::task_arena arena(threads);
    arena.execute([&] {
      tbb::parallel_pipeline(
          static_cast<std::size_t>(2 * threads),
          tbb::make_filter<void, std::shared_ptr<Piece>>(tbb::filter_mode::serial_in_order,
                                                         [this](tbb::flow_control& fc) { return next(fc); }) &
              tbb::make_filter<std::shared_ptr<Piece>, std::shared_ptr<Piece>>(
                  tbb::filter_mode::parallel, [this](std::shared_ptr<Piece> p) { return simulate(std::move(p)); }) &
              tbb::make_filter<std::shared_ptr<Piece>, void>(tbb::filter_mode::serial_in_order,
                                                             [this](const std::shared_ptr<Piece>& p) { write(*p); }));
    });
    writer_.reset();  // an unfinished file's temporary goes with it
    if (!inputFailure_.ok()) return inputFailure_;
    if (!outputFailure_.ok()) return outputFailure_;
    report_.simulated = eventsDone_;
    return {};
  }

 private:
  // The next piece, with the simulation of its run (made at the run's first piece).
  std::shared_ptr<Piece> next(tbb::flow_control& fc) {
    if (nextRun_ >= todo_.size() || stop_.load()) {
      fc.stop();
      return nullptr;
    }
    const PeriodRun& r = runs_[todo_[nextRun_]];
    if (nextEvent_ == 0) {
      sim::SimulationOptions so = o_.simulation;
      so.generator.beamEnergy = r.beamEnergy * units::MeV;
      so.generator.thetaMin = s_.thetaMin;
      so.generator.thetaMax = s_.thetaMax;
      so.run = static_cast<std::int32_t>(r.run);
      so.seed = r.seed;
      auto sim = sim::Simulation::create(calo_, r.truth, so);
      if (!sim) {
        inputFailure_ = Error{fmt::format("run {}: {}", r.run, sim.error().message)};
        fc.stop();
        return nullptr;
      }
      current_ = std::make_shared<const sim::Simulation>(std::move(*sim));
    }
    auto piece = std::make_shared<Piece>();
    piece->run = todo_[nextRun_];
    piece->first = nextEvent_;
    piece->last = std::min(r.events, nextEvent_ + kPiece);
    piece->simulation = current_;
    nextEvent_ = piece->last;
    if (nextEvent_ >= r.events) {
      ++nextRun_;
      nextEvent_ = 0;
    }
    return piece;
  }

  std::shared_ptr<Piece> simulate(std::shared_ptr<Piece> p) {
    sim::EventScratch& sc = scratch_.local();
    sc.failedEvent = -1;
    for (std::int64_t i = p->first; i < p->last; ++i) {
      p->simulation->simulateEvent(i, sc, p->rows, p->truth, o_.hits ? &p->hits : nullptr);
    }
    if (sc.failedEvent >= 0) {
      p->status = Error{fmt::format("run {} event {}: the generator made no event in 2^20 trials", runs_[p->run].run,
                                    sc.failedEvent)};
    }
    return p;
  }

  // Appends a piece to its run's file: opened at the run's first piece, closed at its last.
  void write(const Piece& p) {
    if (!outputFailure_.ok()) return;
    if (!p.status.ok()) return fail(p.status);
    const PeriodRun& r = runs_[p.run];
    if (p.first == 0) {
      auto w = io::EventWriter::open((fs::path(dir_) / r.file).string(), writerOptions(r));
      if (!w) return fail(w.error());
      writer_ = std::move(*w);
    }
    if (Status a = writer_->append(p.rows, p.truth, p.hits); !a) return fail(a);
    report_.rows += static_cast<std::int64_t>(p.rows.size());
    eventsDone_ += p.last - p.first;
    if (p.last != r.events) return;
    if (Status c = writer_->close(); !c) return fail(c);
    writer_.reset();
    ++runsDone_;
    if (o_.progress) o_.progress(runsDone_, static_cast<std::int64_t>(runs_.size()), eventsDone_);
  }

  // A run file's attributes: its truth, and how it was simulated.
  [[nodiscard]] io::WriterOptions writerOptions(const PeriodRun& r) const {
    io::WriterOptions wo;
    wo.withTruth = true;
    wo.withHits = o_.hits;
    wo.compression = o_.compression;
    wo.placement = io::Placement::InDirectory;
    const Json settings = {{"software", fmt::format("emcalign {}", kVersion)},
                           {"period", s_.name},
                           {"run", r.run},
                           {"events", r.events},
                           {"seed", r.seed},
                           {"beam_energy_mev", r.beamEnergy},
                           {"theta_range_deg", {s_.thetaMin / units::deg, s_.thetaMax / units::deg}},
                           {"settings", o_.settings}};
    wo.attributes = {{"truth_parameters", io::alignmentToJson(r.truth).dump()}, {"simulation", settings.dump()}};
    return wo;
  }

  // The output stage's failure; `stop_` tells the input stage (they run at the same time,
  // so each keeps its own failure).
  void fail(Status s) {
    outputFailure_ = std::move(s);
    stop_ = true;
  }

  const PeriodScenario& s_;
  const geometry::Calorimeter& calo_;
  const std::string& dir_;
  const PeriodOptions& o_;
  const std::vector<PeriodRun>& runs_;
  const std::vector<std::size_t> todo_;
  PeriodReport& report_;
  std::size_t nextRun_ = 0;
  std::int64_t nextEvent_ = 0;
  std::shared_ptr<const sim::Simulation> current_;
  Status inputFailure_, outputFailure_;
  std::atomic<bool> stop_{false};
  std::unique_ptr<io::EventWriter> writer_;
  std::int64_t eventsDone_ = 0, runsDone_ = 0;
  tbb::enumerable_thread_specific<sim::EventScratch> scratch_;
};

}  // namespace

Result<PeriodReport> simulatePeriod(const PeriodScenario& s, const geometry::Calorimeter& calo, const std::string& dir,
                                    const PeriodOptions& o) {
  const std::vector<PeriodRun> runs = planPeriod(s, o.simulation.generator.process);
  // Every run's generator checked before the directory is claimed: a period refused for its
  // polar range or a beam energy (of this process) leaves nothing behind.
  for (const PeriodRun& r : runs) {
    sim::GeneratorOptions g = o.simulation.generator;
    g.beamEnergy = r.beamEnergy * units::MeV;
    g.thetaMin = s.thetaMin;
    g.thetaMax = s.thetaMax;
    if (Status v = g.validate(); !v) {
      const bool radians = s.thetaMax / units::deg <= 3.2;  // [0.7, 2.44]: 40°–140° in radians
      return Error{fmt::format("the period's run {} ({} at {} MeV, theta_range_deg [{}, {}]{}): {}", r.run,
                               sim::name(g.process), r.beamEnergy, s.thetaMin / units::deg, s.thetaMax / units::deg,
                               radians ? ", in radians? it is in degrees" : "", v.error().message)};
    }
  }
  if (Status c = claimPeriodDirectory(dir, s, o); !c) return c.error();

  PeriodReport report;
  report.runs = static_cast<std::int64_t>(runs.size());
  for (const PeriodRun& r : runs) report.events += r.events;
  std::vector<std::size_t> todo;
  for (std::size_t k = 0; k < runs.size(); ++k) {
    if (fs::exists(fs::path(dir) / runs[k].file)) {
      ++report.resumed;
    } else {
      todo.push_back(k);
    }
  }
  PeriodPipeline pipeline(s, calo, dir, o, runs, std::move(todo), report);
  if (Status p = pipeline.run(); !p) return p.error();

  const double r1 = calo.description().r1();
  if (Status w = io::writeFileIn(dir, "truth.json", periodTruthJson(s, runs, r1).dump(1) + "\n"); !w) {
    return w.error();
  }
  return report;
}

}  // namespace emcalign::validation
