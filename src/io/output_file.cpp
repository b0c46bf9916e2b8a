// Outputs written through temporaries (io/output_file.hpp): the registry of temporaries a
// signal removes, where an output goes (resolved and checked), and the file renamed into place.

#include "emcalign/io/output_file.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <filesystem>

#include <mutex>

#include <fmt/format.h>

#include "emcalign/core/secrets.hpp"
#include "input_protection.hpp"

namespace emcalign::io {

namespace {

namespace fs = std::filesystem;

// ------------------------------------------------------------- the registry of temporaries

// Fixed storage that a signal handler can read without locks or allocation: a slot is
// free (0), being filled (1) or holds a path (2).
constexpr std::size_t kSlots = 64;
constexpr std::size_t kMaxPath = 4096;
struct Slot {
  std::atomic<int> state{0};
  char path[kMaxPath];
};
std::array<Slot, kSlots> gSlots;
static_assert(std::atomic<int>::is_always_lock_free);

int registerTemporary(const std::string& path) {
  if (path.size() >= kMaxPath) return -1;  // still removed on failure and as a stale file
  for (std::size_t i = 0; i < kSlots; ++i) {
    int expected = 0;
    if (gSlots[i].state.compare_exchange_strong(expected, 1, std::memory_order_acquire)) {
      std::memcpy(gSlots[i].path, path.c_str(), path.size() + 1);
      gSlots[i].state.store(2, std::memory_order_release);
      return static_cast<int>(i);
    }
  }
  return -1;
}

void unregisterTemporary(int slot) {
  if (slot >= 0) gSlots[static_cast<std::size_t>(slot)].state.store(0, std::memory_order_release);
}

// ------------------------------------------------------------------------------- helpers

std::string reason(int error) { return std::strerror(error); }

std::string parentOf(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  return parent.empty() ? std::string(".") : parent.string();
}

// Removes `<realPath>.tmp-<pid>` files whose process no longer exists.
void removeStaleTemporaries(const std::string& realPath) {
  const std::string prefix = fs::path(realPath).filename().string() + ".tmp-";
  std::error_code ec;
  fs::directory_iterator it(parentOf(realPath), ec);
  if (ec) return;
  for (; it != fs::directory_iterator(); it.increment(ec)) {
    if (ec) return;
    const std::string name = it->path().filename().string();
    if (!name.starts_with(prefix) || name.size() == prefix.size()) continue;
    // NAME.tmp-PID, or NAME.tmp-PID.tmp-PID2 (a temporary written through its own temporary).
    long pid = 0;
    const char* first = name.data() + prefix.size();
    const char* last = name.data() + name.size();
    const auto [ptr, err] = std::from_chars(first, last, pid);
    const bool nested = std::string_view(ptr, static_cast<std::size_t>(last - ptr)).starts_with(".tmp-");
    if (err != std::errc() || (ptr != last && !nested) || pid <= 0 || pid == static_cast<long>(::getpid())) continue;
    if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;  // alive, or not ours to judge
    std::error_code kind;
    if (!fs::is_regular_file(it->symlink_status(kind))) continue;
    fs::remove(it->path(), kind);
  }
}

// Writes all of [data, data + size) to `fd`.
bool writeAll(int fd, const char* data, std::size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    data += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

std::atomic<unsigned> gStreamTemporaries{0};

Error overwritesInput(const std::string& output, const NamedPath& input) {
  return Error{
      fmt::format("{}: is the same file as the input {}: refusing to overwrite an input", output, describe(input))};
}

}  // namespace

void removeTemporaries() noexcept {
  for (auto& slot : gSlots) {
    if (slot.state.load(std::memory_order_acquire) == 2) ::unlink(slot.path);
  }
}

long temporaryWriter(std::string_view name) {
  auto pidOf = [](std::string_view s) -> long {
    long pid = 0;
    const auto [ptr, err] = std::from_chars(s.data(), s.data() + s.size(), pid);
    return !s.empty() && err == std::errc() && ptr == s.data() + s.size() && pid > 0 ? pid : 0;
  };
  if (const auto at = name.find(".tmp-"); at != std::string_view::npos && at > 0) {
    // NAME.tmp-PID, or NAME.tmp-PID.tmp-PID2 (a temporary written through its own temporary).
    std::string_view rest = name.substr(at + 5);
    if (const auto inner = rest.find(".tmp-"); inner != std::string_view::npos) rest = rest.substr(0, inner);
    if (long pid = pidOf(rest); pid > 0) return pid;
  }
  constexpr std::string_view kCorrected = ".corrected-", kH5 = ".h5";
  if (name.starts_with(kCorrected) && name.ends_with(kH5) && name.size() > kCorrected.size() + kH5.size()) {
    return pidOf(name.substr(kCorrected.size(), name.size() - kCorrected.size() - kH5.size()));
  }
  return 0;
}

bool isTemporaryName(std::string_view name) { return temporaryWriter(name) > 0; }

std::string temporaryPathFor(const std::string& realPath) {
  return fmt::format("{}.tmp-{}", realPath, static_cast<long>(::getpid()));
}

namespace {

// An output that does not exist yet: its directory must exist and take a new file, and no input
// may be there under its name (a new file among an input directory's data is one).
Result<OutputTarget> newOutput(const std::string& path) {
  const std::string dir = parentOf(path);
  struct stat d {};
  if (::stat(dir.c_str(), &d) != 0) {
    return Error{fmt::format("{}: cannot write here: the directory '{}' does not exist", path, dir)};
  }
  if (!S_ISDIR(d.st_mode)) return Error{fmt::format("{}: cannot write here: '{}' is not a directory", path, dir)};
  if (::access(dir.c_str(), W_OK) != 0) {
    return Error{fmt::format("{}: cannot create a file in '{}': {}", path, dir, reason(errno))};
  }
  if (auto input = protectedInputAt(path)) {
    return Error{fmt::format("{}: {} the input {}: refusing to write there", path,
                             fs::is_directory(input->path) ? "would be read as data of" : "is a file of",
                             describe(*input))};
  }
  return OutputTarget{path, path, OutputKind::File};
}

// An existing regular file replaced (`link`: lstat of the name, a link to it followed): not an
// input, writable, its temporary made beside the file itself.
Result<OutputTarget> replacedOutput(const std::string& path, const struct stat& link, const struct stat& st) {
  if (auto input = protectedInputAt(path)) return overwritesInput(path, *input);
  if ((st.st_mode & (S_IWUSR | S_IWGRP | S_IWOTH)) == 0) {
    return Error{
        fmt::format("{}: is read-only: refusing to replace it (chmod u+w {} to allow it, or remove it)", path, path)};
  }
  if (::access(path.c_str(), W_OK) != 0) {
    return Error{fmt::format("{}: cannot replace it: {}", path, reason(errno))};
  }
  std::string real = path;
  if (S_ISLNK(link.st_mode)) {
    std::error_code ec;
    real = fs::canonical(path, ec).string();
    if (ec) return Error{fmt::format("{}: cannot follow the symbolic link: {}", path, ec.message())};
  }
  const std::string dir = parentOf(real);
  if (::access(dir.c_str(), W_OK) != 0) {
    return Error{fmt::format("{}: cannot create the temporary file in '{}': {}", path, dir, reason(errno))};
  }
  return OutputTarget{path, real, OutputKind::File};
}

}  // namespace

Result<OutputTarget> resolveOutput(const std::string& path, Placement placement) {
  if (path.empty()) return Error{"an output name is empty"};
  if (path == "-") return OutputTarget{path, path, OutputKind::Stdout};
  // A password would be kept in the file system's names, and in every record naming the file.
  if (core::holdsPassword(path)) {
    return Error{fmt::format("{}: holds a password (a database address given where a file name goes?): not a file name",
                             core::withoutPasswords(path))};
  }
  if (const long writer = temporaryWriter(fs::path(path).filename().string());
      writer > 0 && writer != static_cast<long>(::getpid())) {
    return Error{
        fmt::format("{}: a name emcalign gives its temporaries (removed as stale by a later run): choose "
                    "another",
                    path)};
  }
  struct stat link {};
  if (::lstat(path.c_str(), &link) != 0) {
    const int error = errno;
    if (error != ENOENT) return Error{fmt::format("{}: cannot use as an output: {}", path, reason(error))};
    return newOutput(path);
  }
  if (S_ISLNK(link.st_mode) && placement == Placement::InDirectory) {
    // A file a command names inside its output directory is the command's: a link found there
    // (planted by whoever can write into the directory) is replaced, never written through.
    const std::string dir = parentOf(path);
    if (::access(dir.c_str(), W_OK) != 0) {
      return Error{fmt::format("{}: cannot create a file in '{}': {}", path, dir, reason(errno))};
    }
    return OutputTarget{path, path, OutputKind::File};
  }
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int error = errno;
    if (S_ISLNK(link.st_mode) && error == ENOENT) {
      std::error_code ec;
      const auto to = fs::read_symlink(path, ec);
      return Error{
          fmt::format("{}: is a symbolic link to '{}', which does not exist: refusing to write through it "
                      "(remove the link, or create its target)",
                      path, ec ? std::string("?") : to.string())};
    }
    return Error{fmt::format("{}: cannot use as an output: {}", path, reason(error))};
  }
  if (S_ISDIR(st.st_mode)) return Error{fmt::format("{}: is a directory (an output file name is expected)", path)};
  if ((S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode)) && placement == Placement::InDirectory) {
    return Error{
        fmt::format("{}: is {}: the files a command writes into its output directory are regular files "
                    "(remove it, or write elsewhere)",
                    path, S_ISFIFO(st.st_mode) ? "a FIFO" : "a device")};
  }
  if (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode)) return OutputTarget{path, path, OutputKind::Stream};
  if (S_ISBLK(st.st_mode)) return Error{fmt::format("{}: is a block device: refusing to write to it", path)};
  if (!S_ISREG(st.st_mode))
    return Error{fmt::format("{}: is not a regular file, a device or a pipe: refusing to write to it", path)};
  return replacedOutput(path, link, st);
}

