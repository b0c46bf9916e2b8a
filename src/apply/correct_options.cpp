// The options and the record of a correction as a user gives them (apply/correct.hpp).

#include <fmt/format.h>

#include "emcalign/apply/correct.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"

namespace emcalign::apply {

Result<CorrectOptions> correctOptionsOf(std::string_view method, double depthOffset, const std::string& corrections,
                                        const geometry::Calorimeter& calo) {
  CorrectOptions options;
  const auto m = correctionMethodFromName(method);
  if (!m) return Error{fmt::format("method '{}': expected auto, hits or clusters", method)};
  options.method = *m;
  if (Status s = calib::checkDepthOffset(depthOffset, corrections); !s) return s.error();
  options.depth = geometry::ShowerDepth::of(calo.description());
  options.depth.offset = depthOffset;
  if (!corrections.empty()) {
    auto grid = calib::CorrectionsGrid::read(corrections);
    if (!grid) return grid.error();
    if (grid->isGrid()) {
      options.depthAt =
          calib::depthAtEnergy(std::make_shared<const calib::CorrectionsGrid>(std::move(*grid)), options.depth);
    } else {
      options.depth.offset = grid->points().front().corrections.depthOffset;
    }
  }
  return options;
}

io::Json correctionRecord(const io::Json& alignment, std::string_view method, const CorrectOptions& options,
                          const std::vector<std::string>& inputs, const std::string& corrections) {
  io::Json source = alignment;
  io::Json snapshot;  // a conditions tag's: the time read, at the top for --snapshot
  if (source.is_object() && source.contains("conditions_snapshot")) {
    snapshot = source["conditions_snapshot"];
    source.erase("conditions_snapshot");
  }
  io::Json record = {{"software", fmt::format("emcalign {}", kVersion)},
                     {"alignment", source},
                     {"method", method},
                     {"log_weight_w0", options.logWeightW0},
                     {"depth_offset_cm", options.depth.offset / units::cm},
                     {"inputs", inputs}};
  if (options.depthAt) {  // a grid: the offset of each event's beam energy
    record["depth_offset_cm"] = nullptr;
    record["corrections_grid"] = corrections;
  }
  if (!snapshot.is_null()) record["conditions_snapshot"] = snapshot;
  return record;
}

}  // namespace emcalign::apply
