#include "emcalign/sim/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <future>
#include <limits>
#include <numbers>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <oneapi/tbb/enumerable_thread_specific.h>
#include <oneapi/tbb/global_control.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/task_arena.h>

#include "emcalign/core/types.hpp"

namespace emcalign::sim {

namespace {
// The random stream of the order of the recorded background: beyond any event index.
constexpr std::uint64_t kBackgroundOrderStream = ~std::uint64_t{0};
}  // namespace

void SimulationOptions::setIdealised() {
  generator.radiation = false;
  tracking.multipleScattering = false;
  emc.showerFluctuations = false;
  emc.pointShowers = true;
  emc.energyResolution = false;
  emc.noise = false;
  emc.deadCountersOn = false;
  emc.beamBackground = false;
  emc.layer3OffsetOn = false;
  reconstruction.directionFromCounters = false;
  reconstruction.idealDirectionSigma = 0.0;  // a smeared direction can cross the parting plane
  reconstruction.containment = 1.0;
  cosmicFraction = 0.0;
}

const std::vector<std::string>& SimulationOptions::effectNames() {
  static const std::vector<std::string> names = {
      "radiation",           "background",          "dead-counters", "noise",
      "energy-resolution",   "shower-fluctuations", "layer3-offset", "cosmics",
      "multiple-scattering", "counter-directions"};
  return names;
}

Status SimulationOptions::applyRealism(bool ideal, const std::vector<std::string>& off) {
  if (ideal) setIdealised();
  for (const auto& e : off) {
    if (Status s = switchOff(e); !s) return s;
  }
  return {};
}

Status SimulationOptions::switchOff(std::string_view effect) {
  if (effect == "radiation")
    generator.radiation = false;
  else if (effect == "background")
    emc.beamBackground = false;
  else if (effect == "dead-counters")
    emc.deadCountersOn = false;
  else if (effect == "noise")
    emc.noise = false;
  else if (effect == "energy-resolution")
    emc.energyResolution = false;
  else if (effect == "shower-fluctuations")
    emc.showerFluctuations = false;
  else if (effect == "layer3-offset")
    emc.layer3OffsetOn = false;
  else if (effect == "cosmics")
    cosmicFraction = 0.0;
  else if (effect == "multiple-scattering")
    tracking.multipleScattering = false;
  else if (effect == "counter-directions")
    reconstruction.directionFromCounters = false;
  else
    return Error{fmt::format("unknown effect '{}' (known: {})", effect, fmt::join(effectNames(), ", "))};
  return {};
}

Status SimulationOptions::validate(int counters) const {
  if (Status s = generator.validate(); !s) return s;
  if (Status s = tracking.validate(); !s) return s;
  if (Status s = emc.validate(counters); !s) return s;
  if (Status s = reconstruction.validate(); !s) return s;
  if (!(cosmicFraction >= 0.0 && cosmicFraction <= 1.0)) return Error{"cosmic fraction must be in [0, 1]"};
  if (!(muonVetoEfficiency >= 0.0 && muonVetoEfficiency <= 1.0)) {
    return Error{"muon veto efficiency must be in [0, 1]"};
  }
  if (recordedBackground) {
    if (recordedBackground->empty()) return Error{"the recorded beam background has no event"};
    if (recordedBackground->size() > std::numeric_limits<std::uint32_t>::max()) {
      return Error{"the recorded beam background has more events than the simulation can use"};
    }
    for (const Hit& h : recordedBackground->allHits()) {
      if (h.counter < 0 || h.counter >= counters || !(h.energy >= 0.0 && h.energy <= kMaxRandomTriggerEnergyMev)) {
        return Error{
            fmt::format("the recorded beam background has a hit in counter {} ({} MeV): not a counter of "
                        "this detector (0..{}) or not an energy",
                        h.counter, h.energy, counters - 1)};
      }
    }
  }
  return {};
}

Result<Simulation> Simulation::create(const geometry::Calorimeter& calorimeter,
                                      const geometry::AlignmentParameters& truth, SimulationOptions options) {
  if (Status s = options.validate(calorimeter.size()); !s) return s.error();
  auto transform = geometry::AlignmentTransform::create(truth, geometry::AlignmentRadii::of(calorimeter.description()));
  if (!transform) return transform.error();
  Simulation sim;
  sim.calo_ = &calorimeter;
  sim.options_ = std::move(options);
  sim.response_ = std::make_shared<const CalorimeterResponse>(calorimeter, *transform, sim.options_.emc);
  sim.neighbours_ = std::make_shared<const CounterNeighbours>(calorimeter);
  sim.nominal_ = std::make_shared<const geometry::CounterGeometry>(geometry::CounterGeometry::nominal(calorimeter));
  sim.tracking_ = TrackingSystem(sim.options_.tracking);
  if (const auto& recorded = sim.options_.recordedBackground) {
    // A permutation drawn from the seed (Fisher–Yates), on a stream no event uses.
    auto& order = sim.backgroundOrder_;
    order.resize(recorded->size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<std::uint32_t>(i);
    Rng rng(sim.options_.seed, kBackgroundOrderStream);
    for (std::size_t i = order.size(); i > 1; --i) {
      const auto j = static_cast<std::size_t>(rng.uniform() * static_cast<double>(i));
      std::swap(order[i - 1], order[std::min(j, i - 1)]);
    }
  }
  return sim;
}

void Simulation::cosmic(Rng& rng, GeneratedEvent& event) const {
  // A cosmic muon crossing the detector: zenith angle ∝ cos²ζ, passing within 10 cm of the
  // centre. The TS sees it as two outgoing half-tracks from its closest approach.
  const double cosZenith = std::cbrt(rng.uniformOpen());
  const double sinZenith = std::sqrt(1.0 - cosZenith * cosZenith);
  double c, s;
  rng.unitCircle(c, s);
  const Vec3 down(sinZenith * c, -cosZenith, sinZenith * s);
  Vec3 point(rng.uniform(-10.0, 10.0), 0.0, rng.uniform(-15.0, 15.0));
  point -= point.dot(down) * down;
  constexpr double kEnergy = 2000.0;
  const double p = std::sqrt(kEnergy * kEnergy - mass::Muon * mass::Muon);
  event.vertex = point;
  event.particles.clear();
  event.particles.push_back({pdg::MuonPlus, -p * down, kEnergy});
  event.particles.push_back({pdg::MuonMinus, p * down, kEnergy});
}

using Showering = CalorimeterResponse::Showering;
using Tracking = CalorimeterResponse::Tracking;

namespace {

// The generated particles through the detector, particle k the hits' source k: a charged one
// scattered and measured by the TS, then showering (e±) or leaving its track (π±, μ±) in the
// EMC; a photon showers.
inline void passParticles(const GeneratedEvent& ev, int sources, const TrackingSystem& tracking,
                          const CalorimeterResponse& response, Rng& rng, EventScratch& scratch) {
  CounterHits& hits = scratch.hits;
  for (int k = 0; k < sources; ++k) {
    const GeneratedParticle& particle = ev.particles[static_cast<std::size_t>(k)];
    const double p = particle.momentum.norm();
    if (!(p > 0.0)) continue;
    const Vec3 d = particle.momentum / p;
    if (particle.charge() != 0) {
      const ChargedPath path = tracking.scatter(ev.vertex, d, p, p / particle.energy, rng);
      if (auto t = tracking.measure(path, rng)) {
        scratch.tracks.push_back(*t);
        scratch.trackSource.push_back(k);
      }
      const int apdg = std::abs(particle.pdg);
      if (apdg == pdg::Electron) {
        response.shower(hits, k, particle.energy, Showering::Electron, path.point, path.direction, rng);
      } else {
        const Tracking kind = apdg == pdg::PiPlus ? Tracking::Pion : Tracking::Muon;
        response.track(hits, k, particle.energy - particle.mass(), kind, path.point, path.direction, rng);
      }
    } else if (particle.pdg == pdg::Photon) {
      response.shower(hits, k, particle.energy, Showering::Photon, ev.vertex, d, rng);
    }
  }
}

// The reconstructed event as rows: a row per track (with its matched cluster), then a row per
// cluster no track claimed (a photon), each with its truth.
struct EventRows {
  const GeneratedEvent& ev;
  const EventScratch& scratch;
  int sources;
  std::vector<ParticleRow>& rows;
  std::vector<TruthRow>& truth;
  std::vector<Hit>* hitsOut;

  // The truth of a row made by `source` (−1: the beam background).
  [[nodiscard]] TruthRow truthOf(int source) const {
    TruthRow t;
    t.vertex = ev.vertex;
    t.showerCentre = scratch.hits.sourceCentre(source >= 0 ? source : CounterHits::kBackground);
    if (source >= 0 && source < sources) {
      const auto& gp = ev.particles[static_cast<std::size_t>(source)];
      t.pdg = gp.pdg;
      t.energy = gp.energy;
      t.theta = geometry::polar(gp.momentum);
      t.phi = geometry::azimuth(gp.momentum);
    } else {
      t.energy = t.theta = t.phi = kNaN;
    }
    return t;
  }

  // A cluster row carries the cluster's counters (when the caller keeps hits).
  void keepHits(ParticleRow& r, const Cluster& c) const {
    if (hitsOut == nullptr) return;
    r.hitCount = c.counters;
    const auto first = scratch.clusters.hits.begin() + c.firstHit;
    hitsOut->insert(hitsOut->end(), first, first + c.counters);
  }

  // The tracks, each with the cluster matched to it (`match`, −1: none), marked `used`.
  void charged(const ParticleRow& base, const std::vector<int>& match, std::vector<char>& used) const {
    for (std::size_t i = 0; i < scratch.tracks.size(); ++i) {
      ParticleRow r = base;
      const auto& t = scratch.tracks[i];
      r.charged = 1;
      r.z0 = t.z0;
      r.rho = t.rho;
      r.phiTs = t.phi;
      r.thetaTs = t.theta;
      if (match[i] >= 0) {
        const Cluster& c = scratch.clusterList[static_cast<std::size_t>(match[i])];
        used[static_cast<std::size_t>(match[i])] = 1;
        r.energy = c.energy;
        r.phiEmc = c.phi;
        r.thetaEmc = c.theta;
        keepHits(r, c);
      } else {
        r.energy = r.phiEmc = r.thetaEmc = kNaN;
      }
      rows.push_back(r);
      truth.push_back(truthOf(scratch.trackSource[i]));
    }
  }

  // Photons: the clusters no track claimed, most energetic first.
  void photons(const ParticleRow& base, const std::vector<char>& used) const {
    std::vector<std::size_t> unclaimed;
    for (std::size_t c = 0; c < scratch.clusterList.size(); ++c) {
      if (!used[c]) unclaimed.push_back(c);
    }
    std::stable_sort(unclaimed.begin(), unclaimed.end(), [&](std::size_t a, std::size_t b) {
      return scratch.clusterList[a].energy > scratch.clusterList[b].energy;
    });
    for (std::size_t c : unclaimed) {
      const Cluster& cl = scratch.clusterList[c];
      ParticleRow r = base;
      r.charged = 0;
      r.z0 = r.rho = r.phiTs = r.thetaTs = kNaN;
      r.energy = cl.energy;
      r.phiEmc = cl.phi;
      r.thetaEmc = cl.theta;
      keepHits(r, cl);
      rows.push_back(r);
      truth.push_back(truthOf(cl.mainSource == CounterHits::kBackground ? -1 : cl.mainSource));
    }
  }
};

}  // namespace

void Simulation::simulateEvent(std::int64_t index, EventScratch& scratch, std::vector<ParticleRow>& rows,
                               std::vector<TruthRow>& truth, std::vector<Hit>* hitsOut) const {
  const auto& o = options_;
  Rng rng(o.seed, static_cast<std::uint64_t>(index));
  const bool isCosmic = o.cosmicFraction > 0.0 && rng.uniform() < o.cosmicFraction;
  GeneratedEvent& ev = scratch.event;
  if (isCosmic) {
    cosmic(rng, ev);
  } else if (!generate(o.generator, rng, ev).made()) {
    if (scratch.failedEvent < 0 || index < scratch.failedEvent) scratch.failedEvent = index;
    return;
  }

  CounterHits& hits = scratch.hits;
  hits.clear();
  scratch.tracks.clear();
  scratch.trackSource.clear();
  const int sources = std::min<int>(static_cast<int>(ev.particles.size()), CounterHits::kMaxSources - 1);
  passParticles(ev, sources, tracking_, *response_, rng, scratch);
  if (o.recordedBackground) {
    response_->mergeRecorded(hits, o.recordedBackground->hits(static_cast<std::size_t>(recordedEventOf(index))));
  } else {
    response_->background(hits, rng);
  }
  hits.digitize(o.emc, response_->gains(), rng);
  findClusters(hits, *nominal_, *neighbours_, o.reconstruction, scratch.clusters, rng, scratch.clusterList);
  const std::vector<int> match = matchTracks(scratch.tracks, scratch.clusterList, o.reconstruction);
  const std::int8_t veto = isCosmic && rng.uniform() < o.muonVetoEfficiency ? 1 : 0;

  ParticleRow base;
  base.run = o.run;
  base.event = index;
  base.beamEnergy = o.generator.beamEnergy;
  base.muonVeto = veto;
  std::vector<char> used(scratch.clusterList.size(), 0);
  const EventRows out{ev, scratch, sources, rows, truth, hitsOut};
  out.charged(base, match, used);
  out.photons(base, used);
}

Status Simulation::run(std::int64_t events, int threads, const Sink& sink, const Progress& progress) const {
  if (events < 0) return Error{"the number of events must not be negative"};
  const int concurrency = threads > 0 ? threads : tbb::this_task_arena::max_concurrency();
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(concurrency));
  tbb::enumerable_thread_specific<EventScratch> scratch([this] { return EventScratch(calo_->size()); });

  // Blocks of events are made in parallel, in chunks whose rows are kept apart and then
  // handed over in event order: the output is the same on any number of threads. The sink
  // (writing, compressing) of a block runs on its own thread while the next block is made.
  constexpr std::int64_t kChunk = 512;
  constexpr std::int64_t kBlock = 64 * kChunk;
  struct Chunk {
    std::vector<ParticleRow> rows;
    std::vector<TruthRow> truth;
    std::vector<Hit> hits;
  };
  std::vector<Chunk> buffers[2];
  std::future<Status> pending;
  auto drain = [&pending]() -> Status { return pending.valid() ? pending.get() : Status{}; };
  int which = 0;
  for (std::int64_t first = 0; first < events; first += kBlock, which ^= 1) {
    const std::int64_t last = std::min(events, first + kBlock);
    const auto nChunks = static_cast<std::size_t>((last - first + kChunk - 1) / kChunk);
    std::vector<Chunk>& chunks = buffers[which];
    chunks.resize(nChunks);
    tbb::parallel_for(std::size_t{0}, nChunks, [&](std::size_t c) {
      Chunk& chunk = chunks[c];
      chunk.rows.clear();
      chunk.truth.clear();
      chunk.hits.clear();
      EventScratch& s = scratch.local();
      const std::int64_t begin = first + static_cast<std::int64_t>(c) * kChunk;
      const std::int64_t end = std::min(last, begin + kChunk);
      for (std::int64_t i = begin; i < end; ++i) simulateEvent(i, s, chunk.rows, chunk.truth, &chunk.hits);
    });
    for (EventScratch& s : scratch) {
      if (s.failedEvent >= 0) {
        return Error{
            fmt::format("event {}: the {} generator made no event in 2^20 trials: its options (beam energy {} "
                        "MeV, polar range) are at the edge of what it models",
                        s.failedEvent, name(options_.generator.process), options_.generator.beamEnergy)};
      }
    }
    if (Status s = drain(); !s) return s;
    pending = std::async(std::launch::async, [&sink, &chunks]() -> Status {
      for (const Chunk& chunk : chunks) {
        if (Status s = sink(chunk.rows, chunk.truth, chunk.hits); !s) return s;
      }
      return {};
    });
    if (progress) progress(last);
  }
  return drain();
}

std::int64_t Simulation::recordedEventOf(std::int64_t index) const {
  if (backgroundOrder_.empty() || index < 0) return -1;
  return backgroundOrder_[static_cast<std::size_t>(index % static_cast<std::int64_t>(backgroundOrder_.size()))];
}

void Simulation::randomTriggerEvent(std::int64_t index, EventScratch& scratch, std::vector<Hit>& out) const {
  Rng rng(options_.seed, static_cast<std::uint64_t>(index));
  CounterHits& hits = scratch.hits;
  hits.clear();
  out.clear();
  response_->background(hits, rng);
  hits.digitize(options_.emc, response_->gains(), rng);
  for (int c : hits.fired()) out.push_back({c, hits.energy(c)});
}

Result<RandomTriggerEvents> Simulation::randomTrigger(std::int64_t events, int threads,
                                                      const Progress& progress) const {
  if (events < 0) return Error{"the number of events must not be negative"};
  if (static_cast<std::uint64_t>(events) > kMaxRandomTriggerEvents) {
    return Error{fmt::format("a random-trigger file holds at most {} events", kMaxRandomTriggerEvents)};
  }
  const int concurrency = threads > 0 ? threads : tbb::this_task_arena::max_concurrency();
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(concurrency));
  tbb::enumerable_thread_specific<EventScratch> scratch([this] { return EventScratch(calo_->size()); });
  constexpr std::int64_t kChunk = 4096;
  RandomTriggerEvents out;
  std::vector<std::vector<std::vector<Hit>>> chunks;
  for (std::int64_t first = 0; first < events; first += 64 * kChunk) {
    const std::int64_t last = std::min(events, first + 64 * kChunk);
    const auto nChunks = static_cast<std::size_t>((last - first + kChunk - 1) / kChunk);
    chunks.assign(nChunks, {});
    tbb::parallel_for(std::size_t{0}, nChunks, [&](std::size_t c) {
      EventScratch& s = scratch.local();
      const std::int64_t begin = first + static_cast<std::int64_t>(c) * kChunk;
      const std::int64_t end = std::min(last, begin + kChunk);
      auto& chunk = chunks[c];
      chunk.resize(static_cast<std::size_t>(end - begin));
      for (std::int64_t i = begin; i < end; ++i) randomTriggerEvent(i, s, chunk[static_cast<std::size_t>(i - begin)]);
    });
    std::int64_t index = first;
    for (const auto& chunk : chunks) {
      for (const auto& hits : chunk) out.append(options_.run, index++, hits);
    }
    if (progress) progress(last);
  }
  return out;
}

}  // namespace emcalign::sim
