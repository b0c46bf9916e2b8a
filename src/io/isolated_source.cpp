// A row source read in a child process (event_file_internal.hpp, openIsolated).
//
// Why: HDF5 1.10 (Debian 12's libhdf5) is not safe on corrupted files. Fuzzing the event
// reader found a division by zero in its chunk-layout decoding (SIGFPE), an endless loop
// in its global-heap decoding (a variable-length string attribute), and allocations of
// exabytes. None of them can be fixed here, so the HDF5 source runs in a forked child that
// streams the rows back through a pipe: a crash there is reported as an error naming the
// file, a child that stops answering is killed after the timeout, and the parent (the
// user's job) goes on to print the message and exit cleanly. On two cores the child also
// decompresses while the parent selects.
//
// Protocol, child → parent, each message `kind (1 byte) | payload size (8 bytes) | payload`:
//   'H' header: has-truth (1 byte), has-hits (1 byte), the number of attributes, then each as (key size, key,
//       value size, value), sizes in 8 bytes
//   'R' rows: their count (4 bytes), the rows, then (with truth) their truth rows, each in
//       the fixed layout of encodeRow and encodeTruth, then the number of hits (8 bytes) and
//       the hits of these rows in row order
//   'E' an error message (the source's own text); the child then exits
//   'Z' the end of the file
//   'D' (readIsolated) the whole answer of a reader that reads a file at once
// The child never returns into the caller's code: it leaves with _exit (no atexit handlers,
// no flush of the parent's stdio buffers it inherited).

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <functional>
#include <mutex>
#include <optional>
#include <string_view>

#include <fmt/format.h>

#include "event_file_internal.hpp"

