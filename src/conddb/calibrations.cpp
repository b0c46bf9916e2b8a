#include "emcalign/conddb/calibrations.hpp"

#include <cmath>
#include <filesystem>
#include <limits>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/apply/placements.hpp"
#include "emcalign/calib/fit_notes.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/utf8.hpp"
#include "emcalign/core/version.hpp"
#include "lenient_json.hpp"

namespace emcalign::conddb {

namespace {

namespace fs = std::filesystem;
using io::Json;

// The digests of a fit's inputs: found as named, or next to the result file.
Json inputDigests(const Json& result, const std::string& resultPath, std::vector<std::string>& warnings) {
  Json digests = Json::object();
  if (!result.contains("input") || !result["input"].is_object() || !result["input"].contains("files") ||
      !result["input"]["files"].is_array()) {
    return digests;
  }
  for (const Json& f : result["input"]["files"]) {
    if (!f.is_string()) continue;
    const std::string name = f.get<std::string>();
    std::string path = name;
    if (!fs::exists(path)) path = (fs::path(resultPath).parent_path() / name).string();
    if (!fs::is_regular_file(path)) {
      warnings.push_back(fmt::format("{}: input {} not found: its digest is not recorded", resultPath, name));
      continue;
    }
    auto d = sha256OfFile(path);
    if (!d) {
      warnings.push_back(d.error().message);
      continue;
    }
    digests[name] = *d;
  }
  return digests;
}

}  // namespace

Result<PutReport> putResultFile(Database& db, const ResultFileToPut& file) {
  const std::string& tag = file.tag;
  const std::string& path = file.path;
  auto text = io::readTextFile(path);
  if (!text) return text.error();
  auto j = io::parseJson(*text, path);
  if (!j) return j.error();
  PutReport report;
  Json provenance = {{"source_sha256", sha256(*text)}, {"put_software", fmt::format("emcalign {}", kVersion)}};
  if (Json d = inputDigests(*j, path, report.warnings); !d.empty()) provenance["input_sha256"] = d;
  auto payload = makePayload(*j, file.r1, path, provenance);
  if (!payload) return payload.error();
  // A parameter file's unit slip (a fit result's own warnings say its range).
  if (!j->contains("status")) {
    if (auto eta = io::parseAlignment(payload->parameterFile(), file.r1, path); eta) {
      if (auto w = calib::parametersRangeWarning(*eta, file.r1)) report.warnings.push_back(*w);
    }
  }
  auto existed = db.tag(tag);
  if (!existed) return existed.error();
  if (Status s = db.put(tag, file.firstRun, file.lastRun, *payload, IfMissing::Create, file.description); !s)
    return s.error();
  report.newTag = !existed->has_value();
  report.payload = payload->hash();
  return report;
}

io::Json parameterFileOf(const Iov& iov, const Payload& payload, const std::string& uri, const std::string& tag,
                         const std::string& at) {
  Json file = payload.parameterFile();
  Json input = {{"conditions", uri}, {"tag", tag}};
  if (!at.empty()) input["snapshot"] = at;
  input["first_run"] = iov.firstRun;
  input["last_run"] = iov.lastRun;
  input["payload"] = iov.payload;
  input["inserted"] = iov.inserted;
  if (payload.content.contains("selected_events")) input["selected_events"] = payload.content["selected_events"];
  if (payload.content.contains("provenance")) input["provenance"] = payload.content["provenance"];
  file["input"] = std::move(input);
  return file;
}

namespace {

// Whether `tag` holds exactly these IOVs: false when the tag does not exist, an error when it
// holds anything else.
Result<bool> tagHolds(Database& db, const std::string& tag, const std::vector<Database::NewIov>& iovs) {
  auto t = db.tag(tag);
  if (!t) return t.error();
  if (!t->has_value()) return false;
  auto stored = db.iovs(tag);
  if (!stored) return stored.error();
  bool same = stored->size() == iovs.size();
  for (std::size_t k = 0; same && k < iovs.size(); ++k) {
    same = (*stored)[k].firstRun == iovs[k].firstRun && (*stored)[k].lastRun == iovs[k].lastRun &&
           (*stored)[k].payload == iovs[k].payload.hash();
  }
  if (!same) {
    return Error{
        fmt::format("{}: tag '{}' exists already, with other IOVs or calibrations: write to a new tag", db.uri(), tag)};
  }
  return true;
}

}  // namespace

Result<WholeTagPut> putWholeTag(Database& db, const std::string& tag, const std::vector<Database::NewIov>& iovs,
                                const std::string& description, TagState state) {
  auto held = tagHolds(db, tag, iovs);
  if (!held) return held.error();
  if (*held) return WholeTagPut::HeldAlready;
  auto made = db.createTag({.name = tag, .description = description, .state = state, .iovs = iovs});
  if (!made) return made.error();
  if (!*made) {
    auto meanwhile = tagHolds(db, tag, iovs);  // a copy of this job stored it first
    if (!meanwhile) return meanwhile.error();
    if (*meanwhile) return WholeTagPut::HeldAlready;
    return Error{fmt::format("{}: tag '{}' exists already: write to a new tag", db.uri(), tag)};
  }
  return WholeTagPut::Stored;
}

Result<CopiedTag> copyTag(Database& from, const std::string& tag, Database& to, const std::string& as,
                          const std::string& at) {
  auto snapshot = TagSnapshot::load(from, tag, false, at);
  if (!snapshot) return snapshot.error();
  std::vector<Database::NewIov> iovs;
  iovs.reserve(snapshot->iovs().size());
  for (const auto& iov : snapshot->iovs()) {
    auto p = snapshot->payload(iov);
    if (!p) return p.error();
    iovs.push_back({iov.firstRun, iov.lastRun, **p});
  }
  const std::string name = as.empty() ? tag : as;
  Json origin = {{"conditions", from.uri()}, {"tag", tag}};
  if (!snapshot->at().empty()) origin["snapshot"] = snapshot->at();
  const Tag& t = snapshot->tag();
  const std::string description = t.description.empty() ? fmt::format("copy of {} {}", from.uri(), tag) : t.description;
  auto made =
      to.createTag({.name = name, .description = description, .state = t.state, .iovs = iovs, .copyOf = origin});
  if (!made) return made.error();
  if (!*made) return Error{fmt::format("{}: tag '{}' exists already (copy to a new tag: --as NAME)", to.uri(), name)};
  return CopiedTag{iovs.size(), t.state};
}

Result<RunCalibration> calibrationAt(Database& db, const std::string& tag, std::int64_t run,
                                     const std::string& atText) {
  auto snapshot = snapshotForm(atText);  // the text recorded
  if (!snapshot) return snapshot.error();
  const std::string& at = *snapshot;
  if (!at.empty()) {
    auto t = db.tag(tag, at);
    if (!t) return t.error();
    if (!t->has_value()) return missingTag(db, tag, at);
  }
  auto got = db.get(tag, run, at);
  if (!got) return got.error();
  if (!got->has_value()) {
    auto t = db.tag(tag);
    if (t && !t->has_value()) {
      return Error{fmt::format("{}: no tag '{}' (the tags: emcalign conditions list {})", db.uri(), tag, db.uri())};
    }
    return Error{fmt::format("{}: tag '{}': no IOV contains run {}{}", db.uri(), tag, run,
                             at.empty() ? std::string() : " at " + at)};
  }
  const auto& [iov, payload] = **got;
  return RunCalibration{iov, parameterFileOf(iov, payload, db.uri(), tag, at)};
}

IovListing iovListing(const Iov& iov, const Payload& payload) {
  // What a stored fit result says, where it says it as a fit result writes it.
  const Json& content = payload.content;
  const Json& a = lenient::objectAt(content, "alignment");
  const Json& sigma = lenient::objectAt(a, "sigma_sys");
  return {.iov = iov,
          .status = io::stringAt(a, "status"),
          .chi2 = lenient::numberAt(a, "chi2"),
          .ndf = lenient::integerAt(a, "ndf"),
          .sigmaSysMethod = io::stringAt(sigma, "method"),
          .chi2Statistical = lenient::numberAt(sigma, "chi2_statistical_errors"),
          .sigmaSysDeg = lenient::numberAt(sigma, "value_deg"),
          .selectedEvents = lenient::integerAt(content, "selected_events"),
          .model = payload.modelIdentity()};
}

std::string sigmaSysSummary(const std::vector<IovListing>& iovs) {
  std::set<std::string> methods;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& i : iovs) {
    methods.insert(i.sigmaSysMethod.value_or(""));
    if (i.sigmaSysDeg && std::isfinite(*i.sigmaSysDeg)) {
      lo = std::min(lo, *i.sigmaSysDeg);
      hi = std::max(hi, *i.sigmaSysDeg);
    }
  }
  if (methods.empty() || (methods.size() == 1 && methods.begin()->empty()) || !(lo <= hi)) return "-";
  const std::string values = lo == hi ? fmt::format("{:.3g} deg", lo) : fmt::format("{:.3g}-{:.3g} deg", lo, hi);
  if (methods.size() > 1) return printable(fmt::format("mixed ({}): {}", fmt::join(methods, ", "), values));
  return *methods.begin() == "auto" ? "auto (" + values + ")" : values;
}

