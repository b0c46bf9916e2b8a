// The inputs no output may replace (io/output_file.hpp): the command's and each guard's,
// by identity and by name, and the check that an output directory holds none of them.

#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <mutex>

#include <fmt/format.h>

#include "emcalign/io/output_file.hpp"
#include "input_protection.hpp"

namespace emcalign::io {

namespace {

namespace fs = std::filesystem;

// An input no output may replace: its identity when it exists (device and inode, so that
// links and hard links are seen through) and its name (a file that does not exist yet, as a
// database's journal, must not be created by an output either). Entries of a guard (owner >
// 0) hold while the guard lives, whether or not the protection is on; the command's (owner 0)
// only while it is on.
struct ProtectedInput {
  NamedPath name;
  std::string absolute;  // the name, absolute and normalised
  bool exists = false;
  dev_t dev{};
  ino_t ino{};
  std::uint64_t owner = 0;              // 0: the command's; else the InputGuard's id
  bool directory = false;               // a directory whose files are read as data: nothing is created in it
  std::vector<std::string> extensions;  // directory: the names ending so are its data
};
std::mutex gProtectedMutex;
std::atomic<bool> gProtecting{false};
std::vector<ProtectedInput> gProtected;  // guarded by gProtectedMutex
std::atomic<std::uint64_t> gGuards{0};

// The file an existing path is (following links): a regular file's device and inode.
bool fileIdentity(const std::string& path, dev_t& dev, ino_t& ino) {
  struct stat st {};
  if (path.empty() || path == "-" || ::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
  dev = st.st_dev;
  ino = st.st_ino;
  return true;
}

// A path's name, absolute: links in its directories resolved (an output may reach the file
// through another directory), not a link that is the last component (that is another name).
std::string normalised(const std::string& p) {
  std::error_code ec;
  const fs::path absolute = fs::absolute(p, ec).lexically_normal();
  const fs::path directory = fs::weakly_canonical(absolute.parent_path(), ec);
  return ec ? absolute.string() : (directory / absolute.filename()).lexically_normal().string();
}

void addProtected(const NamedPath& input, std::uint64_t owner, bool directory,
                  std::vector<std::string> extensions = {}) {
  if (input.path.empty() || input.path == "-") return;
  ProtectedInput p{input, normalised(input.path), false, {}, {}, owner, directory, std::move(extensions)};
  if (!directory) p.exists = fileIdentity(input.path, p.dev, p.ino);
  const std::lock_guard lock(gProtectedMutex);
  for (auto& q : gProtected) {
    const bool same = q.directory == directory && q.owner == owner &&
                      (p.exists && q.exists ? q.dev == p.dev && q.ino == p.ino : q.absolute == p.absolute);
    if (!same) continue;
    if (q.name.option.empty()) q.name = input;  // the option it was given with names it best
    return;
  }
  gProtected.push_back(std::move(p));
}

bool applies(const ProtectedInput& p) { return p.owner != 0 || gProtecting.load(); }

}  // namespace

void enableInputProtection() { gProtecting.store(true); }

void disableInputProtection() {
  gProtecting.store(false);
  const std::lock_guard lock(gProtectedMutex);
  std::erase_if(gProtected, [](const ProtectedInput& p) { return p.owner == 0; });
}

void protectInput(const NamedPath& input) {
  if (gProtecting.load()) addProtected(input, 0, false);
}

void protectInputDirectory(const NamedPath& directory, const std::vector<std::string>& extensions) {
  if (gProtecting.load()) addProtected(directory, 0, true, extensions);
}

InputGuard::InputGuard(const std::vector<NamedPath>& files) : id_(++gGuards) {
  for (const auto& f : files) addProtected(f, id_, false);
}

InputGuard::~InputGuard() {
  const std::lock_guard lock(gProtectedMutex);
  std::erase_if(gProtected, [this](const ProtectedInput& p) { return p.owner == id_; });
}

std::optional<NamedPath> protectedInputAt(const std::string& path) {
  dev_t dev{};
  ino_t ino{};
  const bool exists = fileIdentity(path, dev, ino);
  const std::string absolute = normalised(path);
  const std::string parent = fs::path(absolute).parent_path().string();
  const std::lock_guard lock(gProtectedMutex);
  for (const auto& p : gProtected) {
    if (!applies(p)) continue;
    if (p.directory) {
      const bool data = std::any_of(p.extensions.begin(), p.extensions.end(),
                                    [&](const std::string& e) { return absolute.ends_with(e); });
      if (!exists && data && parent == p.absolute) return p.name;  // a new file among the data
      continue;
    }
    if ((exists && p.exists && p.dev == dev && p.ino == ino) || p.absolute == absolute) return p.name;
  }
  return std::nullopt;
}

Status checkDirectoryHoldsNoInput(const NamedPath& directory, const std::vector<NamedPath>& inputs, int maxDepth) {
  struct Known {
    NamedPath name;
    std::string absolute;  // the name it was given by, normalised
    dev_t dev;
    ino_t ino;
  };
  std::vector<Known> known;
  for (const auto& i : inputs) {
    dev_t dev{};
    ino_t ino{};
    if (fileIdentity(i.path, dev, ino)) known.push_back({i, normalised(i.path), dev, ino});
  }
  {
    const std::lock_guard lock(gProtectedMutex);
    for (const auto& p : gProtected) {
      if (applies(p) && p.exists) known.push_back({p.name, p.absolute, p.dev, p.ino});
    }
  }
  std::error_code ec;
  if (known.empty() || !fs::is_directory(directory.path, ec)) return {};
  constexpr std::size_t kMaxEntries = 100000;  // a campaign's directory; beyond, the write-time check remains
  std::size_t seen = 0;
  fs::recursive_directory_iterator it(directory.path, fs::directory_options::skip_permission_denied, ec);
  for (; !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (++seen > kMaxEntries) break;
    if (it.depth() >= maxDepth) it.disable_recursion_pending();
    std::error_code kind;
    if (it->is_directory(kind)) continue;
    dev_t dev{};
    ino_t ino{};
    const std::string entry = it->path().string();
    if (!fileIdentity(entry, dev, ino)) continue;
    for (const auto& k : known) {
      if (k.dev != dev || k.ino != ino || normalised(entry) == k.absolute) continue;
      return Error{fmt::format(
          "{} {}: {} is {} the input {}: an output written there would replace that input (remove it from the "
          "directory, or write elsewhere)",
          directory.option, directory.path, entry,
          fs::is_symlink(it->symlink_status(kind)) ? "a link to" : "a hard link of", describe(k.name))};
    }
  }
  return {};
}

std::string describe(const NamedPath& input) {
  return input.option.empty() ? input.path : input.option + " " + input.path;
}

}  // namespace emcalign::io
