// emcalign: geometric calibration of a two-hemisphere EM calorimeter relative to a tracker.
// This file only wires the subcommands (each adds itself from cmd_<name>.cpp; task, finish and
// batch from planned.cpp, which also wires the --plan of the four commands that fan out), the
// signals and the exit codes of docs/conventions.md.

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <exception>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include "arguments.hpp"
#include "common.hpp"
#include "console.hpp"
#include "emcalign/core/secrets.hpp"
#include "emcalign/core/utf8.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/output_file.hpp"
#include "planned.hpp"

namespace {

// Interrupted (Ctrl-C, kill, a closed terminal or pipe): remove the temporaries of the
// outputs being written, then die of the same signal, so the shell sees 128 + N.
extern "C" void onFatalSignal(int signal) {
  emcalign::io::removeTemporaries();
  std::raise(signal);  // the handler was reset to the default by SA_RESETHAND
}

void installSignalHandlers() {
  struct sigaction action {};
  action.sa_handler = onFatalSignal;
  action.sa_flags = SA_RESETHAND;
  sigemptyset(&action.sa_mask);
  for (int s : {SIGINT, SIGTERM, SIGHUP, SIGPIPE}) sigaction(s, &action, nullptr);
  // Over a file-size limit (ulimit -f) a write then fails with EFBIG and is reported like a
  // full disk, instead of killing the process with its temporaries in place.
  std::signal(SIGXFSZ, SIG_IGN);
}

// Standard output was closed when the command started (`>&-`).
bool gStdoutClosed = false;

// A command's report or output to standard output that did not arrive (a full disk, a closed
// descriptor) is a failure, not a success. The command's own work (its files, its database
// writes) is done by then: the message says what was lost. A command that failed already said
// why (its output to standard output among it, if that was the failure).
int checkStandardOutput(int exitCode) {
  if (std::fflush(stdout) == 0 && std::ferror(stdout) == 0) return exitCode;
  const int error = errno;
  if (exitCode != emcalign::app::kExitOk && exitCode != emcalign::app::kExitUnusable) return exitCode;
  emcalign::app::eprint(
      "emcalign: error: standard output: {}: what the command printed there is lost (the files and database writes "
      "it reports are in place)\n",
      gStdoutClosed ? std::string("closed")
                    : fmt::format("write failed: {}", error != 0 ? std::strerror(error) : "an output error"));
  return emcalign::app::kExitFailure;
}

// Standard input, output and error are open: a command started with one closed (`2>&-`)
// would otherwise open its first file as that descriptor, and print its messages into it.
// Input and error are opened on /dev/null; output on /dev/null for reading only, so that what
// is printed there fails as a write to a closed descriptor does (EBADF).
void openStandardDescriptors() {
  for (int fd = 0; fd <= 2; ++fd) {
    if (::fcntl(fd, F_GETFD) != -1 || errno != EBADF) continue;
    if (fd == 1) gStdoutClosed = true;
    const int opened = ::open("/dev/null", fd == 2 ? O_WRONLY : O_RDONLY);
    if (opened >= 0 && opened != fd) {
      ::dup2(opened, fd);
      ::close(opened);
    }
  }
}

// Standard output without the command line's passwords (core/secrets.hpp): when it holds one,
// stdout becomes a line-buffered stream whose lines are redacted on their way to the real one.
void redactStandardOutput(int argc, char** argv) {
  for (int i = 0; i < argc; ++i) emcalign::core::rememberPasswordsOf(argv[i]);
  if (!emcalign::core::passwordsRemembered()) return;
  if (std::FILE* redacted = emcalign::core::redactingStream(stdout); redacted != nullptr) stdout = redacted;
}

// The command line parsed and run (main catches what escapes it).
int runMain(int argc, char** argv) {
  openStandardDescriptors();
  installSignalHandlers();
  // Before anything is printed: every line shows "***" for a password of the command line.
  redactStandardOutput(argc, argv);
  // No output of a command may replace one of its inputs (io/output_file.hpp).
  emcalign::io::enableInputProtection();
  CLI::App app{
      "emcalign: geometric calibration of the electromagnetic calorimeter relative to the "
      "tracking system (SND-like, 12 alignment parameters)"};
  app.set_version_flag("--version", std::string(emcalign::kVersion));
  app.require_subcommand(1);
  app.footer(
      "Exit codes: 0 ok; 1 input refused or a step failed (nothing written); 2 usage error; 3 result written "
      "but not converged; 4 internal error; 128+N killed by signal N. See docs/conventions.md.");
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return fmt::format("emcalign: usage error: {}\nRun with --help for more information.\n", e.what());
  });
  // Paths and names go into JSON (results, attributes), which is UTF-8: say so before any work.
  // A control character (a newline) would let a name forge a line of a message or a script.
  for (int i = 1; i < argc; ++i) {
    if (const std::string refused = emcalign::argumentRefusal(argv[i], i); !refused.empty()) {
      emcalign::app::eprint("emcalign: usage error: {}\n", refused);
      return emcalign::app::kExitUsage;
    }
  }
  int exitCode = 0;
  emcalign::app::addAllCommands(app, exitCode);
  emcalign::app::setCommandLine(argc, argv);
  if (auto mistyped = emcalign::app::mistypedArgument(app, argc, argv)) {
    emcalign::app::eprint("emcalign: usage error: {}\nRun with --help for more information.\n", *mistyped);
    return emcalign::app::kExitUsage;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version end here with 0; every other parse error is a usage error.
    // Printed here, not by CLI11 to std::cout/std::cerr: without the command line's passwords.
    std::ostringstream out, err;
    const int code = app.exit(e, out, err);
    const std::string text = emcalign::core::withoutPasswords(out.str());
    std::fwrite(text.data(), 1, text.size(), stdout);
    emcalign::app::writeToStderr(err.str());
    return code == 0 ? checkStandardOutput(0) : emcalign::app::kExitUsage;
  } catch (const emcalign::app::Refusal& r) {  // a command's input refused, or a step failed (must)
    return checkStandardOutput(emcalign::app::reportError(r.error));
  } catch (const std::system_error& e) {
    // fmt::print throws when standard output (or error, for a report sent there) cannot be
    // written: not a bug, but the command stopped there.
    if (std::ferror(stdout) != 0) return checkStandardOutput(emcalign::app::kExitOk);
    if (std::ferror(stderr) != 0) return emcalign::app::kExitFailure;
    emcalign::app::eprint("emcalign: internal error: {} (a bug: please report it with the command line)\n", e.what());
    return emcalign::app::kExitInternal;
  } catch (const std::exception& e) {
    emcalign::app::eprint("emcalign: internal error: {} (a bug: please report it with the command line)\n", e.what());
    return emcalign::app::kExitInternal;
  }
  return checkStandardOutput(exitCode);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const int code = runMain(argc, argv);
    // A command that failed leaves no empty output directory behind (its own, made for it).
    if (code != emcalign::app::kExitOk && code != emcalign::app::kExitUnusable) {
      emcalign::io::removeOutputDirectoriesLeftEmpty();
    }
    return code;
  } catch (const std::exception& e) {  // the parser's setup (allocation): nothing has run yet
    std::fprintf(stderr, "emcalign: internal error: %s (a bug: please report it with the command line)\n", e.what());
  } catch (...) {
    std::fputs("emcalign: internal error (a bug: please report it with the command line)\n", stderr);
  }
  return emcalign::app::kExitInternal;
}