namespace emcalign::io::detail {

namespace {

constexpr std::size_t kRowsPerMessage = 4096;
constexpr std::uint64_t kMaxMessage = std::uint64_t{1} << 30;

// ------------------------------------------------------------------------------ encoding

// Rows travel in a fixed layout, field by field (no padding, no struct copies):
// run i32, event i64, beam f64, veto i8, charged i8, the seven doubles of the row, its
// hit count i32; truth: pdg i32, then its nine doubles; a hit: counter i32, energy f64.
constexpr std::size_t kRowBytes = 4 + 8 + 8 + 1 + 1 + 7 * 8 + 4;
constexpr std::size_t kTruthBytes = 4 + 9 * 8;
constexpr std::size_t kHitBytes = 4 + 8;
constexpr std::size_t kHitsPerMessage = std::size_t{1} << 20;

template <typename T>
char* put(char* p, T v) {
  std::memcpy(p, &v, sizeof(T));
  return p + sizeof(T);
}
template <typename T>
const char* take(const char* p, T& v) {
  std::memcpy(&v, p, sizeof(T));
  return p + sizeof(T);
}

void encodeRow(char* p, const ParticleRow& r) {
  p = put(p, r.run);
  p = put(p, r.event);
  p = put(p, r.beamEnergy);
  p = put(p, r.muonVeto);
  p = put(p, r.charged);
  for (double x : {r.z0, r.rho, r.phiTs, r.thetaTs, r.energy, r.phiEmc, r.thetaEmc}) p = put(p, x);
  put(p, r.hitCount);
}

void decodeRow(const char* p, ParticleRow& r) {
  p = take(p, r.run);
  p = take(p, r.event);
  p = take(p, r.beamEnergy);
  p = take(p, r.muonVeto);
  p = take(p, r.charged);
  for (double* x : {&r.z0, &r.rho, &r.phiTs, &r.thetaTs, &r.energy, &r.phiEmc, &r.thetaEmc}) p = take(p, *x);
  take(p, r.hitCount);
}

void encodeTruth(char* p, const TruthRow& t) {
  p = put(p, t.pdg);
  for (double x : {t.energy, t.theta, t.phi}) p = put(p, x);
  for (int k = 0; k < 3; ++k) p = put(p, t.vertex[k]);
  for (int k = 0; k < 3; ++k) p = put(p, t.showerCentre[k]);
}

void decodeTruth(const char* p, TruthRow& t) {
  p = take(p, t.pdg);
  for (double* x : {&t.energy, &t.theta, &t.phi}) p = take(p, *x);
  for (int k = 0; k < 3; ++k) p = take(p, t.vertex[k]);
  for (int k = 0; k < 3; ++k) p = take(p, t.showerCentre[k]);
}

// The header: has-truth, has-hits, then the attributes as (size, text) pairs.
std::string encodeHeader(bool hasTruth, bool hasHits, const Attributes& attributes) {
  std::string out(1, hasTruth ? '\1' : '\0');
  out += hasHits ? '\1' : '\0';
  const auto text = [&](const std::string& s) {
    const std::uint64_t n = s.size();
    out.append(reinterpret_cast<const char*>(&n), 8);
    out += s;
  };
  const std::uint64_t n = attributes.size();
  out.append(reinterpret_cast<const char*>(&n), 8);
  for (const auto& [key, value] : attributes) {
    text(key);
    text(value);
  }
  return out;
}

bool decodeHeader(const std::string& in, bool& hasTruth, bool& hasHits, Attributes& attributes) {
  const char* p = in.data();
  const char* end = p + in.size();
  const auto u64 = [&](std::uint64_t& v) {
    if (end - p < 8) return false;
    p = take(p, v);
    return true;
  };
  if (end - p < 2) return false;
  hasTruth = *p++ != 0;
  hasHits = *p++ != 0;
  std::uint64_t n = 0;
  if (!u64(n)) return false;
  for (std::uint64_t k = 0; k < n; ++k) {
    std::string parts[2];
    for (auto& part : parts) {
      std::uint64_t size = 0;
      if (!u64(size) || size > static_cast<std::uint64_t>(end - p)) return false;
      part.assign(p, size);
      p += size;
    }
    attributes.emplace_back(std::move(parts[0]), std::move(parts[1]));
  }
  return p == end;
}

bool writeAll(int fd, const char* data, std::size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    data += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

bool send(int fd, char kind, std::string_view payload) {
  char head[9];
  head[0] = kind;
  const std::uint64_t size = payload.size();
  std::memcpy(head + 1, &size, 8);
  return writeAll(fd, head, sizeof(head)) && writeAll(fd, payload.data(), payload.size());
}

// ----------------------------------------------------------------------------- the child

[[noreturn]] void runChild(int fd, const std::function<Result<std::unique_ptr<RowSource>>()>& open) {
  auto source = open();
  if (!source) {
    send(fd, 'E', source.error().message);
    ::_exit(0);
  }
  RowSource& s = **source;
  const bool truth = s.hasTruth();
  if (!send(fd, 'H', encodeHeader(truth, s.hasHits(), s.attributes()))) ::_exit(0);
  const std::size_t perRow = kRowBytes + (truth ? kTruthBytes : 0);
  std::string message(4 + kRowsPerMessage * perRow, '\0');
  std::string hitBytes;
  std::vector<Hit> hits;
  std::uint32_t count = 0;
  const auto flush = [&] {
    if (count == 0) return true;
    std::memcpy(message.data(), &count, 4);
    // Rows first, then their truth, then the number of hits and the hits: the layout the
    // parent decodes.
    if (truth) {
      std::memmove(message.data() + 4 + count * kRowBytes, message.data() + 4 + kRowsPerMessage * kRowBytes,
                   count * kTruthBytes);
    }
    hitBytes.assign(8 + hits.size() * kHitBytes, '\0');
    char* p = put(hitBytes.data(), static_cast<std::uint64_t>(hits.size()));
    for (const Hit& h : hits) p = put(put(p, h.counter), h.energy);
    std::string whole(message.data(), 4 + count * perRow);
    whole += hitBytes;
    const bool ok = send(fd, 'R', whole);
    count = 0;
    hits.clear();
    return ok;
  };
  ParticleRow row;
  TruthRow t;
  while (true) {
    auto got = s.next(row, t, hits);
    if (!got) {
      if (flush()) send(fd, 'E', got.error().message);
      ::_exit(0);
    }
    if (!*got) break;
    encodeRow(message.data() + 4 + count * kRowBytes, row);
    if (truth) encodeTruth(message.data() + 4 + kRowsPerMessage * kRowBytes + count * kTruthBytes, t);
    if ((++count == kRowsPerMessage || hits.size() >= kHitsPerMessage) && !flush()) ::_exit(0);  // the parent went away
  }
  if (flush()) send(fd, 'Z', {});
  ::_exit(0);
}

// ---------------------------------------------------------------------------- the parent

class IsolatedSource final : public RowSource {
 public:
  IsolatedSource(std::string path, pid_t child, int fd, double timeoutSeconds)
      : path_(std::move(path)), child_(child), fd_(fd), timeout_(timeoutSeconds) {}
  ~IsolatedSource() override {
    if (fd_ >= 0) ::close(fd_);
    reap(true);
  }

  // Reads the header (or the child's first error).
  Status start() {
    std::string payload;
    char kind = 0;
    if (Status s = receive(kind, payload); !s) return s;
    if (kind == 'E') return Error{payload};
    if (kind != 'H' || !decodeHeader(payload, hasTruth_, hasHits_, attributes_)) return protocolError();
    return {};
  }

  Result<bool> next(ParticleRow& row, TruthRow& truth, std::vector<Hit>& hits) override {
    while (pos_ == count_) {
      if (ended_) return false;
      if (failed_) return *failed_;
      char kind = 0;
      if (Status s = receive(kind, payload_); !s) return fail(s.error());
      if (kind == 'Z') {
        ended_ = true;
        reap(false);
        return false;
      }
      if (kind == 'E') {
        reap(false);
        return fail(Error{payload_});
      }
      std::uint32_t n = 0;
      const std::size_t perRow = kRowBytes + (hasTruth_ ? kTruthBytes : 0);
      if (kind != 'R' || payload_.size() < 4) return fail(protocolError().error());
      std::memcpy(&n, payload_.data(), 4);
      std::uint64_t nHits = 0;
      if (n == 0 || payload_.size() < 4 + n * perRow + 8) return fail(protocolError().error());
      std::memcpy(&nHits, payload_.data() + 4 + n * perRow, 8);
      if (payload_.size() != 4 + n * perRow + 8 + nHits * kHitBytes) return fail(protocolError().error());
      count_ = n;
      pos_ = 0;
      hitsAt_ = payload_.data() + 4 + n * perRow + 8;
      hitsLeft_ = nHits;
    }
    decodeRow(payload_.data() + 4 + pos_ * kRowBytes, row);
    if (hasTruth_) decodeTruth(payload_.data() + 4 + count_ * kRowBytes + pos_ * kTruthBytes, truth);
    if (row.hitCount < 0 || static_cast<std::uint64_t>(row.hitCount) > hitsLeft_) {
      return fail(protocolError().error());
    }
    for (std::int32_t k = 0; k < row.hitCount; ++k) {
      Hit h;
      hitsAt_ = take(take(hitsAt_, h.counter), h.energy);
      hits.push_back(h);
    }
    hitsLeft_ -= static_cast<std::uint64_t>(row.hitCount);
    ++pos_;
    ++delivered_;
    return true;
  }

  // readIsolated's one answer: the bytes ('D') or the child's error ('E').
  Result<std::string> answer() {
    char kind = 0;
    std::string payload;
    if (Status s = receive(kind, payload); !s) return s.error();
    reap(false);
    if (kind == 'E') return Error{payload};
    if (kind != 'D') return protocolError().error();
    return payload;
  }

  [[nodiscard]] bool hasTruth() const override { return hasTruth_; }
  [[nodiscard]] bool hasHits() const override { return hasHits_; }
  [[nodiscard]] const Attributes& attributes() const override { return attributes_; }
  [[nodiscard]] std::string location() const override {
    return fmt::format("{}: record {}", path_, delivered_ > 0 ? delivered_ - 1 : 0);
  }

 private:
  Error fail(Error e) {
    failed_ = e;
    return e;
  }

  Status protocolError() const {
    return Error{fmt::format("{}: the HDF5 reader process sent a malformed message (a bug: please report it)", path_)};
  }

  // Waits for `size` bytes; the error says whether the child crashed or stopped answering.
  Status readExactly(char* out, std::size_t size) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_);
    while (size > 0) {
      const auto left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
      if (left <= 0.0) return stalled();
      pollfd p{fd_, POLLIN, 0};
      const int ready = ::poll(&p, 1, static_cast<int>(std::min(left * 1000.0, 1e9)) + 1);
      if (ready < 0 && errno == EINTR) continue;
      if (ready < 0) return Error{fmt::format("{}: cannot wait for the HDF5 reader: {}", path_, std::strerror(errno))};
      if (ready == 0) continue;
      const ssize_t n = ::read(fd_, out, size);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return died();
      out += n;
      size -= static_cast<std::size_t>(n);
    }
    return {};
  }

