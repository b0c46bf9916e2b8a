#pragma once
// Strict reading of JSON inputs (the readers of io/json_files.cpp, the period scenario, …):
// an object whose keys are checked against the allowed ones, values of the expected type,
// and an error that names the file and the key path ("s.json: key 'segments[1].from_run':
// expected an integer"). The readers throw BadInput inside `guarded`, which returns it as an
// Error.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/fit_status.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::io::strict {

// Internal: the readers below throw this and the public functions turn it into an Error.
struct BadInput {
  std::string message;
};

inline std::string join(std::string_view path, std::string_view key) {
  return path.empty() ? std::string(key) : fmt::format("{}.{}", path, key);
}

inline std::string typeName(const Json& j) { return j.type_name(); }

/// The first key of the object `j` that is not one of `allowed`, if any ("x"); `j` must be an
/// object.
inline std::optional<std::string> unknownKey(const Json& j, std::initializer_list<std::string_view> allowed) {
  for (const auto& [key, value] : j.items()) {
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) return key;
  }
  return std::nullopt;
}

/// What every reader of a JSON file says of a key it does not know: "unknown key (allowed:
/// format, ranges)".
inline std::string unknownKeyText(std::initializer_list<std::string_view> allowed) {
  return fmt::format("unknown key (allowed: {})", fmt::join(allowed, ", "));
}

/// Where an object is: its file (or what else the messages call the input) and its key path
/// there ("" for the document itself).
struct Where {
  std::string_view source;
  std::string_view path = {};
};

/// The keys of the object `j` against the allowed ones, for the readers that return a Status:
/// "s.json: key 'ranges.x': unknown key (allowed: beta, mu)". `j` must be an object.
inline Status checkKeys(const Json& j, std::initializer_list<std::string_view> allowed, Where where) {
  if (auto key = unknownKey(j, allowed)) {
    return Error{fmt::format("{}: key '{}': {}", where.source, join(where.path, *key), unknownKeyText(allowed))};
  }
  return {};
}

// A JSON object whose keys are checked against the allowed ones.
class StrictObject {
 public:
  StrictObject(const Json& j, std::string path, std::string_view source)
      : j_(j), path_(std::move(path)), source_(source) {
    if (!j.is_object()) {
      fail(path_.empty() ? "the document" : path_, fmt::format("expected an object, got {}", typeName(j)));
    }
  }

  void allowOnly(std::initializer_list<std::string_view> allowed) const {
    if (auto key = unknownKey(j_, allowed)) fail(join(path_, *key), unknownKeyText(allowed));
  }

  [[nodiscard]] bool has(std::string_view key) const { return j_.contains(key); }
  [[nodiscard]] const Json& at(std::string_view key) const {
    if (!has(key)) fail(join(path_, key), "missing");
    return j_.at(std::string(key));
  }
  [[nodiscard]] std::string pathOf(std::string_view key) const { return join(path_, key); }
  /// The object at `key`, checked as this one is and named in the same file.
  [[nodiscard]] StrictObject object(std::string_view key) const { return {at(key), pathOf(key), source_}; }
  /// Another object of the same file (an array's element) at `path`.
  [[nodiscard]] StrictObject nested(const Json& j, std::string path) const { return {j, std::move(path), source_}; }

  [[nodiscard]] double number(std::string_view key) const { return numberValue(at(key), pathOf(key)); }
  [[nodiscard]] double number(std::string_view key, double fallback) const { return has(key) ? number(key) : fallback; }
  [[nodiscard]] std::string string(std::string_view key) const {
    const Json& v = at(key);
    if (!v.is_string()) fail(pathOf(key), fmt::format("expected a string, got {}", typeName(v)));
    return v.get<std::string>();
  }

  /// A number, or NaN for null (what io::numberOrNull writes for NaN); the key required.
  [[nodiscard]] double numberOrNull(std::string_view key) const {
    const Json& v = at(key);
    if (v.is_null()) return std::numeric_limits<double>::quiet_NaN();
    if (!v.is_number()) fail(pathOf(key), fmt::format("expected a number or null, got {}", typeName(v)));
    return v.get<double>();
  }
  /// The same, NaN when the key is absent too.
  [[nodiscard]] double numberOrNullIfGiven(std::string_view key) const {
    return has(key) ? numberOrNull(key) : std::numeric_limits<double>::quiet_NaN();
  }
  [[nodiscard]] std::int64_t integer(std::string_view key) const {
    const Json& v = at(key);
    if (!v.is_number_integer()) fail(pathOf(key), fmt::format("expected an integer, got {}", typeName(v)));
    return v.get<std::int64_t>();
  }
  [[nodiscard]] bool boolean(std::string_view key) const {
    const Json& v = at(key);
    if (!v.is_boolean()) fail(pathOf(key), fmt::format("expected true or false, got {}", typeName(v)));
    return v.get<bool>();
  }
  [[nodiscard]] const Json& array(std::string_view key) const {
    const Json& v = at(key);
    if (!v.is_array()) fail(pathOf(key), fmt::format("expected an array, got {}", typeName(v)));
    return v;
  }
  [[nodiscard]] std::vector<std::string> strings(std::string_view key) const {
    std::vector<std::string> out;
    const Json& list = array(key);
    for (std::size_t k = 0; k < list.size(); ++k) {
      if (!list[k].is_string()) fail(fmt::format("{}[{}]", pathOf(key), k), "expected a string");
      out.push_back(list[k].get<std::string>());
    }
    return out;
  }
  [[nodiscard]] std::vector<double> numbers(std::string_view key) const {
    std::vector<double> out;
    const Json& list = array(key);
    for (std::size_t k = 0; k < list.size(); ++k)
      out.push_back(numberValue(list[k], fmt::format("{}[{}]", pathOf(key), k)));
    return out;
  }

  [[nodiscard]] double numberValue(const Json& v, const std::string& where) const {
    if (!v.is_number()) fail(where, fmt::format("expected a number, got {}", typeName(v)));
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(where, "not a finite number");
    return x;
  }

  [[noreturn]] void fail(std::string_view where, std::string_view what) const {
    throw BadInput{fmt::format("{}: key '{}': {}", source_, where, what)};
  }

 private:
  const Json& j_;
  std::string path_;
  std::string_view source_;
};

/// The keys every reader of a parameter file or a fit result checks first (docs/contract.md §3): no key
/// such a file does not have, "format" (when given) emcalign-alignment/1, "units" (when
/// given) deg and cm, and only the 12 fit parameters' names in "parameters".
void checkAlignmentHeader(const StrictObject& top);

/// A fit result's "status" (core/fit_status.hpp), an unknown name refused with the four.
inline FitStatus fitStatusAt(const StrictObject& o, std::string_view key) {
  const std::string status = o.string(key);
  const auto s = fitStatusFromName(status);
  if (!s) {
    o.fail(o.pathOf(key),
           fmt::format("unknown status '{}' (converged, poor fit, not converged, covariance singular)", status));
  }
  return *s;
}

template <typename F>
auto guarded(F&& f) -> Result<decltype(f())> {
  try {
    return f();
  } catch (const BadInput& e) {
    return Error{e.message};
  } catch (const Json::exception& e) {
    return Error{e.what()};
  }
}

}  // namespace emcalign::io::strict
