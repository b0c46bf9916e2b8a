#pragma once
// Opening an input file without hanging on it. A FIFO given where a file is expected blocks
// its reader until a writer comes (forever, in a batch job); /dev/zero or /dev/urandom never
// end. Every reader of this library opens its inputs here: the file is opened without
// blocking, refused unless it is a regular file, and read with a limit enforced while reading
// (a file that grows while it is read cannot get past it).

#include <cstddef>
#include <string>
#include <utility>

#include "emcalign/core/result.hpp"

namespace emcalign {

/// An open regular file (closed when destroyed).
class RegularFile {
 public:
  /// Opens `path` for reading; the error names the path and why (a FIFO, a device, a
  /// directory, the system's reason).
  static Result<RegularFile> open(const std::string& path);
  RegularFile(RegularFile&& other) noexcept;
  RegularFile& operator=(RegularFile&& other) noexcept;
  RegularFile(const RegularFile&) = delete;
  RegularFile& operator=(const RegularFile&) = delete;
  ~RegularFile();

  /// Reads up to `size` bytes (fewer only at the end of the file); the error names the path.
  Result<std::size_t> read(char* data, std::size_t size);
  /// The rest of the file, refused when it holds more than `maxBytes`.
  Result<std::string> readAll(std::size_t maxBytes);
  /// Moves to the file's last `bytes` bytes (its start when it is shorter): a log's tail is read
  /// without reading what comes before, however large.
  Status seekToLast(std::size_t bytes);

 private:
  RegularFile(int fd, std::string path) : fd_(fd), path_(std::move(path)) {}
  int fd_ = -1;
  std::string path_;
};

}  // namespace emcalign
