#pragma once
// Running another program (gnuplot, Slurm's sbatch and squeue): its standard input given,
// its standard output and error captured, a time limit.

#include <atomic>
#include <string>
#include <string_view>
#include <vector>

namespace emcalign::core {

struct Ran {
  bool timedOut = false;  ///< killed after the time allowed
  int status = -1;        ///< as waitpid gives it; -1: could not start
  int startError = 0;     ///< errno when it could not start
  std::string out, err;   ///< its standard output and error

  /// Started, ended by itself with exit status 0.
  [[nodiscard]] bool succeeded() const;
  /// "exit status N", "killed by signal N", "not started: <reason>", "stopped after the time allowed".
  [[nodiscard]] std::string outcome() const;
};

/// Runs `argv` (argv[0] looked up in PATH) in `cwd` with `input` on its standard input,
/// capturing its standard output and error (poll on the three pipes: no deadlock whatever
/// their sizes; 16 MiB of each kept, the rest read and dropped); it and its process group (what
/// a shell starts) killed after `seconds`.
/// With `stop`: killed (its process group too) as soon as it is set, as at the deadline.
Ran runCapturing(const std::vector<std::string>& argv, const std::string& cwd, std::string_view input, int seconds,
                 const std::atomic<bool>* stop = nullptr);

}  // namespace emcalign::core
