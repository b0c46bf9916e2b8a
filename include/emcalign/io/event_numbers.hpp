#pragma once
// The event numbers of one run met in one file, as intervals of consecutive numbers: a file
// numbered without gaps costs one interval per run, each gap one more. Commands that read
// files one by one (a campaign's scan, in parallel) compare these afterwards, so that an
// event in two files — a file given twice, a copy or a corrected copy beside the original —
// is refused as the single reader of `fit` refuses it ("appears again").

#include <cstdint>
#include <map>
#include <optional>

namespace emcalign::io {

class EventNumbers {
 public:
  /// Adds an event number (again: no change).
  void insert(std::int64_t event);
  /// The smallest event number both sets hold, or none.
  [[nodiscard]] std::optional<std::int64_t> firstCommon(const EventNumbers& other) const;
  [[nodiscard]] std::size_t intervals() const { return intervals_.size(); }
  [[nodiscard]] bool empty() const { return intervals_.empty(); }

 private:
  std::map<std::int64_t, std::int64_t> intervals_;  ///< first → last, disjoint, not adjacent
};

}  // namespace emcalign::io
