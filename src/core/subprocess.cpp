#include "emcalign/core/subprocess.hpp"

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <thread>

#include <fmt/format.h>

extern char** environ;

namespace emcalign::core {

bool Ran::succeeded() const { return !timedOut && status != -1 && WIFEXITED(status) && WEXITSTATUS(status) == 0; }

std::string Ran::outcome() const {
  if (timedOut) return "stopped after the time allowed";
  if (status == -1) return fmt::format("not started: {}", std::strerror(startError));
  if (WIFEXITED(status)) return fmt::format("exit status {}", WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return fmt::format("killed by signal {}", WTERMSIG(status));
  return "ended abnormally";
}

namespace {

constexpr std::size_t kMaxCaptured = std::size_t{16} << 20;

// Starts `argv` in `cwd` with its standard streams on `in`, `out` and `err`: 0 and its pid, or
// the error number.
int spawn(const std::vector<std::string>& argv, const std::string& cwd, int in, int out, int err, pid_t& pid) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, in, 0);
  posix_spawn_file_actions_adddup2(&actions, out, 1);
  posix_spawn_file_actions_adddup2(&actions, err, 2);
  posix_spawn_file_actions_addchdir_np(&actions, cwd.c_str());
  // Its own process group: at the deadline the whole group is killed (a shell's children too).
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attributes, 0);
  std::vector<char*> args;
  args.reserve(argv.size() + 1);
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const int spawned = ::posix_spawnp(&pid, args[0], &actions, &attributes, args.data(), environ);
  posix_spawnattr_destroy(&attributes);
  posix_spawn_file_actions_destroy(&actions);
  return spawned;
}

// Feeds `input` to the child's standard input (`in`) and collects its output and errors (`out`,
// `err`) until both close, or kills it at the deadline; closes the three.
void exchange(pid_t pid, int in, int out, int err, std::string_view input, int seconds, Ran& r,
              const std::atomic<bool>* stop) {
  std::size_t written = 0;
  if (input.empty()) {
    ::close(in);
    in = -1;
  }
  char buffer[1 << 16];
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(seconds);
  while (out >= 0 || err >= 0) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0 || (stop != nullptr && stop->load())) {
      ::kill(-pid, SIGKILL);  // its process group
      ::kill(pid, SIGKILL);
      r.timedOut = true;
      break;
    }
    pollfd fds[3] = {{in, POLLOUT, 0}, {out, POLLIN, 0}, {err, POLLIN, 0}};
    if (::poll(fds, 3, static_cast<int>(std::min<long long>(left.count(), 200))) < 0) {
      if (errno == EINTR) continue;
      break;
    }
    if (in >= 0 && (fds[0].revents & (POLLOUT | POLLERR | POLLHUP)) != 0) {
      const ssize_t n = ::send(in, input.data() + written, input.size() - written, MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n > 0) written += static_cast<std::size_t>(n);
      if (n < 0 && errno != EAGAIN && errno != EINTR) written = input.size();  // it stopped reading
      if (written == input.size()) {
        ::close(in);
        in = -1;
      }
    }
    for (int k : {1, 2}) {
      int& fd = k == 1 ? out : err;
      if (fd < 0 || (fds[k].revents & (POLLIN | POLLERR | POLLHUP)) == 0) continue;
      const ssize_t n = ::read(fd, buffer, sizeof buffer);
      if (n > 0) {
        // Kept up to a bound (a command that prints without end must not take the memory); the
        // rest is read and dropped.
        std::string& to = k == 1 ? r.out : r.err;
        if (to.size() < kMaxCaptured)
          to.append(buffer, std::min(static_cast<std::size_t>(n), kMaxCaptured - to.size()));
      } else if (n == 0 || (errno != EINTR && errno != EAGAIN)) {
        ::close(fd);
        fd = -1;
      }
    }
  }
  for (int fd : {in, out, err}) {
    if (fd >= 0) ::close(fd);
  }
}

}  // namespace

Ran runCapturing(const std::vector<std::string>& argv, const std::string& cwd, std::string_view input, int seconds,
                 const std::atomic<bool>* stop) {
  Ran r;
  // Its standard input is a socket, not a pipe: a gnuplot that exits before reading all of it
  // gets EPIPE without a SIGPIPE (MSG_NOSIGNAL), which would end this process.
  int in[2], out[2], err[2];
  if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, in) != 0) {
    r.startError = errno;
    return r;
  }
  if (::pipe2(out, O_CLOEXEC) != 0) {
    r.startError = errno;
    for (int fd : in) ::close(fd);
    return r;
  }
  if (::pipe2(err, O_CLOEXEC) != 0) {
    r.startError = errno;
    for (int fd : {in[0], in[1], out[0], out[1]}) ::close(fd);
    return r;
  }
  pid_t pid = 0;
  const int spawned = spawn(argv, cwd, in[0], out[1], err[1], pid);
  ::close(in[0]);
  ::close(out[1]);
  ::close(err[1]);
  if (spawned != 0) {
    r.startError = spawned;
    ::close(in[1]);
    ::close(out[0]);
    ::close(err[0]);
    return r;
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(seconds);
  exchange(pid, in[1], out[0], err[0], input, seconds, r, stop);
  // A child that closed its output (or sent it elsewhere) is waited for up to the same deadline.
  for (;;) {
    const pid_t done = ::waitpid(pid, &r.status, r.timedOut ? 0 : WNOHANG);
    if (done == pid || (done < 0 && errno != EINTR)) break;
    if (done == 0 && (std::chrono::steady_clock::now() >= deadline || (stop != nullptr && stop->load()))) {
      ::kill(-pid, SIGKILL);
      ::kill(pid, SIGKILL);
      r.timedOut = true;
      continue;
    }
    if (done == 0) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  if (r.timedOut) ::kill(-pid, SIGKILL);  // what the group left behind
  return r;
}

}  // namespace emcalign::core