std::string modelSummary(const std::vector<IovListing>& iovs, bool brief) {
  std::vector<calib::ModelIdentity> models;
  for (const auto& i : iovs) calib::addDistinct(models, i.model);
  if (models.empty() || (models.size() == 1 && models.front().kind == calib::ModelIdentity::Kind::Unsaid)) return "-";
  if (models.size() > 1) {
    if (brief) return "mixed";
    std::set<std::string> texts;  // one text for models that differ only by a digest one of them lacks
    for (const auto& m : models) texts.insert(m.text());
    return printable(fmt::format("mixed: {}", fmt::join(texts, " | ")));
  }
  return printable(brief ? models.front().brief() : models.front().text());
}

Result<TagListing> tagListing(Database& db, const Tag& tag, const std::string& at) {
  auto list = db.iovs(tag.name, at);
  if (!list) return list.error();
  TagListing listing{.tag = tag};
  if (list->empty()) return listing;
  auto payloads = db.payloadsOf(tag.name);  // each hash checked: an edited payload is an error, not shown
  if (!payloads) return payloads.error();
  listing.iovs.reserve(list->size());
  for (const auto& iov : *list) {
    auto it = payloads->find(iov.payload);
    if (it == payloads->end()) return Error{fmt::format("{}: no payload {}", db.uri(), printable(iov.payload))};
    listing.iovs.push_back(iovListing(iov, *it->second));
  }
  return listing;
}

