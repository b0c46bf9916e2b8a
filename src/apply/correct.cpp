#include "emcalign/apply/correct.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
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

namespace {

// Whether the file's clusters were rebuilt from counter centres, so that the hits method is
// the identity at zero alignment: not with `simulate --ideal` or `--off counter-directions`
// (directions from the deposit itself), as the file's "simulation" attribute says.
bool clustersFromCounters(const std::vector<std::pair<std::string, std::string>>& attributes) {
  for (const auto& [key, value] : attributes) {
    if (key != "simulation") continue;
    auto j = io::Json::parse(value, nullptr, false);
    if (j.is_discarded() || !j.is_object()) continue;
    const io::Json off = j.value("off", io::Json::array());
    if (j.value("ideal", false) ||
        (off.is_array() && std::find(off.begin(), off.end(), io::Json("counter-directions")) != off.end())) {
      return false;
    }
  }
  return true;
}

// The method for these inputs: the one asked for, or for `auto` the hits method when the
// files have hits and their clusters were made from counters.
Result<CorrectionMethod> methodFor(const io::EventReader& reader, const CorrectOptions& o, const std::string& input) {
  const bool hits = reader.hits() != nullptr;
  if (o.method == CorrectionMethod::Hits && !hits) {
    return Error{
        fmt::format("{}: --method hits needs event files with counter hits (emcalign simulate writes them to "
                    "HDF5); this one has none: use --method clusters",
                    input)};
  }
  const bool fromCounters = clustersFromCounters(reader.attributes());
  if (o.method == CorrectionMethod::Hits && !fromCounters) {
    return Error{
        fmt::format("{}: its clusters were not reconstructed from counter centres (simulate --ideal or --off "
                    "counter-directions), so the hits method cannot rebuild them: use --method clusters",
                    input)};
  }
  if (o.method != CorrectionMethod::Auto) return o.method;
  return hits && fromCounters ? CorrectionMethod::Hits : CorrectionMethod::Clusters;
}

// The alignment of the current run and, for the hits method, its aligned counters, made once
// per alignment.
class RunAlignments {
 public:
  RunAlignments(const geometry::Calorimeter& calo, const AlignmentOfRun& alignmentOf, bool withCounters)
      : calo_(calo), alignmentOf_(alignmentOf), withCounters_(withCounters) {}

  Status select(std::int64_t run) {
    if (transform_ && run == run_) return {};
    auto t = alignmentOf_(run);
    if (!t) return t.error();
    run_ = run;
    transform_ = *t;
    used_.insert(t->get());
    if (withCounters_) {
      auto& c = counters_[t->get()];
      if (!c) c = std::make_unique<geometry::CounterGeometry>(geometry::CounterGeometry::aligned(calo_, **t));
      current_ = c.get();
    }
    return {};
  }
  [[nodiscard]] const geometry::AlignmentTransform& transform() const { return *transform_; }
  [[nodiscard]] const geometry::CounterGeometry& counters() const { return *current_; }
  [[nodiscard]] int used() const { return static_cast<int>(used_.size()); }

 private:
  const geometry::Calorimeter& calo_;
  const AlignmentOfRun& alignmentOf_;
  bool withCounters_;
  std::int64_t run_ = -1;
  std::shared_ptr<const geometry::AlignmentTransform> transform_;
  const geometry::CounterGeometry* current_ = nullptr;
  std::map<const geometry::AlignmentTransform*, std::unique_ptr<geometry::CounterGeometry>> counters_;
  std::set<const geometry::AlignmentTransform*> used_;
};

// The hits method on a block: each stretch of one run with its alignment's counters.
Status correctBlockByHits(std::span<ParticleRow> rows, std::span<const Hit> hits, RunAlignments& alignments, double w0,
                          const std::string& source) {
  std::size_t begin = 0, hitBegin = 0;
  while (begin < rows.size()) {
    std::size_t end = begin, hitEnd = hitBegin;
    while (end < rows.size() && rows[end].run == rows[begin].run) hitEnd += rows[end++].hitCount;
    if (hitEnd > hits.size()) {
      return Error{fmt::format("{}: run {}: the rows count more hits than the file has", source, rows[begin].run)};
    }
    if (Status s = alignments.select(rows[begin].run); !s) return s;
    if (Status s = correctByHits(rows.subspan(begin, end - begin), hits.subspan(hitBegin, hitEnd - hitBegin),
                                 alignments.counters(), w0, source);
        !s) {
      return s;
    }
    begin = end;
    hitBegin = hitEnd;
  }
  return {};
}

// The cluster method on a block: each cluster's direction corrected at the depth of its beam
// energy (o.depthAt, remembered between blocks in `depth` and `depthEnergy`).
Status correctBlockByClusters(std::span<ParticleRow> rows, RunAlignments& alignments, const CorrectOptions& o,
                              geometry::ShowerDepth& depth, double& depthEnergy, const std::string& source) {
  for (ParticleRow& r : rows) {
    if (std::isnan(r.energy)) continue;
    if (Status s = alignments.select(r.run); !s) return s;
    if (o.depthAt && r.beamEnergy != depthEnergy) {
      auto d = o.depthAt(r.beamEnergy);
      if (!d) return Error{fmt::format("{}: run {} ({} MeV): {}", source, r.run, r.beamEnergy, d.error().message)};
      depth = *d;
      depthEnergy = r.beamEnergy;
    }
    std::tie(r.phiEmc, r.thetaEmc) = correctDirection(alignments.transform(), depth, r.phiEmc, r.thetaEmc, r.energy);
  }
  return {};
}

}  // namespace

