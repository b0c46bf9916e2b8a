#include <algorithm>
#include <map>

#include <fmt/format.h>

#include "emcalign/conddb/conditions.hpp"

namespace emcalign::conddb {

Error missingTag(Database& db, const std::string& tag, const std::string& at) {
  if (!at.empty()) {
    if (auto now = db.tag(tag); now && now->has_value()) {
      return Error{fmt::format("{}: tag '{}' did not exist at {} (created {})", db.uri(), tag, at, (*now)->created)};
    }
  }
  return Error{fmt::format("{}: no tag '{}' (the tags: emcalign conditions list {})", db.uri(), tag, db.uri())};
}

Result<TagSnapshot> TagSnapshot::load(Database& db, const std::string& tag, bool allowInvalid,
                                      const std::string& atText) {
  auto snapshot = snapshotForm(atText);  // the text recorded
  if (!snapshot) return snapshot.error();
  const std::string& at = *snapshot;
  if (!allowInvalid) {
    // Invalid now: never served, whatever the snapshot.
    auto now = db.tag(tag);
    if (!now) return now.error();
    if (now->has_value() && (*now)->state == TagState::Invalid) {
      const Tag& x = **now;
      return Error{fmt::format("{}: tag '{}' is invalid (since {}{}): it is kept and listed, but never served",
                               db.uri(), tag, x.stateChanged.empty() ? std::string("its creation") : x.stateChanged,
                               x.reason.empty() ? std::string() : ": " + x.reason)};
    }
  }
  auto t = db.tag(tag, at);
  if (!t) return t.error();
  if (!t->has_value()) return missingTag(db, tag, at);
  auto iovs = db.iovs(tag, at);
  if (!iovs) return iovs.error();
  TagSnapshot s;
  s.db_ = &db;
  s.at_ = at;
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
    auto& shared = byHash_[iov.payload];  // another IOV with the same payload may have fetched it
    if (!shared) {
      auto p = db_->payload(iov.payload);  // its hash checked by the database
      if (!p) {
        byHash_.erase(iov.payload);
        return p.error();
      }
      shared = std::make_shared<const Payload>(std::move(*p));
    }
    payloads_[k] = shared;
  }
  return payloads_[k].get();
}

Status TagSnapshot::fetchAll() {
  auto all = db_->payloadsOf(tag_.name);
  if (!all) return all.error();
  for (auto& [hash, p] : *all) byHash_.try_emplace(hash, std::move(p));
  return {};
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
