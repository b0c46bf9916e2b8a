// Speed of emcalign correct (apply/correct.hpp), in particles (rows) per second:
//   build/bin/emcalign_bench_correct
// - the correction alone, on rows in memory: the cluster method (docs/contract.md §9) and the hits
//   method (each cluster rebuilt from its counters at the aligned centres);
// - the whole command on a file: read (the HDF5 reader process), correct, write, for both
//   methods (a simulated 200 000-event HDF5 file with truth and hits, made once).

#include <unistd.h>

#include <cmath>
#include <filesystem>

#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include "emcalign/apply/cluster_correction.hpp"
#include "emcalign/apply/correct.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/sim/reconstruction.hpp"
#include "emcalign/sim/simulation.hpp"

namespace {

using namespace emcalign;
namespace fs = std::filesystem;

const geometry::Calorimeter& snd() {
  static const geometry::Calorimeter calo = *geometry::Calorimeter::create(geometry::DetectorDescription::sndDefault());
  return calo;
}

geometry::AlignmentParameters paperLike() {
  geometry::AlignmentParameters eta;
  eta[Param::Alpha] = 3.0 * units::deg;
  eta[Param::Dx] = 0.3;
  eta[Param::Dp1] = 0.6;
  eta[Param::Dp2] = 0.2;
  eta[Param::Dp3] = 0.4;
  eta[Param::DyRel] = 0.05;
  return eta;
}

struct Sample {
  std::vector<ParticleRow> rows;
  std::vector<TruthRow> truth;
  std::vector<Hit> hits;
};

const Sample& sample() {
  static const Sample s = [] {
    Sample out;
    auto sim = sim::Simulation::create(snd(), paperLike(), sim::SimulationOptions{});
    sim::EventScratch scratch(snd().size());
    for (std::int64_t i = 0; i < 50000; ++i) sim->simulateEvent(i, scratch, out.rows, out.truth, &out.hits);
    return out;
  }();
  return s;
}

const geometry::AlignmentTransform& transform() {
  static const auto t =
      *geometry::AlignmentTransform::create(paperLike(), geometry::AlignmentRadii::of(snd().description()));
  return t;
}

void BM_ClusterMethodInMemory(benchmark::State& state) {
  const auto& rows = sample().rows;
  const auto depth = geometry::ShowerDepth::of(snd().description());
  for (auto _ : state) {
    double sum = 0.0;
    for (const ParticleRow& r : rows) {
      if (std::isnan(r.energy)) continue;
      const auto [phi, theta] = apply::correctDirection(transform(), depth, r.phiEmc, r.thetaEmc, r.energy);
      sum += phi + theta;
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(rows.size()));
}
BENCHMARK(BM_ClusterMethodInMemory)->Unit(benchmark::kMillisecond);

void BM_HitsMethodInMemory(benchmark::State& state) {
  const auto& s = sample();
  const auto aligned = geometry::CounterGeometry::aligned(snd(), transform());
  for (auto _ : state) {
    double sum = 0.0;
    std::size_t at = 0;
    for (const ParticleRow& r : s.rows) {
      const std::span<const Hit> own(s.hits.data() + at, static_cast<std::size_t>(r.hitCount));
      at += own.size();
      if (own.empty()) continue;
      if (const auto d = sim::clusterDirection(own, aligned, 3.5)) sum += d->first + d->second;
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(s.rows.size()));
}
BENCHMARK(BM_HitsMethodInMemory)->Unit(benchmark::kMillisecond);

// A 200 000-event HDF5 file with truth and hits, written once per process.
const std::string& eventFile() {
  static const std::string path = [] {
    const std::string p =
        (fs::temp_directory_path() / fmt::format("emcalign_bench_correct_{}.h5", ::getpid())).string();
    sim::SimulationOptions o;
    o.generator.thetaMin = 40.0 * units::deg;
    o.generator.thetaMax = 140.0 * units::deg;
    auto sim = sim::Simulation::create(snd(), paperLike(), o);
    io::WriterOptions wo;
    wo.withTruth = wo.withHits = true;
    auto writer = io::EventWriter::open(p, wo);
    (void)sim->run(200000, 0, [&](auto rows, auto truth, auto hits) { return (*writer)->append(rows, truth, hits); });
    (void)(*writer)->close();
    return p;
  }();
  return path;
}

void BM_CorrectFile(benchmark::State& state) {
  const auto method = state.range(0) == 0 ? apply::CorrectionMethod::Clusters : apply::CorrectionMethod::Hits;
  const std::string out = eventFile() + ".out.h5";
  apply::CorrectOptions o;
  o.method = method;
  o.depth = geometry::ShowerDepth::of(snd().description());
  o.description = "{}";
  std::int64_t rows = 0;
  for (auto _ : state) {
    auto r = apply::correctFiles({eventFile()}, out, snd(), transform(), o);
    if (!r) {
      state.SkipWithError(r.error().message.c_str());
      break;
    }
    rows = r->rows;
    fs::remove(out);
  }
  state.SetItemsProcessed(state.iterations() * rows);
  state.SetLabel(method == apply::CorrectionMethod::Clusters ? "clusters" : "hits");
}
// Real time: the reader process works beside this one.
BENCHMARK(BM_CorrectFile)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::error_code ec;
  fs::remove(fs::temp_directory_path() / fmt::format("emcalign_bench_correct_{}.h5", ::getpid()), ec);
  return 0;
}
