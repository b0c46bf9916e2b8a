// The detector simulation with a known (truth) alignment: events as numpy columns, or a file
// as `emcalign simulate` writes it (validation/simulate_file.hpp).

#include <fmt/format.h>

#include <atomic>
#include <memory>

#include "bindings.hpp"
#include "emcalign/apply/placements.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/sim/simulation.hpp"
#include "emcalign/validation/simulate_file.hpp"

namespace emcalign::python {

namespace {

// The truth: 12 values (native units) or a file holding an alignment (its warnings shown as
// Python warnings, as the command-line tool prints them).
geometry::AlignmentParameters truthOf(const py::object& truth, const Detector& detector, std::string& file) {
  if (py::isinstance<py::str>(truth) || py::isinstance<py::bytes>(truth) || py::hasattr(truth, "__fspath__")) {
    file = pathString(truth.cast<Path>());
    const auto loaded = unwrap(apply::loadAlignment(file, detector.calorimeter()));
    for (const auto& w : loaded.warnings) {
      if (PyErr_WarnEx(PyExc_UserWarning, w.c_str(), 1) != 0) throw py::error_already_set();
    }
    return loaded.parameters;
  }
  const auto values = Array::ensure(truth);
  if (!values) {
    PyErr_Clear();
    throw py::type_error("truth: 12 values (native units) or the path of a parameter, fit-result or placements file");
  }
  return parametersOf(values);
}

// The keyword arguments of simulate (keyword-only in Python but for truth, events, detector).
struct SimulateArgs {
  std::int64_t events = 0;
  std::uint64_t seed = 1;
  std::string process;
  std::optional<double> beamEnergy, thetaMinDeg, thetaMaxDeg;
  std::int32_t run = 1;
  bool ideal = false;
  std::vector<std::string> off;
  std::optional<std::vector<int>> deadCounters;
  bool pointShowers = false;
  int threads = 0;
  bool hits = true;
};

// Events kept in memory at most: about 1 kB each with the numpy copies (a row, its truth and
// its hits, twice); more belong in a file.
constexpr std::int64_t kMaxEventsInMemory = 5'000'000;

validation::SimulateRequest requestOf(const SimulateArgs& a, const Detector& detector) {
  if (a.events < 0 || a.events > sim::kMaxEvents) {
    raise(Error{fmt::format("events: {} is not in [0, {}]", a.events, sim::kMaxEvents)});
  }
  if (a.threads < 0 || a.threads > sim::kMaxThreads) {
    raise(Error{fmt::format("threads: {} is not in [0, {}] (0: all cores)", a.threads, sim::kMaxThreads)});
  }
  validation::SimulateRequest r;
  sim::SimulationOptions& o = r.options;
  if (Status s = o.applyRealism(a.ideal, a.off); !s) raise(Error{fmt::format("off: {}", s.error().message)});
  if (a.pointShowers) o.emc.pointShowers = true;
  if (a.deadCounters) o.emc.deadCounters = *a.deadCounters;
  if (Status s = o.generator.choose(a.process, a.beamEnergy, a.thetaMinDeg, a.thetaMaxDeg); !s) {
    raise(Error{fmt::format("process: {}", s.error().message)});
  }
  o.seed = a.seed;
  o.run = a.run;
  r.events = a.events;
  r.threads = a.threads;
  r.hits = a.hits;
  r.ideal = a.ideal;
  r.off = a.off;
  r.detectorName = detector.source();
  return r;
}

// Ctrl-C during a simulation: the calling thread looks for Python's signals after each
// block of events (with the GIL, briefly); once one is pending, the sink stops the run and
// the KeyboardInterrupt is raised when the GIL is back.
class Interruption {
 public:
  // The progress callback: called on the calling thread.
  void check() {
    if (pending_) return;
    py::gil_scoped_acquire acquire;
    if (PyErr_CheckSignals() != 0) {
      error_ = std::make_unique<py::error_already_set>();
      pending_ = true;
    }
  }
  [[nodiscard]] bool pending() const { return pending_; }
  // With the GIL: raises the pending KeyboardInterrupt (or whatever the handler raised).
  void raiseIfPending() {
    if (error_) {
      const py::error_already_set e = *error_;
      error_.reset();
      throw e;
    }
  }
  ~Interruption() {
    if (!error_) return;
    try {  // a Python object is released under the GIL; nothing more to do if it cannot be taken
      py::gil_scoped_acquire acquire;
      error_.reset();
    } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor does not throw
    }
  }

