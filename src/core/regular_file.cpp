#include "emcalign/core/regular_file.hpp"

#include <fcntl.h>
#include <linux/magic.h>
#include <sys/stat.h>
#include <sys/vfs.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <utility>

#include <fmt/format.h>

namespace emcalign {

namespace {

std::string kindOf(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO (named pipe; a <(...) is one: write the data to a file first)";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

}  // namespace

Result<RegularFile> RegularFile::open(const std::string& path) {
  // O_NONBLOCK: opening a FIFO without a writer returns at once instead of waiting for one.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    const int error = errno;
    if (error == ENOENT) return Error{fmt::format("{}: no such file", path)};
    return Error{fmt::format("{}: cannot open: {}", path, std::strerror(error))};
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int error = errno;
    ::close(fd);
    return Error{fmt::format("{}: cannot open: {}", path, std::strerror(error))};
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    return Error{fmt::format("{}: is {}, not a regular file: refusing to read it (it could block or never end)", path,
                             kindOf(st.st_mode))};
  }
  // The kernel's files look regular, but may block (/proc/kmsg) or never end.
  struct statfs fs {};
  if (::fstatfs(fd, &fs) == 0 && (fs.f_type == PROC_SUPER_MAGIC || fs.f_type == SYSFS_MAGIC)) {
    ::close(fd);
    return Error{fmt::format("{}: a file of the kernel's /proc or /sys, not data: refusing to read it", path)};
  }
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  return RegularFile(fd, path);
}

RegularFile::RegularFile(RegularFile&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)), path_(std::move(other.path_)) {}

RegularFile& RegularFile::operator=(RegularFile&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    path_ = std::move(other.path_);
  }
  return *this;
}

RegularFile::~RegularFile() {
  if (fd_ >= 0) ::close(fd_);
}

Status RegularFile::seekToLast(std::size_t bytes) {
  struct stat st {};
  if (::fstat(fd_, &st) != 0) return Error{fmt::format("{}: {}", path_, std::strerror(errno))};
  const auto size = static_cast<std::size_t>(st.st_size);
  if (::lseek(fd_, static_cast<off_t>(size > bytes ? size - bytes : 0), SEEK_SET) < 0) {
    return Error{fmt::format("{}: cannot seek: {}", path_, std::strerror(errno))};
  }
  return {};
}

Result<std::size_t> RegularFile::read(char* data, std::size_t size) {
  std::size_t got = 0;
  while (got < size) {
    const ssize_t n = ::read(fd_, data + got, size - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return Error{fmt::format("{}: read error: {}", path_, std::strerror(errno))};
    if (n == 0) break;
    got += static_cast<std::size_t>(n);
  }
  return got;
}

Result<std::string> RegularFile::readAll(std::size_t maxBytes) {
  std::string out;
  char buffer[1 << 16];
  while (true) {
    auto n = read(buffer, sizeof buffer);
    if (!n) return n.error();
    if (*n == 0) break;
    if (out.size() + *n > maxBytes) {
      return Error{fmt::format("{}: larger than {} MiB: not a file emcalign reads whole (a wrong file?)", path_,
                               maxBytes >> 20)};
    }
    out.append(buffer, *n);
  }
  return out;
}

}  // namespace emcalign