namespace {
std::mutex gAbsentDirectoriesMutex;
std::vector<std::string> gAbsentDirectories;  // checked absent: made by this command, if at all
bool gKeepDirectories = false;
}  // namespace

void keepOutputDirectories() noexcept {
  const std::lock_guard lock(gAbsentDirectoriesMutex);
  gKeepDirectories = true;
}

void removeOutputDirectoriesLeftEmpty() noexcept {
  const std::lock_guard lock(gAbsentDirectoriesMutex);
  if (gKeepDirectories) return;
  for (auto it = gAbsentDirectories.rbegin(); it != gAbsentDirectories.rend(); ++it) ::rmdir(it->c_str());
}

Status checkOutputDirectory(const std::string& path) {
  if (path.empty()) return Error{"an output directory name is empty"};
  if (core::holdsPassword(path)) {
    return Error{fmt::format(
        "{}: holds a password (a database address given where a directory name goes?): not a directory name",
        core::withoutPasswords(path))};
  }
  struct stat link {};
  if (::lstat(path.c_str(), &link) != 0) {
    if (errno == ENOENT) {
      std::error_code ec;
      const std::lock_guard lock(gAbsentDirectoriesMutex);
      gAbsentDirectories.push_back(fs::absolute(path, ec).string());
      return {};
    }
    return Error{fmt::format("{}: cannot use as an output directory: {}", path, reason(errno))};
  }
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    return Error{fmt::format("{}: is a symbolic link to nothing: refusing to write through it", path)};
  }
  if (!S_ISDIR(st.st_mode))
    return Error{fmt::format("{}: exists and is not a directory (an output directory is expected)", path)};
  if (::access(path.c_str(), W_OK | X_OK) != 0) {
    return Error{fmt::format("{}: cannot write into this directory: {}", path, reason(errno))};
  }
  return {};
}

