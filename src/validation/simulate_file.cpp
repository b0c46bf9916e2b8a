#include "emcalign/validation/simulate_file.hpp"

#include <fmt/format.h>

#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/io/random_trigger_file.hpp"

namespace emcalign::validation {

namespace {

io::Json backgroundSettings(const SimulateRequest& request) {
  const sim::SimulationOptions& o = request.options;
  if (o.recordedBackground) {
    return {{"model", "recorded"},
            {"file", request.backgroundName},
            {"sha256", request.backgroundSha256},
            {"events", o.recordedBackground->size()}};
  }
  return {{"model", "poisson"},
          {"hits_per_event", o.emc.backgroundHitsPerEvent},
          {"mean_energy_mev", o.emc.backgroundMeanEnergy}};
}

io::Json offList(const SimulateRequest& request) {
  io::Json off = io::Json::array();
  for (const auto& e : request.off) off.push_back(e);
  return off;
}

}  // namespace

io::Json randomTriggerSettings(const SimulateRequest& request) {
  const sim::SimulationOptions& o = request.options;
  return io::Json{{"software", fmt::format("emcalign {}", kVersion)},
                  {"process", "random-trigger"},
                  {"events", request.events},
                  {"seed", o.seed},
                  {"run", o.run},
                  {"off", offList(request)},
                  {"dead_counters", o.emc.deadCountersOn ? o.emc.deadCounters : std::vector<int>{}},
                  {"background", backgroundSettings(request)},
                  {"noise_mev", o.emc.noise ? o.emc.noiseSigma : 0.0},
                  {"counter_threshold_mev", o.emc.counterThreshold},
                  {"detector", request.detectorName}};
}

Result<SimulateReport> simulateRandomTriggerFile(const geometry::Calorimeter& calo, const SimulateRequest& request,
                                                 const std::string& output,
                                                 const std::function<void(std::int64_t)>& progress) {
  if (request.options.recordedBackground) {
    return Error{"random-trigger events are made from the Poisson model of the background, not from recorded ones"};
  }
  auto simulation = sim::Simulation::create(calo, geometry::AlignmentParameters{}, request.options);
  if (!simulation) return simulation.error();
  auto events = simulation->randomTrigger(request.events, request.threads, [&](std::int64_t n) {
    if (progress) progress(n);
  });
  if (!events) return events.error();
  if (Status s = io::writeRandomTriggerFile(output, *events, {{"simulation", randomTriggerSettings(request).dump()}});
      !s) {
    return s.error();
  }
  SimulateReport report;
  report.events = request.events;
  report.rows = static_cast<std::int64_t>(events->allHits().size());
  for (std::size_t i = 0; i < events->size(); ++i) report.eventsWritten += events->hits(i).empty() ? 0 : 1;
  return report;
}

io::Json simulationSettings(const SimulateRequest& request) {
  const sim::SimulationOptions& o = request.options;
  return io::Json{
      {"software", fmt::format("emcalign {}", kVersion)},
      {"process", sim::name(o.generator.process)},
      {"events", request.events},
      {"seed", o.seed},
      {"run", o.run},
      {"beam_energy_mev", o.generator.beamEnergy},
      {"beam_energy_spread_mev", o.generator.beamEnergySpread},
      {"theta_range_deg", {o.generator.thetaMin / units::deg, o.generator.thetaMax / units::deg}},
      {"vertex_sigma_cm", {o.generator.vertexSigma.x(), o.generator.vertexSigma.y(), o.generator.vertexSigma.z()}},
      {"ideal", request.ideal},
      {"point_showers", o.emc.pointShowers},
      {"off", offList(request)},
      {"dead_counters", o.emc.deadCountersOn ? o.emc.deadCounters : std::vector<int>{}},
      {"background", backgroundSettings(request)},
      {"cosmic_fraction", o.cosmicFraction},
      {"detector", request.detectorName}};
}

io::Json periodSimulationSettings(const SimulateRequest& request, const geometry::DetectorDescription& detector) {
  io::Json settings = simulationSettings(request);
  for (const char* perRun : {"events", "seed", "run", "beam_energy_mev", "theta_range_deg", "software"}) {
    settings.erase(perRun);
  }
  // e+e- → e+e- is what a period is (and what periods made before another process could be
  // chosen record); another process is said, so that one directory holds one process.
  if (request.options.generator.process == sim::Process::Bhabha) settings.erase("process");
  settings["detector_sha256"] = sha256(io::toJson(detector).dump());
  return settings;
}

Result<SimulateReport> simulateFile(const geometry::Calorimeter& calo, const geometry::AlignmentParameters& truth,
                                    const SimulateRequest& request, const std::string& output,
                                    const std::function<void(std::int64_t)>& progress) {
  auto simulation = sim::Simulation::create(calo, truth, request.options);
  if (!simulation) return simulation.error();
  io::WriterOptions wo;
  wo.withTruth = true;
  wo.withHits = request.hits;
  wo.compression = request.compression;
  wo.attributes = {{"truth_parameters", io::alignmentToJson(truth).dump()},
                   {"simulation", simulationSettings(request).dump()}};
  auto writer = io::EventWriter::open(output, wo);
  if (!writer) return writer.error();
  SimulateReport report;
  report.events = request.events;
  std::int64_t lastEvent = -1;
  const Status done = simulation->run(
      request.events, request.threads,
      [&](std::span<const ParticleRow> r, std::span<const TruthRow> t, std::span<const Hit> h) {
        if (request.interrupted && request.interrupted()) return Status{Error{kInterrupted}};
        report.rows += static_cast<std::int64_t>(r.size());
        for (std::size_t k = 0; k < r.size(); ++k) {  // rows of an event are contiguous, in event order
          if (k == 0 ? r[0].event != lastEvent : r[k].event != r[k - 1].event) ++report.eventsWritten;
        }
        if (!r.empty()) lastEvent = r.back().event;
        return (*writer)->append(r, t, h);
      },
      [&](std::int64_t n) {
        if (progress) progress(n);
      });
  if (!done) return done.error();
  if (Status s = (*writer)->close(); !s) return s.error();
  return report;
}

}  // namespace emcalign::validation
