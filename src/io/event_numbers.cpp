#include "emcalign/io/event_numbers.hpp"

#include <algorithm>
#include <iterator>
#include <limits>

namespace emcalign::io {

void EventNumbers::insert(std::int64_t event) {
  // The interval starting after `event`, and the one before it.
  auto next = intervals_.upper_bound(event);
  if (next != intervals_.begin()) {
    auto prev = std::prev(next);
    if (event <= prev->second) return;  // held already
    if (prev->second != std::numeric_limits<std::int64_t>::max() && event == prev->second + 1) {
      prev->second = event;
      if (next != intervals_.end() && next->first == event + 1) {  // the gap is closed
        prev->second = next->second;
        intervals_.erase(next);
      }
      return;
    }
  }
  if (next != intervals_.end() && event != std::numeric_limits<std::int64_t>::max() && next->first == event + 1) {
    const std::int64_t last = next->second;
    intervals_.erase(next);
    intervals_.emplace(event, last);
    return;
  }
  intervals_.emplace_hint(next, event, event);
}

std::optional<std::int64_t> EventNumbers::firstCommon(const EventNumbers& other) const {
  auto a = intervals_.begin();
  auto b = other.intervals_.begin();
  while (a != intervals_.end() && b != other.intervals_.end()) {
    const std::int64_t lo = std::max(a->first, b->first);
    const std::int64_t hi = std::min(a->second, b->second);
    if (lo <= hi) return lo;
    if (a->second < b->second) {
      ++a;
    } else {
      ++b;
    }
  }
  return std::nullopt;
}

}  // namespace emcalign::io