  Status receive(char& kind, std::string& payload) {
    char head[9];
    if (Status s = readExactly(head, sizeof(head)); !s) return s;
    kind = head[0];
    std::uint64_t size = 0;
    std::memcpy(&size, head + 1, 8);
    if (size > kMaxMessage) return protocolError();
    payload.resize(size);
    return readExactly(payload.data(), size);
  }

  Status stalled() {
    ::kill(child_, SIGKILL);
    reap(false);
    return Error{
        fmt::format("{}: the HDF5 library did not answer within {:g} s while reading this file: it is "
                    "corrupted (libhdf5 loops on some damaged files), or the storage stalled",
                    path_, timeout_)};
  }

  Status died() {
    const int status = reap(false);
    if (status >= 0 && WIFSIGNALED(status)) {
      const int sig = WTERMSIG(status);
      return Error{fmt::format("{}: the HDF5 library crashed reading this file (signal {}, {}): the file is corrupted",
                               path_, sig, ::strsignal(sig))};
    }
    return Error{
        fmt::format("{}: the HDF5 reader process ended without an answer (exit status {}): the file is "
                    "probably corrupted",
                    path_, status >= 0 && WIFEXITED(status) ? WEXITSTATUS(status) : -1)};
  }

  // Waits for the child (killing it first when asked); its wait status, or −1.
  int reap(bool kill) {
    if (child_ <= 0) return -1;
    if (kill) ::kill(child_, SIGKILL);
    int status = 0;
    pid_t r;
    do {
      r = ::waitpid(child_, &status, 0);
    } while (r < 0 && errno == EINTR);
    child_ = -1;
    return r > 0 ? status : -1;
  }