namespace {
// What a path names now: "-" is standard output (a redirection onto an input is that input).
bool statOf(const std::string& p, struct stat& st) {
  return p == "-" ? ::fstat(STDOUT_FILENO, &st) == 0 : ::stat(p.c_str(), &st) == 0;
}
// /dev/null takes any number of outputs: each is thrown away.
bool isNullDevice(const struct stat& st) {
  struct stat null {};
  return S_ISCHR(st.st_mode) && ::stat("/dev/null", &null) == 0 && st.st_rdev == null.st_rdev;
}
std::string shownOutput(const NamedPath& o) {
  return o.path == "-" ? fmt::format("{} - (standard output)", o.option) : fmt::format("{} {}", o.option, o.path);
}
}  // namespace

Status checkDistinct(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs) {
  struct Seen {
    const NamedPath* path;
    dev_t dev;
    ino_t ino;
  };
  std::vector<Seen> in;
  for (const auto& i : inputs) {
    struct stat st {};
    if (!i.path.empty() && i.path != "-" && ::stat(i.path.c_str(), &st) == 0 && S_ISREG(st.st_mode)) {
      in.push_back({&i, st.st_dev, st.st_ino});
    }
  }
  // Outputs that do not exist yet are compared by their normalised absolute name.
  std::vector<std::pair<const NamedPath*, std::string>> absent;
  for (const auto& o : outputs) {
    struct stat st {};
    if (o.path.empty() || o.path == "-" || ::lstat(o.path.c_str(), &st) == 0) continue;
    std::error_code ec;
    const std::string name = fs::weakly_canonical(fs::absolute(o.path, ec), ec).string();
    for (const auto& [other, otherName] : absent) {
      if (otherName == name) {
        return Error{fmt::format("{}: is the same file as the output {}: give each output its own file", shownOutput(o),
                                 shownOutput(*other))};
      }
    }
    absent.emplace_back(&o, name);
  }
  // Outputs that exist (standard output among them): never an input, never another output's
  // file, pipe or stream (two outputs would run into one), but for /dev/null.
  std::vector<Seen> out;
  for (const auto& o : outputs) {
    struct stat st {};
    if (o.path.empty() || !statOf(o.path, st)) continue;
    for (const auto& s : in) {
      if (S_ISREG(st.st_mode) && s.dev == st.st_dev && s.ino == st.st_ino) {
        return Error{fmt::format("{}: is the same file as the input {}{}: refusing to overwrite an input",
                                 shownOutput(o), s.path->option.empty() ? "" : s.path->option + " ", s.path->path)};
      }
    }
    for (const auto& s : out) {
      if (s.dev == st.st_dev && s.ino == st.st_ino && !isNullDevice(st)) {
        return Error{fmt::format("{}: is the same {} as the output {}: give each output its own file", shownOutput(o),
                                 S_ISREG(st.st_mode) ? "file" : "stream", shownOutput(*s.path))};
      }
    }
    out.push_back({&o, st.st_dev, st.st_ino});
  }
  return {};
}

