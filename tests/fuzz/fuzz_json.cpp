// libFuzzer target: the JSON readers — the parser (duplicate keys, depth, size), the
// alignment file (both forms, fit results), the detector description, the corrections and
// the period scenario.

#include "emcalign/calib/corrections.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/period.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace emcalign;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto j = io::parseJson(text, "fuzz.json");
  if (!j) {
    fuzz::expectMessage(false, j.error().message);
    return 0;
  }
  if (auto a = io::parseAlignmentFile(*j, 53.7, "fuzz.json"); !a) fuzz::expectMessage(false, a.error().message);
  if (auto d = io::parseDetectorDescription(*j, "fuzz.json")) {
    if (auto calo = geometry::Calorimeter::create(*d); !calo) fuzz::expectMessage(false, calo.error().message);
  } else {
    fuzz::expectMessage(false, d.error().message);
  }
  if (auto c = calib::parseCorrections(*j, "fuzz.json")) {
    // What reads must also write back and read again.
    auto again = calib::parseCorrections(calib::correctionsJson(*c), "again.json");
    if (!again) __builtin_trap();
  } else {
    fuzz::expectMessage(false, c.error().message);
  }
  if (auto p = validation::parsePeriodScenario(*j, 53.7, "fuzz.json")) {
    if (validation::planPeriod(*p).empty()) __builtin_trap();  // a scenario read has runs
  } else {
    fuzz::expectMessage(false, p.error().message);
  }
  return 0;
}
