#include "emcalign/apply/correct.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <span>
#include <tuple>

#include <fmt/format.h>

#include "emcalign/apply/cluster_correction.hpp"
#include "emcalign/geometry/counter_geometry.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/sim/reconstruction.hpp"

namespace emcalign::apply {

std::string_view name(CorrectionMethod m) {
  switch (m) {
    case CorrectionMethod::Auto:
      return "auto";
    case CorrectionMethod::Hits:
      return "hits";
    case CorrectionMethod::Clusters:
      return "clusters";
  }
  return "?";
}

std::optional<CorrectionMethod> correctionMethodFromName(std::string_view n) {
  for (CorrectionMethod m : {CorrectionMethod::Auto, CorrectionMethod::Hits, CorrectionMethod::Clusters}) {
    if (name(m) == n) return m;
  }
  return std::nullopt;
}

namespace {

// The hits method on one block: each cluster row rebuilt from its counters at their aligned
// centres, by the reconstruction the simulation uses (sim/reconstruction.hpp).
Status correctByHits(std::span<ParticleRow> rows, std::span<const Hit> hits, const geometry::CounterGeometry& aligned,
                     double w0, const std::string& source) {
  std::size_t at = 0;
  const int counters = aligned.calorimeter().size();
  for (ParticleRow& r : rows) {
    const std::span<const Hit> own(hits.data() + at, static_cast<std::size_t>(r.hitCount));
    at += own.size();
    if (std::isnan(r.energy)) continue;
    for (const Hit& h : own) {
      if (h.counter >= counters) {
        return Error{
            fmt::format("{}: run {} event {}: counter {} of a hit is not one of this detector's {} counters "
                        "(another --detector?)",
                        source, r.run, r.event, h.counter, counters)};
      }
    }
    const auto direction = sim::clusterDirection(own, aligned, w0);
    if (!direction) {
      return Error{
          fmt::format("{}: run {} event {}: the cluster's counters give no direction (all weights are 0 "
                      "with W0 = {})",
                      source, r.run, r.event, w0)};
    }
    r.thetaEmc = direction->first;
    r.phiEmc = direction->second;
  }
  return {};
}

}  // namespace

Result<CorrectReport> correctFiles(const std::vector<std::string>& inputs, const std::string& output,
                                   const geometry::Calorimeter& calo, const geometry::AlignmentTransform& transform,
                                   const CorrectOptions& o) {
  // One alignment for every run: shared without a copy, never freed through this pointer.
  const std::shared_ptr<const geometry::AlignmentTransform> one(&transform, [](const geometry::AlignmentTransform*) {});
  return correctFiles(
      inputs, output, calo, [&](std::int64_t) { return Result(one); }, o);
}

Result<CorrectReport> correctFiles(const std::vector<std::string>& inputs, const std::string& output,
                                   const geometry::Calorimeter& calo, const AlignmentOfRun& alignmentOf,
                                   const CorrectOptions& o) {
  auto reader = io::EventReader::open(inputs, o.reader);
  if (!reader) return reader.error();
  CorrectReport report;
  std::vector<ParticleRow> rows;
  auto first = (*reader)->next(rows);
  if (!first) return first.error();
  // The input's hits decide the method of `auto` (files without hits: clusters).
  const bool hits = (*reader)->hits() != nullptr;
  if (o.method == CorrectionMethod::Hits && !hits) {
    return Error{
        fmt::format("{}: --method hits needs event files with counter hits (emcalign simulate writes them to "
                    "HDF5); this one has none: use --method clusters",
                    inputs.front())};
  }
  // Rebuilding a cluster from its counters is the identity at zero alignment only when the
  // file's clusters were made that way: not by `simulate --ideal` or `--off counter-directions`
  // (directions from the deposit itself), as the file's "simulation" attribute says.
  bool fromCounters = true;
  for (const auto& [key, value] : (*reader)->attributes()) {
    if (key != "simulation") continue;
    auto j = io::Json::parse(value, nullptr, false);
    if (j.is_discarded() || !j.is_object()) continue;
    const io::Json off = j.value("off", io::Json::array());
    if (j.value("ideal", false) ||
        (off.is_array() && std::find(off.begin(), off.end(), io::Json("counter-directions")) != off.end())) {
      fromCounters = false;
    }
  }
  if (o.method == CorrectionMethod::Hits && !fromCounters) {
    return Error{
        fmt::format("{}: its clusters were not reconstructed from counter centres (simulate --ideal or --off "
                    "counter-directions), so the hits method cannot rebuild them: use --method clusters",
                    inputs.front())};
  }
  report.method = o.method == CorrectionMethod::Auto
                      ? (hits && fromCounters ? CorrectionMethod::Hits : CorrectionMethod::Clusters)
                      : o.method;
  // The alignment of the current run, and its aligned counters (hits method), made once per
  // alignment.
  struct Current {
    std::int64_t run = -1;
    std::shared_ptr<const geometry::AlignmentTransform> transform;
    const geometry::CounterGeometry* counters = nullptr;
  } current;
  std::map<const geometry::AlignmentTransform*, std::unique_ptr<geometry::CounterGeometry>> counters;
  std::set<const geometry::AlignmentTransform*> used;
  auto select = [&](std::int64_t run) -> Status {
    if (current.transform && run == current.run) return {};
    auto t = alignmentOf(run);
    if (!t) return t.error();
    current.run = run;
    current.transform = *t;
    used.insert(t->get());
    if (report.method == CorrectionMethod::Hits) {
      auto& c = counters[t->get()];
      if (!c) c = std::make_unique<geometry::CounterGeometry>(geometry::CounterGeometry::aligned(calo, **t));
      current.counters = c.get();
    }
    return {};
  };

  io::WriterOptions wo;
  const bool hdf5 = io::formatOf(output) == io::EventFormat::Hdf5;
  wo.withTruth = *first && (*reader)->truth() != nullptr && hdf5;
  wo.withHits = hits && hdf5;
  wo.attributes = (*reader)->attributes();
  std::erase_if(wo.attributes, [](const auto& a) { return a.first == "correction"; });
  wo.attributes.emplace_back("correction", o.description);
  auto writer = io::EventWriter::open(output, wo);
  if (!writer) return writer.error();
  report.truth = wo.withTruth;
  report.hits = wo.withHits;

  geometry::ShowerDepth depth = o.depth;  // at depthEnergy, with depthAt
  double depthEnergy = std::numeric_limits<double>::quiet_NaN();
  for (bool more = *first; more;) {
    const auto* truth = (*reader)->truth();
    const auto* blockHits = (*reader)->hits();
    if ((wo.withTruth && truth == nullptr) || (hits && blockHits == nullptr)) {
      return Error{
          fmt::format("{}: the inputs of one output have {} all or none: a later file has none (correct "
                      "the files one by one)",
                      output, truth == nullptr ? "truth" : "hits")};
    }
    for (std::size_t i = 0; i < rows.size(); ++i) {
      if (i == 0 || rows[i].event != rows[i - 1].event || rows[i].run != rows[i - 1].run) ++report.events;
      if (!std::isnan(rows[i].energy)) ++report.clusters;
    }
    if (report.method == CorrectionMethod::Hits) {
      // Each stretch of one run with its alignment's counters.
      std::size_t begin = 0, hitBegin = 0;
      while (begin < rows.size()) {
        std::size_t end = begin, hitEnd = hitBegin;
        while (end < rows.size() && rows[end].run == rows[begin].run) hitEnd += rows[end++].hitCount;
        if (hitEnd > blockHits->size()) {
          return Error{
              fmt::format("{}: run {}: the rows count more hits than the file has", inputs.front(), rows[begin].run)};
        }
        if (Status s = select(rows[begin].run); !s) return s.error();
        const std::span<ParticleRow> stretch(rows.data() + begin, end - begin);
        const std::span<const Hit> stretchHits(blockHits->data() + hitBegin, hitEnd - hitBegin);
        if (Status s = correctByHits(stretch, stretchHits, *current.counters, o.logWeightW0, inputs.front()); !s) {
          return s.error();
        }
        begin = end;
        hitBegin = hitEnd;
      }
    } else {
      for (ParticleRow& r : rows) {
        if (std::isnan(r.energy)) continue;
        if (Status s = select(r.run); !s) return s.error();
        if (o.depthAt && r.beamEnergy != depthEnergy) {
          auto d = o.depthAt(r.beamEnergy);
          if (!d)
            return Error{
                fmt::format("{}: run {} ({} MeV): {}", (*reader)->path(), r.run, r.beamEnergy, d.error().message)};
          depth = *d;
          depthEnergy = r.beamEnergy;
        }
        std::tie(r.phiEmc, r.thetaEmc) = correctDirection(*current.transform, depth, r.phiEmc, r.thetaEmc, r.energy);
      }
    }
    const std::span<const TruthRow> t = wo.withTruth ? std::span<const TruthRow>(*truth) : std::span<const TruthRow>();
    const std::span<const Hit> h = wo.withHits ? std::span<const Hit>(*blockHits) : std::span<const Hit>();
    if (Status s = (*writer)->append(rows, t, h); !s) return s.error();
    report.rows += static_cast<std::int64_t>(rows.size());
    if (o.progress) o.progress(report.rows);
    auto next = (*reader)->next(rows);
    if (!next) return next.error();
    more = *next;
  }
  if (Status s = (*writer)->close(); !s) return s.error();
  report.alignments = static_cast<int>(used.size());
  return report;
}

}  // namespace emcalign::apply
