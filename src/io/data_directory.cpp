#include "emcalign/io/data_directory.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/io/output_file.hpp"

namespace emcalign::io {

namespace fs = std::filesystem;

Result<std::vector<std::string>> dataFilesIn(const std::string& dir, const std::vector<std::string>& extensions,
                                             std::string_view what, const std::string& option) {
  std::vector<std::string> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.starts_with(".") || isTemporaryName(name)) continue;  // hidden, or a command's work in progress
    std::string ext = e.path().extension().string();               // .H5 is .h5
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (std::find(extensions.begin(), extensions.end(), ext) == extensions.end()) continue;
    std::error_code kind;
    if (!e.is_regular_file(kind)) {
      const bool link = e.is_symlink(kind);
      const bool dangling = link && !fs::exists(e.path(), kind);
      return Error{fmt::format("{}: not a regular file ({}{}): {} of the directory that cannot be read",
                               e.path().string(), link ? "a link to " : "",
                               dangling ? "nothing" : "a FIFO, a device or a directory", what)};
    }
    files.push_back(e.path().string());
  }
  if (ec) return Error{fmt::format("{}: cannot list the directory: {}", dir, ec.message())};
  std::sort(files.begin(), files.end());
  protectInputDirectory({option, dir}, extensions);
  return files;
}

}  // namespace emcalign::io
