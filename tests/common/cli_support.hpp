#pragma once
// Running the emcalign binary under test from the command-line tests: exit code, stdout
// and stderr, and a fresh scratch directory per test (and per process, since ctest runs
// tests in parallel processes).

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

namespace emcalign::testing {

struct CommandResult {
  int exitCode = -1;
  std::string out;
  std::string err;
};

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Runs `emcalign ARGS` (ARGS split by the shell) with `stdinText` on stdin; the scratch
/// files (stdin, stdout, stderr) live in `scratch`.
inline CommandResult runEmcalign(const std::filesystem::path& scratch, const std::string& args,
                                 const std::string& stdinText = "") {
  const auto in = scratch / "stdin.txt", out = scratch / "stdout.txt", err = scratch / "stderr.txt";
  std::ofstream(in) << stdinText;
  const std::string cmd =
      std::string(EMCALIGN_BINARY) + " " + args + " <" + in.string() + " >" + out.string() + " 2>" + err.string();
  const int status = std::system(cmd.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(out), slurp(err)};
}

/// An empty directory named after the running test and this process.
inline std::filesystem::path freshTestDirectory(const std::string& prefix) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  // A parameterised test is named "Name/param": one directory, not a parent left behind.
  std::string test = info != nullptr ? info->name() : "suite";
  std::replace(test.begin(), test.end(), '/', '_');
  const auto dir = std::filesystem::temp_directory_path() / (prefix + "_" + std::to_string(::getpid()) + "_" + test);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace emcalign::testing
