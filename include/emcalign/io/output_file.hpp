#pragma once
// Where an output goes and how it is written, so that no command ever destroys a file it
// should not touch (docs/conventions.md, "Output files").
//
// The rules, for every output of every command:
//  - "-" is the standard output, written directly.
//  - A character device (/dev/null, a terminal) or a FIFO (a named pipe, /dev/stdout on a
//    pipe) is written directly: it is never replaced by a regular file.
//  - A regular file, or a name that does not exist yet, is written through the temporary
//    `<path>.tmp-<pid>` in the same directory and renamed into place when complete: a
//    reader never sees half a file, and a failed or interrupted job leaves the old file as
//    it was. The new file keeps the permission bits of the file it replaces.
//  - A symbolic link is followed: the file it points to is replaced and the link stays (as
//    a shell's `>` would do). A link that points to nothing is refused.
//  - Refused before any work: a directory, a block device, a socket, a name in a missing
//    directory, a read-only file (no write permission bit, or not writable by this user:
//    `chmod u+w` allows replacing it), and an output that is the same file (device and
//    inode, through links) as an input of the command or as another of its outputs, and,
//    when the input protection is on, any file the command has read (see below).
//  - Temporaries are registered while they exist. `removeTemporaries()` deletes them and is
//    async-signal-safe: the command-line tool calls it from its SIGINT/SIGTERM/SIGHUP/
//    SIGPIPE handler. A temporary left by a process that no longer runs (kill -9, a crash)
//    is removed the next time the same target is written.

#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "emcalign/core/result.hpp"

namespace emcalign::io {

enum class OutputKind {
  Stdout,  ///< "-"
  Stream,  ///< a character device or a FIFO: written directly
  File,    ///< a regular file or a new name: written through a temporary and a rename
};

/// Who named an output. A user names the outputs of the command line, and may name a device or
/// a FIFO (`-o /dev/null`, `-o >(gzip > f)`); a command names the files it writes into its
/// output directories, and those are regular files: a FIFO or a device planted there (which
/// would block the command, or swallow its results) is refused.
enum class Placement {
  Named,        ///< an output of the command line
  InDirectory,  ///< a file a command writes inside an output directory
};

struct OutputTarget {
  std::string path;      ///< as given (used in messages)
  std::string realPath;  ///< File: the file that is replaced (links resolved); else `path`
  OutputKind kind = OutputKind::File;
};

/// Classifies an output path by the rules above; the error says why it is refused.
Result<OutputTarget> resolveOutput(const std::string& path, Placement placement = Placement::Named);

/// An output directory (figures, a campaign): it must be a directory or not exist yet (it is
/// then created with its parents when written); a file or a dangling link is refused.
Status checkOutputDirectory(const std::string& path);

/// A named path of a command, for messages: ("-o", "result.json").
struct NamedPath {
  std::string option;
  std::string path;
};

/// Refuses an output that is the same file as one of the inputs or as another output
/// (device and inode, through symbolic links). Outputs that do not exist yet, "-", devices
/// and FIFOs never clash.
Status checkDistinct(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs);

/// The inputs of the running command, which no output may replace. While protection is on
/// (the command-line tool turns it on first thing), every file output — also those a command
/// writes inside its output directories, and the figures gnuplot draws — is refused when it
/// is one of them (device and inode, through links and hard links), and the readers of this
/// library (readTextFile, event files, digests, the conditions database) add every file they
/// open. Off, as in a library embedded elsewhere (Python), where reading a file and writing it
/// later is the caller's choice, `protectInput` does nothing.
void enableInputProtection();
/// Turns the protection off and forgets the inputs (tests).
void disableInputProtection();
/// Adds an input (a file that does not exist, "-" or an empty name is skipped).
void protectInput(const NamedPath& input);
/// Adds a directory whose files the command reads as data (a corrections grid: *.json, a
/// directory of event files: *.h5, *.hdf5, *.csv): no output may create a file there whose name
/// ends in one of `extensions` (it would be read with them next time).
void protectInputDirectory(const NamedPath& directory, const std::vector<std::string>& extensions);
/// The protected input that `path` is (through links), or, for a file that does not exist,
/// the protected name or data directory it would land in; none otherwise.
std::optional<NamedPath> protectedInputAt(const std::string& path);

/// Files no output may replace or create while the guard lives, whether or not the protection
/// is on: an open database's file and journals (Python holds one open while it writes files).
class InputGuard {
 public:
  explicit InputGuard(const std::vector<NamedPath>& files);
  ~InputGuard();
  InputGuard(const InputGuard&) = delete;
  InputGuard& operator=(const InputGuard&) = delete;

