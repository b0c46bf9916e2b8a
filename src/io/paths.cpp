#include "emcalign/io/paths.hpp"

#include <algorithm>
#include <filesystem>
#include <iterator>

namespace emcalign::io {

bool isWithin(const std::string& path, const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path p = fs::weakly_canonical(fs::absolute(path, ec), ec);
  if (ec) return false;
  const fs::path d = fs::weakly_canonical(fs::absolute(dir, ec), ec);
  if (ec) return false;
  const auto [end, at] = std::mismatch(d.begin(), d.end(), p.begin(), p.end());
  return end == d.end() || (std::next(end) == d.end() && end->empty());  // "d/" ends in an empty element
}

}  // namespace emcalign::io