Json tagJson(const TagListing& listing) {
  Json iovs = Json::array();
  for (const auto& l : listing.iovs) {
    Json i = {{"first_run", l.iov.firstRun},
              {"last_run", l.iov.lastRun},
              {"payload", l.iov.payload},
              {"inserted", l.iov.inserted}};
    if (l.status) i["status"] = *l.status;
    if (l.chi2) i["chi2"] = io::numberOrNull(*l.chi2);
    if (l.ndf) i["ndf"] = *l.ndf;
    if (l.sigmaSysMethod) i["sigma_sys_method"] = *l.sigmaSysMethod;
    if (l.chi2Statistical) i["chi2_statistical_errors"] = io::numberOrNull(*l.chi2Statistical);
    if (l.sigmaSysDeg && std::isfinite(*l.sigmaSysDeg)) i["sigma_sys_deg"] = *l.sigmaSysDeg;
    if (l.selectedEvents) i["selected_events"] = *l.selectedEvents;
    i["model"] = l.model.text();
    iovs.push_back(std::move(i));
  }
  const Tag& tag = listing.tag;
  Json out{{"tag", tag.name}, {"state", name(tag.state)}, {"description", tag.description}, {"created", tag.created}};
  if (!tag.stateChanged.empty()) out["state_changed"] = tag.stateChanged;
  if (!tag.reason.empty()) out["reason"] = tag.reason;
  out["iovs"] = iovs;
  return out;
}

Result<std::vector<TagListing>> listTags(Database& db, const std::string& tag, const std::string& at) {
  std::vector<Tag> tags;
  if (!tag.empty()) {
    auto t = db.tag(tag, at);
    if (!t) return t.error();
    if (!t->has_value()) {
      auto now = at.empty() ? t : db.tag(tag);
      if (now && now->has_value()) {
        return Error{fmt::format("{}: tag '{}' did not exist at {} (created {})", db.uri(), tag, at, (*now)->created)};
      }
      return Error{fmt::format("{}: no tag '{}'", db.uri(), tag)};
    }
    tags.push_back(**t);
  } else {
    auto all = db.tags(at);
    if (!all) return all.error();
    tags = std::move(*all);
  }
  std::vector<TagListing> listed;
  for (const auto& t : tags) {
    auto l = tagListing(db, t, at);
    if (!l) return l.error();
    listed.push_back(std::move(*l));
  }
  return listed;
}

Result<TagAlignments> TagAlignments::open(const std::string& uri, const std::string& tag,
                                          const geometry::Calorimeter& calo, const std::string& at) {
  auto db = Database::open(uri);
  if (!db) return db.error();
  std::string when = at;
  if (when.empty()) {
    // The tag as of its latest change, read first: a change committed meanwhile is not seen, and
    // a rerun at this time reads what this one read.
    if (auto t = (*db)->tag(tag); t && t->has_value()) {
      auto last = (*db)->lastChange(tag);
      if (!last) return last.error();
      when = *last;
    }
  }
  auto snapshot = TagSnapshot::load(**db, tag, false, when);
  if (!snapshot) return snapshot.error();
  TagAlignments c;
  c.db_ = std::move(*db);
  c.snapshot_ = std::make_unique<TagSnapshot>(std::move(*snapshot));
  c.calo_ = &calo;
  return c;
}