// ------------------------------------------------------------------------------ OutputFile

Result<std::unique_ptr<OutputFile>> OutputFile::reserve(const std::string& path, Placement placement) {
  auto target = resolveOutput(path, placement);
  if (!target) return target.error();
  auto out = std::unique_ptr<OutputFile>(new OutputFile());
  out->target_ = *target;
  if (target->kind == OutputKind::File) {
    removeStaleTemporaries(target->realPath);
    out->written_ = temporaryPathFor(target->realPath);
    struct stat existing {};
    if (::lstat(out->written_.c_str(), &existing) == 0) {
      return Error{
          fmt::format("{}: the temporary file '{}' exists: is this file being written by this process already?", path,
                      out->written_)};
    }
    // The permission bits of the regular file replaced (not those of a device or of what a link
    // planted in an output directory points to).
    struct stat st {};
    if (::lstat(target->realPath.c_str(), &st) == 0 && S_ISREG(st.st_mode)) {
      out->mode_ = static_cast<int>(st.st_mode & 07777);
    }
  } else {
    std::error_code ec;
    const fs::path dir = fs::temp_directory_path(ec);
    if (ec) return Error{fmt::format("{}: no temporary directory to build the file in: {}", path, ec.message())};
    out->written_ =
        (dir / fmt::format("emcalign-{}-{}.tmp", static_cast<long>(::getpid()), gStreamTemporaries.fetch_add(1)))
            .string();
    out->copyOnCommit_ = true;
  }
  out->temporary_ = true;
  out->slot_ = registerTemporary(out->written_);
  return out;
}

Result<std::unique_ptr<OutputFile>> OutputFile::open(const std::string& path, Placement placement) {
  auto target = resolveOutput(path, placement);
  if (!target) return target.error();
  if (target->kind == OutputKind::Stdout) {
    auto out = std::unique_ptr<OutputFile>(new OutputFile());
    out->target_ = *target;
    out->written_ = target->path;  // "-"
    out->stream_ = stdout;
    return out;
  }
  if (target->kind == OutputKind::Stream) {
    auto out = std::unique_ptr<OutputFile>(new OutputFile());
    out->target_ = *target;
    out->written_ = path;
    out->stream_ = std::fopen(path.c_str(), "wb");
    if (out->stream_ == nullptr) return Error{fmt::format("{}: cannot open for writing: {}", path, reason(errno))};
    return out;
  }
  auto out = reserve(path, placement);
  if (!out) return out.error();
  const int fd = ::open((*out)->written_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0666);
  if (fd < 0) {
    const int error = errno;
    (*out)->temporary_ = false;  // not ours to remove (it may be another writer's)
    unregisterTemporary(std::exchange((*out)->slot_, -1));
    return Error{fmt::format("{}: cannot create the temporary file '{}': {}", path, (*out)->written_, reason(error))};
  }
  (*out)->stream_ = ::fdopen(fd, "wb");
  if ((*out)->stream_ == nullptr) {
    const int error = errno;
    ::close(fd);
    return Error{fmt::format("{}: cannot open the temporary file: {}", path, reason(error))};
  }
  return out;
}

