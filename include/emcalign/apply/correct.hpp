#pragma once
// Correcting event files with an alignment (docs/contract.md §9, §11; docs/apply.md): the same rows and
// columns out as in, only the EMC directions (phi_emc_rad, theta_emc_rad) of the clusters
// changed, in the nominal frame → TS frame sense of the alignment.
//
// Methods:
//   clusters  docs/contract.md §9's cluster correction (apply/cluster_correction.hpp): from the
//             reconstructed (φ, θ, E) alone.
//   hits      each cluster rebuilt from its counters with the aligned counter centres, by
//             the reconstruction the simulation uses (needs files with hits).
//   auto      hits when the input has them, clusters otherwise.
// The output records what corrected it (the "correction" attribute: alignment, method,
// software, inputs) besides the first input's attributes; truth is copied when every input
// has it and the output is HDF5.

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::apply {

enum class CorrectionMethod { Auto, Hits, Clusters };
std::string_view name(CorrectionMethod m);
std::optional<CorrectionMethod> correctionMethodFromName(std::string_view name);

struct CorrectOptions {
  CorrectionMethod method = CorrectionMethod::Auto;
  /// R(E, θ) of the cluster method (its offset from a corrections file, or 0: the contract).
  geometry::ShowerDepth depth;
  /// When set, the cluster method's R(E, θ) at each event's beam energy instead (a
  /// corrections grid's offset; an error names the run).
  geometry::DepthAtEnergy depthAt;
  /// W0 of the logarithmic weights of the hits method: the reconstruction's (sim's default,
  /// SND-like).
  double logWeightW0 = 3.5;
  io::Compression compression = io::Compression::Lz4;  ///< of an HDF5 output
  /// Named (the output given), or InDirectory (a file the command writes inside an output
  /// directory: a FIFO or a device there is refused; io/output_file.hpp).
  io::Placement placement = io::Placement::Named;
  /// Recorded as the output's "correction" attribute (compact JSON, made by the caller).
  std::string description;
  /// Small blocks: the reader process prepares the next while this one is written.
  io::ReaderOptions reader{4096};
  /// Called after each block with the rows done so far.
  std::function<void(std::int64_t rows)> progress;
};

/// The options of a correction as a user gives them: the method by name (auto, hits,
/// clusters), the cluster method's R(E, θ) of `calo` with `depthOffset` added (native length),
/// or with the offset of `corrections` when given (a file's; a grid directory's at each
/// event's beam energy). The error names a bad method or corrections file.
Result<CorrectOptions> correctOptionsOf(std::string_view method, double depthOffset, const std::string& corrections,
                                        const geometry::Calorimeter& calo);

/// What the output's "correction" attribute records (CorrectOptions::description, compact):
/// {"software", "alignment", "method" (as given), "log_weight_w0", "depth_offset_cm" (null
/// with a grid, then "corrections_grid": its path), "inputs"}. `alignment` says which
/// alignment corrected it (a file and its parameters, or a conditions tag).
io::Json correctionRecord(const io::Json& alignment, std::string_view method, const CorrectOptions& options,
                          const std::vector<std::string>& inputs, const std::string& corrections);

struct CorrectReport {
  CorrectionMethod method = CorrectionMethod::Clusters;  ///< the one used
  std::int64_t events = 0;
  std::int64_t rows = 0;
  std::int64_t clusters = 0;  ///< rows whose EMC direction was corrected
  bool truth = false;         ///< truth copied
  bool hits = false;          ///< hits copied
  int alignments = 1;         ///< distinct alignments used (the IOVs of a conditions tag)
};

/// The alignment of each run: the IOVs of a conditions tag, or one alignment for every run.
/// The same object is returned for every run of one alignment.
using AlignmentOfRun = std::function<Result<std::shared_ptr<const geometry::AlignmentTransform>>(std::int64_t run)>;

/// Reads `inputs`, corrects every cluster, writes `output` (io/output_file.hpp rules: no
/// partial file on failure).
Result<CorrectReport> correctFiles(const std::vector<std::string>& inputs, const std::string& output,
                                   const geometry::Calorimeter& calo, const geometry::AlignmentTransform& transform,
                                   const CorrectOptions& options);
/// The same, each event corrected with the alignment of its run.
Result<CorrectReport> correctFiles(const std::vector<std::string>& inputs, const std::string& output,
                                   const geometry::Calorimeter& calo, const AlignmentOfRun& alignmentOf,
                                   const CorrectOptions& options);

/// Each input into `directory` under its own name (a period's run files stay one file per
/// run), each event with the alignment of its run; the reports summed (alignments: the most
/// any file used). Two inputs of the same name are refused before any work. `done` is called
/// after each file with its output path.
Result<CorrectReport> correctEachInto(const std::vector<std::string>& inputs, const std::string& directory,
                                      const geometry::Calorimeter& calo, const AlignmentOfRun& alignmentOf,
                                      const CorrectOptions& options,
                                      const std::function<void(const std::string&)>& done = {});

}  // namespace emcalign::apply