 private:
  std::uint64_t id_;
};

/// An output directory that exists must hold no file that is an input of the command under
/// another name (a link or a hard link planted as `DIR/trend.json` → the database): an output
/// written there would replace the input. Looks `maxDepth` levels down; the inputs are
/// `inputs` and the protected ones.
Status checkDirectoryHoldsNoInput(const NamedPath& directory, const std::vector<NamedPath>& inputs, int maxDepth = 3);

/// Writes `content` to `path` by the rules above.
Status writeOutputFile(const std::string& path, std::string_view content, Placement placement = Placement::Named);
/// `dir/name`, a file a command writes inside its output directory (Placement::InDirectory).
Status writeFileIn(const std::string& dir, const std::string& name, std::string_view content);

/// An output written in pieces (event files): a temporary for a File target (stale
/// temporaries of the same target removed first), the target itself for a Stream, the
/// standard output for "-". `commit()` renames the temporary into place; destroying an
/// uncommitted output removes its temporary (a Stream keeps what was written).
class OutputFile {
 public:
  /// Opens for writing with stdio (binary). For a File target the temporary is created
  /// exclusively: an existing `<path>.tmp-<pid>` of this process is an error.
  static Result<std::unique_ptr<OutputFile>> open(const std::string& path, Placement placement = Placement::Named);
  /// For writers that must create the file themselves (HDF5 needs a seekable file): only
  /// reserves and registers the temporary name, which is in the target's directory for a
  /// File target and in the system's temporary directory for a Stream or "-" (its content
  /// is copied to the target by `commit()`).
  static Result<std::unique_ptr<OutputFile>> reserve(const std::string& path, Placement placement = Placement::Named);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  /// The stream to write (open() only; null after commit).
  [[nodiscard]] std::FILE* stream() const { return stream_; }
  /// The file being written: the temporary, or the target itself for a direct write.
  [[nodiscard]] const std::string& writtenPath() const { return written_; }
  [[nodiscard]] const OutputTarget& target() const { return target_; }
  /// Flushes, closes and puts the content in place; the error names the system's reason.
  Status commit();

 private:
  OutputFile() = default;
  Status closeStream();

  OutputTarget target_;
  std::string written_;
  std::FILE* stream_ = nullptr;
  bool temporary_ = false;     ///< written_ is a registered temporary
  bool copyOnCommit_ = false;  ///< a temporary whose content goes to a Stream or stdout
  bool committed_ = false;
  int slot_ = -1;
  int mode_ = -1;  ///< permission bits of the replaced file, or -1
};

/// Removes every registered temporary now. Async-signal-safe (only unlink(2)).
void removeTemporaries() noexcept;

/// The output directories checkOutputDirectory found absent, removed when they are (still)
/// empty: a command that failed leaves no empty directory behind (rmdir(2): nothing in one is
/// ever removed).
void removeOutputDirectoriesLeftEmpty() noexcept;
/// From now on, removeOutputDirectoriesLeftEmpty removes nothing: the process runs a task of a
/// plan, whose output directories its sibling tasks share (one of them may have just made one).
void keepOutputDirectories() noexcept;

/// Whether a file name (without its directory) is an emcalign temporary: `NAME.tmp-PID`, or
/// `.corrected-PID.h5`, which `check` wrote before. Never an input: a command that lists a
/// directory skips them, and the event reader refuses one that is not its own process's (a
/// command reads back only what it writes itself: `check` its corrected events).
bool isTemporaryName(std::string_view filename);
/// The process that writes a temporary of that name (0 when it is none).
long temporaryWriter(std::string_view filename);

/// The name of the temporary of a File target for this process: `<realPath>.tmp-<pid>`.
std::string temporaryPathFor(const std::string& realPath);

}  // namespace emcalign::io
