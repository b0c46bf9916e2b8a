// A tag's changes as records and the snapshot times (conditions.hpp).

#include <fmt/format.h>

#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/clock.hpp"

namespace emcalign::conddb {

io::Json Change::json() const {
  io::Json out = {{"time", time},
                  {"change", change},
                  {"user", user.empty() ? io::Json(nullptr) : io::Json(user)},
                  {"host", host.empty() ? io::Json(nullptr) : io::Json(host)}};
  if (details.is_object()) {
    for (const auto& [key, value] : details.items()) {
      if (!out.contains(key)) out[key] = value;
    }
  }
  return out;
}

namespace {

std::string text(const io::Json& d, const char* key) {
  const auto it = d.find(key);
  if (it == d.end()) return "?";
  return it->is_string() ? it->get<std::string>() : it->dump();
}

std::string runs(const io::Json& d, const char* first, const char* last) {
  return fmt::format("runs {}-{}", text(d, first), text(d, last));
}

std::string range(const io::Json& pair) {
  return pair.is_array() && pair.size() == 2 ? fmt::format("{}-{}", pair[0].dump(), pair[1].dump()) : "?";
}

}  // namespace

std::string Change::summary() const {
  const io::Json& d = details;
  if (!d.is_object()) return "";
  std::string out;
  if (change == "iov") {
    out = fmt::format("{}, payload {}", runs(d, "first_run", "last_run"), text(d, "payload").substr(0, 12));
  } else if (change == "state") {
    out = fmt::format("{} -> {}", text(d, "from"), text(d, "to"));
    if (d.contains("reason")) out += ": " + text(d, "reason");
  } else if (change == "created" || change == "copy") {
    if (change == "copy" && d.contains("copy_of")) {
      const io::Json& o = d["copy_of"];
      out = fmt::format("copy of {} {}{}, ", text(o, "conditions"), text(o, "tag"),
                        o.contains("snapshot") ? " as it was at " + text(o, "snapshot") : std::string());
    }
    out += "state " + text(d, "state");
    if (d.contains("iovs") && d["iovs"] != 0) {
      out += fmt::format(", {} IOVs{}", text(d, "iovs"),
                         d.contains("runs") ? " (runs " + range(d["runs"]) + ")" : std::string());
    }
    if (d.contains("description") && !text(d, "description").empty()) out += ": " + text(d, "description");
  } else if (change == "promotion") {
    const io::Json last = d.value("last_iov", io::Json::object());
    out = fmt::format("from {} at run {}: last IOV {} {} to {}, {} IOVs appended (runs {})", text(d, "from"),
                      text(d, "first_safe_run"), range(last.value("was", io::Json())), text(d, "last_iov_fate"),
                      range(last.value("now", io::Json())), text(d, "appended"), range(d.value("runs", io::Json())));
  } else if (change == "prompt") {
    out = fmt::format("group {}: {}{}", text(d, "group"), text(d, "decision"),
                      d.contains("first_run") ? fmt::format(", {}, payload {}", runs(d, "first_run", "last_run"),
                                                            text(d, "payload").substr(0, 12))
                                              : std::string(", no IOV"));
  } else {
    out = d.dump();
  }
  if (d.contains("note")) out += " (" + text(d, "note") + ")";
  if (d.contains("from_schema")) out += " [from schema " + text(d, "from_schema") + "]";
  return out;
}

Result<std::string> parseSnapshot(std::string_view text, std::string_view option) {
  auto t = parseUtcTime(text);
  if (!t) return Error{fmt::format("{}: {}", option, t.error().message)};
  return utcMicrosText(*t);
}

Result<std::string> snapshotForm(const std::string& at) {
  if (at.empty()) return std::string();
  return parseSnapshot(at, "snapshot");
}

std::string Database::Promotion::lastIovFate() const {
  if (lastBefore.lastRun == firstSafeRun - 1) return "kept";
  return lastBefore.lastRun >= firstSafeRun ? "cut" : "extended";
}

}  // namespace emcalign::conddb
