// libFuzzer target: the HDF5 event reader (docs/contract.md §6) on arbitrary bytes. libhdf5 itself
// crashes and loops on some of them (tests/fuzz/regressions/); the reader runs it in a child
// process, so what must hold here is that every input ends, in this process, with rows or
// with a message.

#include <vector>

#include "emcalign/io/event_file.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace emcalign;
  const std::string path = fuzz::scratchFile(data, size, ".h5");
  io::ReaderOptions options;
  options.blockRows = 300;
  options.hdf5TimeoutSeconds = 0.25;  // a healthy file opens in milliseconds; a looping libhdf5 costs this much
  auto reader = io::EventReader::open({path}, options);
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
    if (const auto* truth = (*reader)->truth(); truth != nullptr && truth->size() != rows.size()) __builtin_trap();
    for (const auto& [key, value] : (*reader)->attributes()) {
      if (key.empty()) __builtin_trap();
    }
  }
  return 0;
}
