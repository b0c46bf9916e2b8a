#include "conditions_support.hpp"

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::app {

io::Json parameterFileOf(const conddb::Iov& iov, const conddb::Payload& payload, const std::string& uri,
                         const std::string& tag) {
  io::Json file = payload.parameterFile();
  io::Json input = {{"conditions", uri},         {"tag", tag},
                    {"first_run", iov.firstRun}, {"last_run", iov.lastRun},
                    {"payload", iov.payload},    {"inserted", iov.inserted}};
  if (payload.content.contains("selected_events")) input["selected_events"] = payload.content["selected_events"];
  if (payload.content.contains("provenance")) input["provenance"] = payload.content["provenance"];
  file["input"] = std::move(input);
  return file;
}

Result<ConditionsAlignments> ConditionsAlignments::open(const std::string& uri, const std::string& tag,
                                                        const geometry::Calorimeter& calo) {
  auto db = conddb::Database::open(uri);
  if (!db) return db.error();
  auto snapshot = conddb::TagSnapshot::load(**db, tag);
  if (!snapshot) return snapshot.error();
  ConditionsAlignments c;
  c.db_ = std::move(*db);
  c.snapshot_ = std::make_unique<conddb::TagSnapshot>(std::move(*snapshot));
  c.calo_ = &calo;
  return c;
}

Result<geometry::AlignmentParameters> ConditionsAlignments::parametersOf(std::int64_t run) {
  auto at = snapshot_->at(run);
  if (!at) return at.error();
  const auto& [iov, payload] = *at;
  return io::parseAlignment(payload->parameterFile(), calo_->description().r1(),
                            fmt::format("{} tag {} IOV {}-{}", db_->uri(), tag(), iov->firstRun, iov->lastRun));
}

Result<std::shared_ptr<const geometry::AlignmentTransform>> ConditionsAlignments::transformOf(std::int64_t run) {
  const conddb::Iov* iov = snapshot_->find(run);
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
                                              const std::string& tag, const geometry::Calorimeter& calo) {
  AlignmentSource a;
  if (!conditions.empty()) {
    auto c = ConditionsAlignments::open(conditions, tag, calo);
    if (!c) return c.error();
    a.byRun = std::make_shared<ConditionsAlignments>(std::move(*c));
    a.description = {{"conditions", a.byRun->uri()}, {"tag", tag}};
    return a;
  }
  auto file = loadAlignment(alignment, calo);
  if (!file) return file.error();
  a.warnings = file->warnings;
  auto transform =
      geometry::AlignmentTransform::create(file->parameters, geometry::AlignmentRadii::of(calo.description()));
  if (!transform) return transform.error();
  a.one = std::make_shared<const geometry::AlignmentTransform>(std::move(*transform));
  a.description = {{"file", alignment}, {"parameters", io::alignmentToJson(file->parameters)["parameters"]}};
  return a;
}

Result<apply::CorrectOptions> correctOptions(const std::string& method, double depthOffsetCm,
                                             const std::string& corrections, const geometry::Calorimeter& calo) {
  apply::CorrectOptions options;
  options.method = *apply::correctionMethodFromName(method);
  options.depth = geometry::ShowerDepth::of(calo.description());
  options.depth.offset = depthOffsetCm * units::cm;
  if (!corrections.empty()) {
    auto grid = calib::CorrectionsGrid::read(corrections);
    if (!grid) return grid.error();
    if (grid->isGrid()) {
      options.depthAt =
          calib::depthAtEnergy(std::make_shared<const calib::CorrectionsGrid>(std::move(*grid)), options.depth);
    } else {
      options.depth.offset = grid->points().front().corrections.depthOffset;
    }
  }
  return options;
}

io::Json tagJson(conddb::Database& db, const conddb::Tag& tag) {
  using io::Json;
  Json iovs = Json::array();
  auto list = db.iovs(tag.name);
  if (list) {
    for (const auto& iov : *list) {
      Json i = {
          {"first_run", iov.firstRun}, {"last_run", iov.lastRun}, {"payload", iov.payload}, {"inserted", iov.inserted}};
      if (auto p = db.payload(iov.payload); p) {
        const Json& a = p->content["alignment"];
        for (const char* key : {"status", "chi2", "ndf"}) {
          if (a.contains(key)) i[key] = a[key];
        }
        if (p->content.contains("selected_events")) i["selected_events"] = p->content["selected_events"];
      }
      iovs.push_back(std::move(i));
    }
  }
  return {{"tag", tag.name},
          {"state", conddb::name(tag.state)},
          {"description", tag.description},
          {"created", tag.created},
          {"iovs", iovs}};
}

}  // namespace emcalign::app
