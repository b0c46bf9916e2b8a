// libFuzzer target: the CSV readers on arbitrary bytes: the event reader (docs/contract.md §6)
// and the points reader of `emcalign transform` (io/points_csv.hpp).

#include <sstream>
#include <vector>

#include "emcalign/io/event_file.hpp"
#include "emcalign/io/points_csv.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace emcalign;
  std::istringstream text(std::string(reinterpret_cast<const char*>(data), size));
  if (auto points = io::readPointsCsv(text, "fuzz"); !points) {
    fuzz::expectMessage(false, points.error().message);
  } else if (points->size() > io::kMaxPoints) {
    __builtin_trap();
  }
  const std::string path = fuzz::scratchFile(data, size, ".csv");
  auto reader = io::EventReader::open({path}, io::ReaderOptions{7});  // small blocks: more boundaries
  if (!reader) {
    fuzz::expectMessage(false, reader.error().message);
    return 0;
  }
  std::vector<ParticleRow> rows;
  while (true) {
    auto more = (*reader)->next(rows);
    if (!more) {
      fuzz::expectMessage(false, more.error().message);
      break;
    }
    if (!*more) break;
    if (rows.empty()) __builtin_trap();  // a block holds at least one row
  }
  return 0;
}
