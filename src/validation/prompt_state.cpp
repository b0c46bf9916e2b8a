// The prompt loop's state directory (validation/prompt.hpp): state.json written and read, and
// the directory as the report's section.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "emcalign/io/strict_json.hpp"
#include "emcalign/report/html.hpp"
#include "emcalign/validation/prompt.hpp"
#include "prompt_internal.hpp"

namespace emcalign::validation {

namespace fs = std::filesystem;
using io::Json;
using prompt::State;

bool isPromptTemporary(std::string_view name) {
  return name.empty() || name.front() == '.' || name.ends_with(".tmp") || name.ends_with(".part") ||
         name.find(".tmp-") != std::string_view::npos;
}

namespace prompt {

// ---- the state kept in STATE_DIR/state.json

Json State::toJson() const {
  Json filesJson = Json::object();
  for (const auto& [name, f] : files) {
    filesJson[name] = {{"size", f.size},     {"mtime_ns", f.mtimeNs}, {"inode", f.inode},  {"sha256", f.sha256},
                       {"status", f.status}, {"runs", f.runs},        {"reason", f.reason}};
  }
  Json openJson = Json::array();
  for (const TakenRun& r : open) {
    openJson.push_back({{"run", r.run},
                        {"file", r.file},
                        {"beam_energy_mev", energyJson(r.beamEnergy)},
                        {"selected_events", r.selected}});
  }
  return {{"format", kPromptStateFormat},
          {"watch_dir", watchDir},
          {"tag", tag},
          {"conditions", conditions},
          {"decided", decided},
          {"decided_sha256", decidedSha256},
          {"model", model},
          {"files", filesJson},
          {"open", openJson},
          {"alerted", alerted},
          {"pending", pending}};
}

Result<State> State::parse(const Json& j, const std::string& source) {
  return io::strict::guarded([&]() -> State {
    const io::strict::StrictObject o(j, "", source);
    o.allowOnly({"format", "watch_dir", "tag", "conditions", "decided", "decided_sha256", "model", "files", "open",
                 "alerted", "pending"});
    if (o.string("format") != kPromptStateFormat) o.fail("format", fmt::format("expected \"{}\"", kPromptStateFormat));
    State s;
    s.watchDir = o.string("watch_dir");
    s.tag = o.string("tag");
    s.conditions = o.string("conditions");
    s.decided = o.at("decided").get<std::int64_t>();
    s.decidedSha256 = o.string("decided_sha256");
    s.model = o.at("model");
    const auto filesObject = o.object("files");
    for (const auto& [name, value] : o.at("files").items()) {
      const auto f = filesObject.object(name);
      f.allowOnly({"size", "mtime_ns", "inode", "sha256", "status", "runs", "reason"});
      FileEntry e;
      e.size = f.at("size").get<std::int64_t>();
      e.mtimeNs = f.at("mtime_ns").get<std::int64_t>();
      e.inode = f.at("inode").get<std::uint64_t>();
      e.sha256 = f.string("sha256");
      e.status = f.string("status");
      if (e.status != "taken" && e.status != "quarantined") f.fail(f.pathOf("status"), "expected taken or quarantined");
      e.runs = f.at("runs").get<std::vector<std::int32_t>>();
      e.reason = f.string("reason");
      s.files[name] = std::move(e);
    }
    const Json& openRuns = o.at("open");
    if (!openRuns.is_array()) o.fail("open", "expected an array");
    for (std::size_t k = 0; k < openRuns.size(); ++k) {
      const auto r = o.nested(openRuns[k], fmt::format("open[{}]", k));
      r.allowOnly({"run", "file", "beam_energy_mev", "selected_events"});
      s.open.push_back({r.at("run").get<std::int32_t>(), r.string("file"), r.numberOrNull("beam_energy_mev"),
                        r.at("selected_events").get<std::int64_t>()});
    }
    s.alerted = o.at("alerted").get<std::set<std::string>>();
    for (const auto& [key, record] : o.at("pending").items()) s.pending[key] = record;
    return s;
  });
}

}  // namespace prompt

Result<std::string> promptReportHtml(const std::string& stateDir) {
  const auto read = [&](const char* name) -> Result<std::string> {
    return io::readTextFile((fs::path(stateDir) / name).string());
  };
  auto stateText = read("state.json");
  if (!stateText) return stateText.error();
  const std::string statePath = (fs::path(stateDir) / "state.json").string();
  auto stateJson = io::parseJson(*stateText, statePath);
  if (!stateJson) return stateJson.error();
  auto state = State::parse(*stateJson, statePath);
  if (!state) return state.error();
  auto thresholdsText = read("thresholds.json");
  if (!thresholdsText) return thresholdsText.error();
  auto thresholds = io::parseJson(*thresholdsText, (fs::path(stateDir) / "thresholds.json").string());
  if (!thresholds) return thresholds.error();
  auto parsed = parseThresholds(*thresholds, (fs::path(stateDir) / "thresholds.json").string());
  if (!parsed) return parsed.error();
  auto text = read("decisions.jsonl");
  if (!text) return text.error();
  std::vector<std::string> records;
  std::int64_t minEvents = 0;
  std::size_t start = 0;
  while (start < text->size()) {
    const std::size_t end = std::min(text->find('\n', start), text->size());
    const std::string line = text->substr(start, end - start);
    start = end + 1;
    if (line.empty()) continue;
    const Json j = Json::parse(line, nullptr, false);
    if (!j.is_object() || !j.contains("runs") || !j.contains("decision") || !j.contains("parameters")) {
      return Error{
          fmt::format("{}/decisions.jsonl: record {} is not a decision of emcalign prompt", stateDir, records.size())};
    }
    minEvents = j.value("min_events", minEvents);
    records.push_back(line);
  }
  const prompt::StatusInput in{*state,     records,
                               state->tag, state->conditions,
                               minEvents,  Json{{"sha256", parsed->sha256}, {"json", parsed->json}},
                               ""};
  std::string body;
  for (const auto& section : prompt::statusSections(in)) {
    body += fmt::format("<h3>{}</h3>\n{}\n", report::html::escape(section.title), section.body);
  }
  return body;
}

}  // namespace emcalign::validation
