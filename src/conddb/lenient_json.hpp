#pragma once
// The lookups of conddb's lenient readers (Payload's members, iovListing): a database can
// hold anything, so what is not where, or not what, a payload's writer puts reads as absent.

#include <cstdint>
#include <limits>
#include <optional>
#include <string_view>

#include "emcalign/io/json_files.hpp"

namespace emcalign::conddb::lenient {

/// The object at `key` of an object; an empty one when there is none.
inline const io::Json& objectAt(const io::Json& j, std::string_view key) {
  static const io::Json kEmpty = io::Json::object();
  if (!j.is_object()) return kEmpty;
  const auto it = j.find(key);
  return it != j.end() && it->is_object() ? *it : kEmpty;
}

/// The number at `key` of an object: NaN for a null (a writer's NaN), none when there is no
/// number.
inline std::optional<double> numberAt(const io::Json& j, std::string_view key) {
  if (!j.is_object()) return std::nullopt;
  const auto it = j.find(key);
  if (it == j.end()) return std::nullopt;
  if (it->is_null()) return std::numeric_limits<double>::quiet_NaN();
  return it->is_number() ? std::optional<double>(it->get<double>()) : std::nullopt;
}

/// The integer at `key` of an object, if there is one.
inline std::optional<std::int64_t> integerAt(const io::Json& j, std::string_view key) {
  if (!j.is_object()) return std::nullopt;
  const auto it = j.find(key);
  return it != j.end() && it->is_number_integer() ? std::optional<std::int64_t>(it->get<std::int64_t>()) : std::nullopt;
}

}  // namespace emcalign::conddb::lenient