Status OutputFile::closeStream() {
  if (stream_ == nullptr) return {};
  std::FILE* s = std::exchange(stream_, nullptr);
  if (s == stdout) {
    if (std::fflush(s) != 0 || std::ferror(s))
      return Error{fmt::format("standard output: write failed: {}", reason(errno))};
    return {};
  }
  const bool flushed = std::fflush(s) == 0 && !std::ferror(s);
  const int flushError = errno;
  const bool closed = std::fclose(s) == 0;
  const int closeError = errno;
  if (!flushed || !closed) {
    return Error{fmt::format("{}: write failed: {}", target_.path, reason(!flushed ? flushError : closeError))};
  }
  return {};
}

Status OutputFile::commit() {
  if (committed_) return Error{fmt::format("{}: already written", target_.path)};
  if (Status s = closeStream(); !s) return s;
  committed_ = true;
  if (!temporary_) return {};
  const auto removeTemporary = [&] {
    ::unlink(written_.c_str());
    unregisterTemporary(slot_);
    temporary_ = false;
  };
  if (copyOnCommit_) {
    const int in = ::open(written_.c_str(), O_RDONLY | O_CLOEXEC);
    if (in < 0) {
      const int error = errno;
      removeTemporary();
      return Error{fmt::format("{}: cannot read back the temporary file: {}", target_.path, reason(error))};
    }
    const bool toStdout = target_.kind == OutputKind::Stdout;
    const int out = toStdout ? STDOUT_FILENO : ::open(target_.path.c_str(), O_WRONLY | O_CLOEXEC);
    int error = out < 0 ? errno : 0;
    if (out >= 0) {
      if (toStdout) std::fflush(stdout);
      std::vector<char> buffer(std::size_t{1} << 20);
      while (true) {
        const ssize_t n = ::read(in, buffer.data(), buffer.size());
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) {
          error = errno;
          break;
        }
        if (n == 0) break;
        if (!writeAll(out, buffer.data(), static_cast<std::size_t>(n))) {
          error = errno;
          break;
        }
      }
      if (!toStdout && ::close(out) != 0 && error == 0) error = errno;
    }
    ::close(in);
    removeTemporary();
    if (error != 0) return Error{fmt::format("{}: write failed: {}", target_.path, reason(error))};
    return {};
  }
  if (mode_ >= 0) ::chmod(written_.c_str(), static_cast<mode_t>(mode_));
  if (::rename(written_.c_str(), target_.realPath.c_str()) != 0) {
    const int error = errno;
    removeTemporary();
    return Error{fmt::format("{}: cannot rename the temporary file into place: {}", target_.path, reason(error))};
  }
  unregisterTemporary(slot_);
  temporary_ = false;
  return {};
}

OutputFile::~OutputFile() {
  if (stream_ != nullptr && stream_ != stdout) std::fclose(stream_);
  if (stream_ == stdout) std::fflush(stdout);
  if (temporary_) {
    ::unlink(written_.c_str());
    unregisterTemporary(slot_);
  }
}

Status writeFileIn(const std::string& dir, const std::string& name, std::string_view content) {
  return writeOutputFile((fs::path(dir) / name).string(), content, Placement::InDirectory);
}

Status writeOutputFile(const std::string& path, std::string_view given, Placement placement) {
  auto out = OutputFile::open(path, placement);
  if (!out) return out.error();
  // The command line's passwords are never written (a record naming what it was given).
  const std::string redacted = core::passwordsRemembered() ? core::withoutPasswords(std::string(given)) : "";
  const std::string_view content = core::passwordsRemembered() ? std::string_view(redacted) : given;
  if (!content.empty() && std::fwrite(content.data(), 1, content.size(), (*out)->stream()) != content.size()) {
    return Error{
        fmt::format("{}: write failed: {}", path == "-" ? std::string("standard output") : path, reason(errno))};
  }
  return (*out)->commit();
}

}  // namespace emcalign::io
