#pragma once
// Shared by the libFuzzer targets: the readers take file names, so each input is written to
// a scratch file of this process first (in /dev/shm when there is one: no disk traffic).

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>

namespace emcalign::fuzz {

/// Writes the input to a file ending in `extension`; the same name on every call.
inline std::string scratchFile(const std::uint8_t* data, std::size_t size, const std::string& extension) {
  namespace fs = std::filesystem;
  static const std::string dir = fs::is_directory("/dev/shm") ? "/dev/shm" : fs::temp_directory_path().string();
  const std::string path = dir + "/emcalign-fuzz-" + std::to_string(::getpid()) + extension;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) __builtin_trap();
  if (size > 0 && std::fwrite(data, 1, size, f) != size) __builtin_trap();
  std::fclose(f);
  return path;
}

/// Reading succeeded or failed with a message: anything else (a crash, a hang, an empty
/// message) is a finding.
inline void expectMessage(bool ok, const std::string& message) {
  if (!ok && message.empty()) __builtin_trap();
}

}  // namespace emcalign::fuzz