Result<std::vector<std::pair<std::string, double>>> TagAlignments::fittedDepths() {
  std::vector<std::pair<std::string, double>> out;
  for (const Iov& iov : snapshot_->iovs()) {
    if (!transforms_.empty() && transforms_.count(iov.firstRun) == 0) continue;  // only the IOVs used, once used
    auto p = snapshot_->payload(iov);
    if (!p) return p.error();
    const std::optional<double> offset = (*p)->depthOffsetCm();
    if (!offset) continue;
    std::pair<std::string, double> d{(*p)->modelIdentity().text(), *offset};
    if (std::find(out.begin(), out.end(), d) == out.end()) out.push_back(std::move(d));
  }
  return out;
}

Result<geometry::AlignmentParameters> TagAlignments::parametersOf(std::int64_t run) {
  auto at = snapshot_->at(run);
  if (!at) return at.error();
  const auto& [iov, payload] = *at;
  return io::parseAlignment(payload->parameterFile(), calo_->description().r1(),
                            fmt::format("{} tag {} IOV {}-{}", db_->uri(), tag(), iov->firstRun, iov->lastRun));
}

Result<std::shared_ptr<const geometry::AlignmentTransform>> TagAlignments::transformOf(std::int64_t run) {
  const Iov* iov = snapshot_->find(run);
  if (iov != nullptr) {
    if (auto it = transforms_.find(iov->firstRun); it != transforms_.end()) return it->second;
  }
  auto eta = parametersOf(run);
  if (!eta) return eta.error();
  auto t = geometry::AlignmentTransform::create(*eta, geometry::AlignmentRadii::of(calo_->description()));
  if (!t) return t.error();
  auto shared = std::make_shared<const geometry::AlignmentTransform>(std::move(*t));
  transforms_[iov->firstRun] = shared;
  return shared;
}

apply::AlignmentOfRun AlignmentSource::alignmentOf() const {
  auto byRunAlignments = byRun;
  auto single = one;
  return [byRunAlignments, single](std::int64_t run) -> Result<std::shared_ptr<const geometry::AlignmentTransform>> {
    if (byRunAlignments) return byRunAlignments->transformOf(run);
    return single;
  };
}

Result<AlignmentSource> AlignmentSource::open(const std::string& alignment, const std::string& conditions,
                                              const std::string& tag, const geometry::Calorimeter& calo,
                                              const std::string& snapshot) {
  AlignmentSource a;
  if (!conditions.empty()) {
    auto c = TagAlignments::open(conditions, tag, calo, snapshot);
    if (!c) return c.error();
    a.byRun = std::make_shared<TagAlignments>(std::move(*c));
    a.description = {{"conditions", a.byRun->uri()}, {"tag", tag}, {"conditions_snapshot", a.byRun->at()}};
    auto depths = a.byRun->fittedDepths();
    if (!depths) return depths.error();
    a.fittedDepths = std::move(*depths);
    return a;
  }
  auto file = apply::loadAlignment(alignment, calo);
  if (!file) return file.error();
  a.warnings = file->warnings;
  auto transform =
      geometry::AlignmentTransform::create(file->parameters, geometry::AlignmentRadii::of(calo.description()));
  if (!transform) return transform.error();
  a.one = std::make_shared<const geometry::AlignmentTransform>(std::move(*transform));
  a.description = {{"file", alignment}, {"parameters", io::alignmentToJson(file->parameters)["parameters"]}};
  // A fit result says its model: input.model_corrections (absent: the paper's, no offset).
  if (auto text = io::readTextFile(alignment); text) {
    const io::Json j = io::Json::parse(*text, nullptr, false);
    if (j.is_object() && j.contains("input") && j["input"].is_object() && j.contains("chi2")) {
      const io::Json& input = j["input"];
      const io::Json c = input.value("model_corrections", io::Json::object());
      const io::Json offset = c.is_object() ? c.value("depth_offset_cm", io::Json(0.0)) : io::Json(0.0);
      const io::Json response = c.is_object() ? c.value("response", io::Json()) : io::Json();
      a.fittedDepths.emplace_back(
          response.is_string() ? "corrections " + response.get<std::string>() : std::string("the paper's model"),
          offset.is_number() ? offset.get<double>() : 0.0);
    }
  }
  return a;
}

}  // namespace emcalign::conddb
