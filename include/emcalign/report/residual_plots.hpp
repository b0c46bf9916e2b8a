#pragma once
// Figures of residual summaries (apply/residual_summary.hpp): how well EMC directions agree
// with the tracks, for several samples side by side — the same events before and after a
// correction, with the truth or with fitted parameters, a nominal detector for reference.
//
//  - residuals.png: the Δφ and Δθ distributions of every sample, normalised to unit area,
//    over ±8° (the paper's Fig. 8: a correction moves the Δφ peak from ~3° to 0 and narrows
//    it). Mean and rms in the key.
//  - residual_columns.png: the mean sin Δφ (·180/π) in each of the 16 φ columns against φ:
//    the irregularity a misalignment leaves, and what remains after the correction.
// Data: residuals.dat (per sample a gnuplot index block with the two histograms) and
// residual_columns.dat; scripts residuals.gp, residual_columns.gp.

#include <string>
#include <vector>

#include "emcalign/apply/residual_summary.hpp"
#include "emcalign/core/result.hpp"

namespace emcalign::report {

struct LabelledSummary {
  std::string label;
  apply::ResidualSummary summary;
};

/// Writes the two figures (with data and scripts) into `dir` (created if missing); the PNG
/// paths. Fails on no sample, on a file that cannot be written, or when gnuplot fails.
Result<std::vector<std::string>> writeResidualPlots(const std::string& dir,
                                                    const std::vector<LabelledSummary>& samples);

}  // namespace emcalign::report
