// libFuzzer target: the profile CSV reader of `fit --profile-in`, and the fit of whatever
// it accepts (a profile that reads must fit or be refused with a message, never crash).

#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/profiles.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace emcalign;
  const std::string path = fuzz::scratchFile(data, size, ".csv");
  auto bins = calib::readProfileCsv(path);
  if (!bins) {
    fuzz::expectMessage(false, bins.error().message);
    return 0;
  }
  calib::markUsedBins(*bins, calib::ProfileOptions{}.minEntries);
  static const auto geometry = calib::FitGeometry::of(geometry::DetectorDescription::sndDefault());
  calib::FitOptions options;
  options.maxIterations = 20;  // enough to exercise every path, fast enough to fuzz
  auto fit = calib::fitProfiles(*bins, geometry, options);
  if (!fit) fuzz::expectMessage(false, fit.error().message);
  return 0;
}
