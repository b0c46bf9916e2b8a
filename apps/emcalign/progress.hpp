#pragma once
// A one-line progress report on stderr, only when stderr is a terminal (a total of 0: unknown).

#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <string>

#include "console.hpp"

namespace emcalign::app {

class ProgressLine {
 public:
  ProgressLine(std::string what, std::int64_t total, std::string unit)
      : what_(std::move(what)),
        unit_(std::move(unit)),
        total_(total),
        enabled_(::isatty(2) != 0),
        start_(std::chrono::steady_clock::now()) {}

  void update(std::int64_t done) {
    if (!enabled_) return;
    const double seconds = elapsed();
    const double rate = seconds > 0.0 ? static_cast<double>(done) / seconds : 0.0;
    if (total_ <= 0) {  // an unknown total: what is done, and how fast
      eprint("\r{}: {} {}, {:.0f} {}/s   ", what_, done, unit_, rate, unit_);
      return;
    }
    const double left = rate > 0.0 ? static_cast<double>(total_ - done) / rate : 0.0;
    eprint("\r{}: {}/{} {} ({:.0f}%), {:.0f} {}/s, {:.0f} s left   ", what_, done, total_, unit_,
           total_ > 0 ? 100.0 * static_cast<double>(done) / static_cast<double>(total_) : 100.0, rate, unit_, left);
  }
  /// The total, when it is known only once the work has started.
  void setTotal(std::int64_t total) { total_ = total; }
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;
  /// A line left open (the command refused midway) is ended before the error is printed.
  ~ProgressLine() { finish(); }

  void finish() {
    if (enabled_ && !finished_) eprint("\n");
    finished_ = true;
  }
  [[nodiscard]] double elapsed() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::string what_, unit_;
  std::int64_t total_;
  bool enabled_;
  bool finished_ = false;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace emcalign::app
