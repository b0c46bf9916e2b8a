// The detector simulation with a known (truth) alignment: events as numpy columns, or a file
// as `emcalign simulate` writes it (validation/simulate_file.hpp).

#include <fmt/format.h>

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
  if (py::isinstance<py::str>(truth) || py::hasattr(truth, "__fspath__")) {
    file = truth.cast<Path>().string();
    const auto loaded = unwrap(apply::loadAlignment(file, detector.calorimeter()));
    for (const auto& w : loaded.warnings) {
      if (PyErr_WarnEx(PyExc_UserWarning, w.c_str(), 1) != 0) throw py::error_already_set();
    }
    return loaded.parameters;
  }
  return parametersOf(truth.cast<Array>());
}

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

validation::SimulateRequest requestOf(const SimulateArgs& a, const Detector& detector) {
  if (a.events < 0) raise(Error{fmt::format("events: {} is negative", a.events)});
  if (a.threads < 0) raise(Error{fmt::format("threads: {} is negative (0: all cores)", a.threads)});
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

// The events in memory, as read_events would give them from the file.
py::dict simulateColumns(const geometry::Calorimeter& calo, const geometry::AlignmentParameters& truth,
                         const validation::SimulateRequest& request) {
  std::vector<ParticleRow> rows;
  std::vector<TruthRow> truthRows;
  std::vector<Hit> hits;
  Status status;
  {
    py::gil_scoped_release release;
    auto simulation = sim::Simulation::create(calo, truth, request.options);
    if (simulation) {
      status = simulation->run(
          request.events, request.threads,
          [&](std::span<const ParticleRow> r, std::span<const TruthRow> t, std::span<const Hit> h) -> Status {
            rows.insert(rows.end(), r.begin(), r.end());
            truthRows.insert(truthRows.end(), t.begin(), t.end());
            if (request.hits) hits.insert(hits.end(), h.begin(), h.end());
            return {};
          });
    } else {
      status = simulation.error();
    }
  }
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
        const auto request = requestOf({events, seed, process, beamEnergy, thetaMinDeg, thetaMaxDeg, run, ideal, off,
                                        deadCounters, pointShowers, threads, hits},
                                       detector);
        if (!output) return simulateColumns(detector.calorimeter(), eta, request);
        const std::string path = output->string();
        if (auto target = io::resolveOutput(path); !target) raise(target.error());
        check(io::checkDistinct({{"output", path}}, {{"truth", truthFile}}));
        Status status;
        validation::SimulateReport report;
        {
          py::gil_scoped_release release;
          auto done = validation::simulateFile(detector.calorimeter(), eta, request, path);
          if (done) {
            report = *done;
          } else {
            status = done.error();
          }
        }
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