 private:
  std::atomic<bool> pending_{false};
  std::unique_ptr<py::error_already_set> error_;
};

// The events in memory, as read_events would give them from the file.
py::dict simulateColumns(const geometry::Calorimeter& calo, const geometry::AlignmentParameters& truth,
                         const validation::SimulateRequest& request) {
  if (request.events > kMaxEventsInMemory) {
    raise(Error{fmt::format("events: {} in memory is more than {} (about 1 kB each): write them to a file (output=)",
                            request.events, kMaxEventsInMemory)});
  }
  std::vector<ParticleRow> rows;
  std::vector<TruthRow> truthRows;
  std::vector<Hit> hits;
  Interruption interruption;
  Status status;
  {
    py::gil_scoped_release release;
    auto simulation = sim::Simulation::create(calo, truth, request.options);
    if (simulation) {
      status = simulation->run(
          request.events, request.threads,
          [&](std::span<const ParticleRow> r, std::span<const TruthRow> t, std::span<const Hit> h) -> Status {
            if (interruption.pending()) return Error{validation::kInterrupted};
            rows.insert(rows.end(), r.begin(), r.end());
            truthRows.insert(truthRows.end(), t.begin(), t.end());
            if (request.hits) hits.insert(hits.end(), h.begin(), h.end());
            return {};
          },
          [&](std::int64_t) { interruption.check(); });
    } else {
      status = simulation.error();
    }
  }
  interruption.raiseIfPending();
  check(status);
  return eventColumns(rows, &truthRows, request.hits ? &hits : nullptr);
}

}  // namespace

void bindSimulate(py::module_& m) {
  m.def(
      "simulate",
      [](const py::object& truth, std::int64_t events, const Detector* given, const std::optional<Path>& output,
         std::uint64_t seed, const std::string& process, std::optional<double> beamEnergy,
         std::optional<double> thetaMinDeg, std::optional<double> thetaMaxDeg, std::int32_t run, bool ideal,
         const std::vector<std::string>& off, const std::optional<std::vector<int>>& deadCounters, bool pointShowers,
         int threads, bool hits) -> py::object {
        const Detector& detector = detectorOr(given);
        std::string truthFile;
        const auto eta = truthOf(truth, detector, truthFile);
        const auto request = requestOf({.events = events,
                                        .seed = seed,
                                        .process = process,
                                        .beamEnergy = beamEnergy,
                                        .thetaMinDeg = thetaMinDeg,
                                        .thetaMaxDeg = thetaMaxDeg,
                                        .run = run,
                                        .ideal = ideal,
                                        .off = off,
                                        .deadCounters = deadCounters,
                                        .pointShowers = pointShowers,
                                        .threads = threads,
                                        .hits = hits},
                                       detector);
        if (!output) return simulateColumns(detector.calorimeter(), eta, request);
        const std::string path = pathString(*output);
        if (auto target = io::resolveOutput(path); !target) raise(target.error());
        check(io::checkDistinct({{"output", path}}, {{"truth", truthFile}}));
        Status status;
        validation::SimulateReport report;
        Interruption interruption;
        auto interruptible = request;
        interruptible.interrupted = [&interruption] { return interruption.pending(); };
        {
          py::gil_scoped_release release;
          auto done = validation::simulateFile(detector.calorimeter(), eta, interruptible, path,
                                               [&](std::int64_t) { interruption.check(); });
          if (done) {
            report = *done;
          } else {
            status = done.error();
          }
        }
        interruption.raiseIfPending();
        check(status);
        py::dict d;
        d["events"] = report.events;
        d["rows"] = report.rows;
        return d;
      },
      py::arg("truth"), py::arg("events"), py::arg("detector") = py::none(), py::kw_only(),
      py::arg("output") = py::none(), py::arg("seed") = sim::SimulationOptions{}.seed,
      py::arg("process") = std::string(sim::name(sim::GeneratorOptions{}.process)), py::arg("beam_energy") = py::none(),
      py::arg("theta_min_deg") = py::none(), py::arg("theta_max_deg") = py::none(),
      py::arg("run") = sim::SimulationOptions{}.run, py::arg("ideal") = false,
      py::arg("off") = std::vector<std::string>{}, py::arg("dead_counters") = py::none(),
      py::arg("point_showers") = false, py::arg("threads") = 0, py::arg("hits") = true,
      "simulates events with the truth alignment `truth` (12 values, native units, or a parameter, fit-result or "
      "placements file), as emcalign simulate does: into `output` (HDF5, or CSV for .csv; the same file as the "
      "command line's), returning {events, rows}, or without output as the dict of columns read_events gives. "
      "process 'ee', 'gg' or '3pi'; beam_energy MeV (None: the process's default); theta_*_deg the generated "
      "polar range; off: realism effects switched off by name; dead_counters: counter indices (None: the "
      "default few, []: none); threads 0: all cores (the events do not depend on it)");
}

}  // namespace emcalign::python