Result<CorrectReport> correctFiles(const std::vector<std::string>& inputs, const std::string& output,
                                   const geometry::Calorimeter& calo, const AlignmentOfRun& alignmentOf,
                                   const CorrectOptions& o) {
  auto reader = io::EventReader::open(inputs, o.reader);
  if (!reader) return reader.error();
  CorrectReport report;
  std::vector<ParticleRow> rows;
  auto first = (*reader)->next(rows);
  if (!first) return first.error();
  auto method = methodFor(**reader, o, inputs.front());
  if (!method) return method.error();
  report.method = *method;
  const bool hits = (*reader)->hits() != nullptr;
  RunAlignments alignments(calo, alignmentOf, report.method == CorrectionMethod::Hits);

  io::WriterOptions wo;
  const io::EventFormat format = io::outputFormatOf(output, inputs.front());
  const bool hdf5 = format == io::EventFormat::Hdf5;
  wo.withTruth = *first && (*reader)->truth() != nullptr && hdf5;
  wo.withHits = hits && hdf5;
  wo.compression = o.compression;
  wo.placement = o.placement;
  wo.attributes = (*reader)->attributes();
  std::erase_if(wo.attributes, [](const auto& a) { return a.first == "correction"; });
  wo.attributes.emplace_back("correction", o.description);
  auto writer = io::EventWriter::open(output, wo, format);
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
          fmt::format("{}: has no {}, which {} has: the inputs of one output have them all or none (correct "
                      "the files one by one)",
                      (*reader)->path(), truth == nullptr ? "truth" : "hits", inputs.front())};
    }
    for (std::size_t i = 0; i < rows.size(); ++i) {
      if (i == 0 || !sameEvent(rows[i], rows[i - 1])) ++report.events;
      if (!std::isnan(rows[i].energy)) ++report.clusters;
    }
    const Status corrected = report.method == CorrectionMethod::Hits
                                 ? correctBlockByHits(rows, *blockHits, alignments, o.logWeightW0, (*reader)->path())
                                 : correctBlockByClusters(rows, alignments, o, depth, depthEnergy, (*reader)->path());
    if (!corrected) return corrected.error();
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
  report.alignments = alignments.used();
  return report;
}

Result<CorrectReport> correctEachInto(const std::vector<std::string>& inputs, const std::string& directory,
                                      const geometry::Calorimeter& calo, const AlignmentOfRun& alignmentOf,
                                      const CorrectOptions& options,
                                      const std::function<void(const std::string&)>& done) {
  std::map<std::string, std::string> byName;
  for (const auto& in : inputs) {
    const std::string name = std::filesystem::path(in).filename().string();
    if (auto [it, fresh] = byName.emplace(name, in); !fresh) {
      return Error{fmt::format("{} and {} have the same name: their corrected files in {} would be one", it->second, in,
                               directory)};
    }
  }
  CorrectOptions o = options;
  o.placement = io::Placement::InDirectory;
  CorrectReport total;
  bool first = true;
  for (const auto& in : inputs) {
    const std::string out = (std::filesystem::path(directory) / std::filesystem::path(in).filename()).string();
    auto r = correctFiles({in}, out, calo, alignmentOf, o);
    if (!r) return r.error();
    if (first) total.method = r->method;
    total.events += r->events;
    total.rows += r->rows;
    total.clusters += r->clusters;
    total.truth = first ? r->truth : total.truth && r->truth;
    total.hits = first ? r->hits : total.hits && r->hits;
    total.alignments = first ? r->alignments : std::max(total.alignments, r->alignments);
    first = false;
    if (done) done(out);
  }
  return total;
}

}  // namespace emcalign::apply
