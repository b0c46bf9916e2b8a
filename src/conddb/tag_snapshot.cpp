#include <algorithm>
#include <map>

#include <fmt/format.h>

#include "emcalign/conddb/conditions.hpp"

namespace emcalign::conddb {

Result<TagSnapshot> TagSnapshot::load(Database& db, const std::string& tag, bool allowRetired) {
  auto t = db.tag(tag);
  if (!t) return t.error();
  if (!t->has_value()) {
    return Error{fmt::format("{}: no tag '{}' (the tags: emcalign conditions list {})", db.uri(), tag, db.uri())};
  }
  if ((*t)->state == TagState::Retired && !allowRetired) {
    return Error{fmt::format("{}: tag '{}' was retired ({}): it is kept and listed, but never served", db.uri(), tag,
                             (*t)->retired)};
  }
  auto iovs = db.iovs(tag);
  if (!iovs) return iovs.error();
  TagSnapshot s;
  s.db_ = &db;
  s.tag_ = **t;
  s.iovs_ = std::move(*iovs);
  s.payloads_.resize(s.iovs_.size());
  return s;
}

const Iov* TagSnapshot::find(std::int64_t run) const {
  // The IOVs never overlap: the candidate is the last one starting at or before `run`.
  auto it = std::upper_bound(iovs_.begin(), iovs_.end(), run,
                             [](std::int64_t r, const Iov& iov) { return r < iov.firstRun; });
  if (it == iovs_.begin()) return nullptr;
  --it;
  return run <= it->lastRun ? &*it : nullptr;
}

Result<const Payload*> TagSnapshot::payload(const Iov& iov) {
  const auto k = static_cast<std::size_t>(&iov - iovs_.data());
  if (k >= iovs_.size()) return Error{"TagSnapshot::payload: an IOV of another tag"};
  if (!payloads_[k]) {
    // Another IOV with the same payload may have fetched it already.
    for (std::size_t j = 0; j < iovs_.size(); ++j) {
      if (payloads_[j] && iovs_[j].payload == iov.payload) {
        payloads_[k] = std::make_unique<Payload>(*payloads_[j]);
        break;
      }
    }
  }
  if (!payloads_[k]) {
    auto p = db_->payload(iov.payload);  // its hash checked by the database
    if (!p) return p.error();
    payloads_[k] = std::make_unique<Payload>(std::move(*p));
  }
  return payloads_[k].get();
}

Result<std::pair<const Iov*, const Payload*>> TagSnapshot::at(std::int64_t run) {
  const Iov* iov = find(run);
  if (iov == nullptr) {
    return Error{fmt::format("run {}: no IOV of tag '{}' in {} contains it (emcalign conditions list {} --tag {})", run,
                             tag_.name, db_->uri(), db_->uri(), tag_.name)};
  }
  auto p = payload(*iov);
  if (!p) return p.error();
  return std::pair{iov, *p};
}

}  // namespace emcalign::conddb
