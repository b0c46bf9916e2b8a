#pragma once
// residuals.json and residuals.md of `emcalign residuals` (docs/outputs.md): the one writer
// and the one reader of the file, beside the summary they record (residual_summary.hpp).

#include <string>
#include <string_view>
#include <vector>

#include "emcalign/apply/residual_summary.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::apply {

/// One named sample of event files and its summary. Read back, the summary holds what the file
/// records: not the column entries nor the distributions (summarizeResiduals' full result).
struct ResidualSample {
  std::string name;
  std::vector<std::string> files;
  ResidualSummary summary;
};

/// What residuals.json records: the samples and the shower depth's offset (cm).
struct ResidualRecord {
  std::vector<ResidualSample> samples;
  double depthOffsetCm = 0.0;
  std::string software = {};  ///< empty: written by this emcalign
};

/// residuals.json: {"software", "depth_offset_cm", "samples": [{"name", "files", "events",
/// "particles", "mean_sin_dphi_deg", "mean_sin_dphi_error_deg", "mean_dtheta_deg",
/// "mean_dtheta_error_deg", "rms_dphi_deg", "rms_dtheta_deg", "phi_column_mean_sin_dphi_deg"
/// (16, null for an empty column), "phi_irregularity_deg"}]}.
io::Json residualsJson(const ResidualRecord& record);
/// residuals.md's table: one row per sample.
std::string residualsTable(const std::vector<ResidualSample>& samples);
/// residuals.md: a title, the table and how to read it.
std::string residualsMarkdown(const std::vector<ResidualSample>& samples);
/// Reads residuals.json (`source` names it in messages): a key missing, unknown or of the wrong
/// type refused, naming the key.
Result<ResidualRecord> parseResiduals(const io::Json& j, std::string_view source);

}  // namespace emcalign::apply