  std::string path_;
  pid_t child_;
  int fd_;
  double timeout_;
  bool hasTruth_ = false;
  Attributes attributes_;
  std::string payload_;  // the last rows message
  std::size_t count_ = 0, pos_ = 0;
  bool hasHits_ = false;
  const char* hitsAt_ = nullptr;  // the next hit of payload_
  std::uint64_t hitsLeft_ = 0;
  std::uint64_t delivered_ = 0;
  bool ended_ = false;
  std::optional<Error> failed_;
};

// The lock of every call into HDF5 (Hdf5Lock): recursive, since a writer's close calls
// into HDF5 from inside another guarded call.
std::recursive_mutex& hdf5Mutex() {
  static std::recursive_mutex m;
  return m;
}

bool gForkedReader = false;  // this process is a forked reader: one thread, no lock

}  // namespace

Hdf5Lock::Hdf5Lock() {
  if (gForkedReader) return;
  hdf5Mutex().lock();
  held_ = true;
}

Hdf5Lock::~Hdf5Lock() {
  if (held_) hdf5Mutex().unlock();
}

void leaveHdf5LockAfterFork() { gForkedReader = true; }

namespace {

// Forks the reader: the child runs `child(fd)` (which never returns) with the write end of
// the pipe; the parent gets the child's pid and the read end.
Result<std::pair<pid_t, int>> forkReader(const std::string& path, const std::function<void(int)>& child) {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) {
    return Error{fmt::format("{}: cannot start the HDF5 reader process: {}", path, std::strerror(errno))};
  }
  std::fflush(nullptr);  // nothing buffered is written twice
  std::optional<Hdf5Lock> noThreadInHdf5;
  noThreadInHdf5.emplace();
  const pid_t pid = ::fork();
  if (pid == 0) {
    leaveHdf5LockAfterFork();  // the mutex was copied held: the child, alone, never takes it
  } else {
    noThreadInHdf5.reset();  // (the child never returns from `child`: nothing to release there)
  }
  if (pid < 0) {
    const int error = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    return Error{fmt::format("{}: cannot start the HDF5 reader process: {}", path, std::strerror(error))};
  }
  if (pid == 0) {
    ::close(fds[0]);
    ::signal(SIGPIPE, SIG_DFL);  // the parent gave up: just end
    // A crash is reported by the parent from the wait status: no handler of the parent's
    // (the app's cleanup, a sanitizer's report) runs in the child.
    for (int s : {SIGINT, SIGTERM, SIGHUP, SIGFPE, SIGSEGV, SIGBUS, SIGILL, SIGABRT}) ::signal(s, SIG_DFL);
    child(fds[1]);
    ::_exit(0);
  }
  ::close(fds[1]);
  ::fcntl(fds[0], F_SETPIPE_SZ, 1 << 20);  // fewer switches between the processes; a smaller pipe works too
  return std::pair{pid, fds[0]};
}

}  // namespace

Result<std::unique_ptr<RowSource>> openIsolated(const std::string& path,
                                                const std::function<Result<std::unique_ptr<RowSource>>()>& open,
                                                double timeoutSeconds) {
  auto forked = forkReader(path, [&open](int fd) { runChild(fd, open); });
  if (!forked) return forked.error();
  auto source = std::make_unique<IsolatedSource>(path, forked->first, forked->second, timeoutSeconds);
  if (Status s = source->start(); !s) return s.error();
  return std::unique_ptr<RowSource>(std::move(source));
}

Result<std::string> readIsolated(const std::string& path, const std::function<Result<std::string>()>& read,
                                 double timeoutSeconds) {
  auto forked = forkReader(path, [&read](int fd) {
    auto bytes = read();
    if (bytes) {
      send(fd, 'D', *bytes);
    } else {
      send(fd, 'E', bytes.error().message);
    }
  });
  if (!forked) return forked.error();
  IsolatedSource channel(path, forked->first, forked->second, timeoutSeconds);
  return channel.answer();
}

}  // namespace emcalign::io::detail
