#include "emcalign/apply/correct.hpp"

#include <cmath>

#include <fmt/format.h>

#include "emcalign/apply/cluster_correction.hpp"

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

Result<CorrectReport> correctFiles(const std::vector<std::string>& inputs, const std::string& output,
                                   const geometry::Calorimeter& /*calo*/, const geometry::AlignmentTransform& transform,
                                   const CorrectOptions& o) {
  auto reader = io::EventReader::open(inputs, o.reader);
  if (!reader) return reader.error();
  CorrectReport report;
  // The input's hits decide the method of `auto` (files without hits: clusters).
  const bool hits = false;
  if (o.method == CorrectionMethod::Hits && !hits) {
    return Error{fmt::format("{}: --method hits needs event files with counter hits (emcalign simulate writes them to "
                             "HDF5); this one has none: use --method clusters",
                             inputs.front())};
  }
  report.method = CorrectionMethod::Clusters;

  std::vector<ParticleRow> rows;
  auto first = (*reader)->next(rows);
  if (!first) return first.error();
  io::WriterOptions wo;
  wo.withTruth = *first && (*reader)->truth() != nullptr && io::formatOf(output) == io::EventFormat::Hdf5;
  wo.attributes = (*reader)->attributes();
  std::erase_if(wo.attributes, [](const auto& a) { return a.first == "correction"; });
  wo.attributes.emplace_back("correction", o.description);
  auto writer = io::EventWriter::open(output, wo);
  if (!writer) return writer.error();
  report.truth = wo.withTruth;

  for (bool more = *first; more;) {
    for (std::size_t i = 0; i < rows.size(); ++i) {
      if (i == 0 || rows[i].event != rows[i - 1].event || rows[i].run != rows[i - 1].run) ++report.events;
      ParticleRow& r = rows[i];
      if (std::isnan(r.energy)) continue;
      const auto [phi, theta] = correctDirection(transform, o.depth, r.phiEmc, r.thetaEmc, r.energy);
      r.phiEmc = phi;
      r.thetaEmc = theta;
      ++report.clusters;
    }
    const auto* truth = (*reader)->truth();
    if (wo.withTruth && truth == nullptr) {
      return Error{fmt::format("{}: the inputs of one output have truth all or none: a later file has none (write "
                               "CSV, which holds no truth, or correct the files one by one)",
                               output)};
    }
    if (Status s = (*writer)->append(rows, wo.withTruth ? std::span<const TruthRow>(*truth) : std::span<const TruthRow>());
        !s) {
      return s.error();
    }
    report.rows += static_cast<std::int64_t>(rows.size());
    if (o.progress) o.progress(report.rows);
    auto next = (*reader)->next(rows);
    if (!next) return next.error();
    more = *next;
  }
  if (Status s = (*writer)->close(); !s) return s.error();
  return report;
}

}  // namespace emcalign::apply
