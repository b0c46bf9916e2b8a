#include "emcalign/conddb/tag_tables.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/core/types.hpp"
#include "emcalign/core/utf8.hpp"

namespace emcalign::conddb {

namespace {

using io::Json;

std::string csvNumber(double v) { return std::isfinite(v) ? fmt::format("{:.10g}", v) : std::string(); }

}  // namespace

Result<StoredValues> storedValues(const Payload& payload, const Iov& iov, const std::string& tag) {
  const StoredValues values = payload.values();
  for (Param p : kAllParams) {
    if (!std::isfinite(values[index(p)].value)) {
      return Error{fmt::format("tag {} IOV {}-{}: parameter {} is missing or not a number", tag, iov.firstRun,
                               iov.lastRun, name(p))};
    }
  }
  return values;
}

namespace {

// Runs of `mine` the IOVs of `other` do not cover, as stretches; both sorted, never overlapping
// within themselves: one sweep.
std::vector<std::pair<std::int64_t, std::int64_t>> uncovered(const std::vector<Iov>& mine,
                                                             const std::vector<Iov>& other) {
  std::vector<std::pair<std::int64_t, std::int64_t>> out;
  const auto add = [&](std::int64_t first, std::int64_t last) {
    if (first > last) return;
    if (!out.empty() && out.back().second + 1 == first) {
      out.back().second = last;
    } else {
      out.emplace_back(first, last);
    }
  };
  std::size_t j = 0;
  for (const Iov& i : mine) {
    std::int64_t run = i.firstRun;
    while (j < other.size() && other[j].lastRun < run) ++j;
    for (std::size_t k = j; k < other.size() && other[k].firstRun <= i.lastRun && run <= i.lastRun; ++k) {
      if (other[k].firstRun > run) add(run, other[k].firstRun - 1);
      run = std::max(run, other[k].lastRun + 1);
    }
    if (run <= i.lastRun) add(run, i.lastRun);
  }
  return out;
}

}  // namespace

ModelComparison compareModels(const TagDiff& d) {
  std::vector<calib::ModelIdentity> a, b;
  for (const auto& p : d.pairs) {
    calib::addDistinct(a, p.modelA);
    calib::addDistinct(b, p.modelB);
  }
  const auto words = [](const std::vector<calib::ModelIdentity>& models) {
    std::set<std::string> said;
    for (const auto& m : models) said.insert(m.kind == calib::ModelIdentity::Kind::Unsaid ? "not said" : m.text());
    return fmt::format("{}", fmt::join(said, " | "));
  };
  const auto within = [](const std::vector<calib::ModelIdentity>& x, const std::vector<calib::ModelIdentity>& y) {
    return std::all_of(x.begin(), x.end(), [&](const calib::ModelIdentity& m) {
      return std::any_of(y.begin(), y.end(), [&](const calib::ModelIdentity& k) { return k.sameModel(m); });
    });
  };
  const auto paper = [](const std::vector<calib::ModelIdentity>& x) {
    return std::any_of(x.begin(), x.end(), [](const calib::ModelIdentity& m) { return m.isPaper(); });
  };
  return {words(a), words(b), within(a, b) && within(b, a), paper(a) != paper(b)};
}

Result<TagDiff> diffTags(Database& db, const std::string& a, const std::string& b, const std::string& at) {
  auto sa = TagSnapshot::load(db, a, true, at);
  if (!sa) return sa.error();
  auto sb = TagSnapshot::load(db, b, true, at);
  if (!sb) return sb.error();
  TagDiff d{a, b, {}, {}, {}, {}, {}};
  const std::vector<Iov>& ia = sa->iovs();
  const std::vector<Iov>& ib = sb->iovs();
  for (auto [snapshot, listing] : {std::pair{&*sa, &d.listingA}, std::pair{&*sb, &d.listingB}}) {
    if (Status s = snapshot->fetchAll(); !s) return s.error();
    listing->reserve(snapshot->iovs().size());
    for (const Iov& i : snapshot->iovs()) {
      auto p = snapshot->payload(i);
      if (!p) return p.error();
      listing->push_back(iovListing(i, **p));
    }
  }
  d.onlyA = uncovered(ia, ib);
  d.onlyB = uncovered(ib, ia);
  // The overlapping pairs, in run order: one sweep over both.
  std::size_t j = 0;
  for (const Iov& x : ia) {
    while (j < ib.size() && ib[j].lastRun < x.firstRun) ++j;
    for (std::size_t k = j; k < ib.size() && ib[k].firstRun <= x.lastRun; ++k) {
      const Iov& y = ib[k];
      const std::int64_t first = std::max(x.firstRun, y.firstRun), last = std::min(x.lastRun, y.lastRun);
      if (first > last) continue;
      auto pa = sa->payload(x);
      if (!pa) return pa.error();
      auto pb = sb->payload(y);
      if (!pb) return pb.error();
      auto va = storedValues(**pa, x, a);
      if (!va) return va.error();
      auto vb = storedValues(**pb, y, b);
      if (!vb) return vb.error();
      IovPair pair{first, last, x, y, *va, *vb, {}, (*pa)->modelIdentity(), (*pb)->modelIdentity()};
      for (std::size_t q = 0; q < kAllQuantities.size(); ++q) {
        const double diff = kAllQuantities[q].difference(pair.valuesA[q].value, pair.valuesB[q].value);
        const double e = std::hypot(pair.valuesA[q].error, pair.valuesB[q].error);
        pair.z.push_back(e > 0.0 ? diff / e : (diff == 0.0 ? 0.0 : kNaN));
      }
      d.pairs.push_back(std::move(pair));
    }
  }
  return d;
}

namespace {

Json pairJson(const IovPair& p) {
  auto iovJson = [](const Iov& i) {
    return Json{{"first_run", i.firstRun}, {"last_run", i.lastRun}, {"payload", i.payload}};
  };
  auto number = [](double v) { return std::isfinite(v) ? Json(v) : Json(); };
  Json params = Json::object();
  for (std::size_t k = 0; k < kAllQuantities.size(); ++k) {
    const Quantity q = kAllQuantities[k];
    params[std::string(q.name())] = {{"a", number(p.valuesA[k].value)},
                                     {"error_a", number(p.valuesA[k].error)},
                                     {"b", number(p.valuesB[k].value)},
                                     {"error_b", number(p.valuesB[k].error)},
                                     {"difference", number(q.difference(p.valuesA[k].value, p.valuesB[k].value))},
                                     {"z", number(p.z[k])},
                                     {"unit", q.unit()}};
  }
  return {{"first_run", p.firstRun},         {"last_run", p.lastRun},
          {"iov_a", iovJson(p.a)},           {"iov_b", iovJson(p.b)},
          {"same_payload", p.samePayload()}, {"model_a", p.modelA.text()},
          {"model_b", p.modelB.text()},      {"parameters", params}};
}

Json stretchesJson(const std::vector<std::pair<std::int64_t, std::int64_t>>& v) {
  Json out = Json::array();
  for (const auto& [f, l] : v) out.push_back(Json::array({f, l}));
  return out;
}

// A value as dump(2) writes it nested `depth` levels deep.
std::string nested(const Json& v, int depth) {
  const std::string text = v.dump(2);
  const std::string pad(static_cast<std::size_t>(2 * depth), ' ');
  std::string out;
  out.reserve(text.size() + text.size() / 4);
  std::size_t from = 0;
  for (std::size_t nl = text.find('\n'); nl != std::string::npos; nl = text.find('\n', from)) {
    out.append(text, from, nl + 1 - from);
    out += pad;
    from = nl + 1;
  }
  out.append(text, from, std::string::npos);
  return out;
}

}  // namespace

Json tagDiffJson(const TagDiff& d) {
  Json pairs = Json::array();
  for (const auto& p : d.pairs) pairs.push_back(pairJson(p));
  return {{"tag_a", d.tagA},
          {"tag_b", d.tagB},
          {"pairs", pairs},
          {"only_a", stretchesJson(d.onlyA)},
          {"only_b", stretchesJson(d.onlyB)}};
}

void writeTagDiffJson(const TagDiff& d, const std::function<void(std::string_view)>& out) {
  out(fmt::format("{{\n  \"tag_a\": {},\n  \"tag_b\": {},\n  \"pairs\": ", Json(d.tagA).dump(), Json(d.tagB).dump()));
  if (d.pairs.empty()) {
    out("[]");
  } else {
    out("[\n");
    // The pairs' text made on every core, a block at a time, written in order.
    constexpr std::size_t kBlock = 1024;
    std::vector<std::string> texts;
    for (std::size_t begin = 0; begin < d.pairs.size(); begin += kBlock) {
      const std::size_t end = std::min(d.pairs.size(), begin + kBlock);
      texts.assign(end - begin, {});
      tbb::parallel_for(tbb::blocked_range<std::size_t>(begin, end), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
          texts[k - begin] = "    " + nested(pairJson(d.pairs[k]), 2) + (k + 1 < d.pairs.size() ? ",\n" : "\n");
        }
      });
      for (const std::string& t : texts) out(t);
    }
    out("  ]");
  }
  out(fmt::format(",\n  \"only_a\": {},\n  \"only_b\": {}\n}}", nested(stretchesJson(d.onlyA), 1),
                  nested(stretchesJson(d.onlyB), 1)));
}

Result<std::string> tagCsv(Database& db, const std::string& tag, const std::string& at) {
  auto snapshot = TagSnapshot::load(db, tag, true, at);
  if (!snapshot) return snapshot.error();
  if (Status s = snapshot->fetchAll(); !s) return s.error();
  std::string units_line = "# units:";
  for (Quantity q : kAllQuantities) units_line += fmt::format(" {}={}", q, q.unit());
  // A comment line: a newline in a database's path would start a row (printable() shows it).
  std::string csv = fmt::format("# emcalign conditions export: tag {} of {}{}\n{}\n", printable(tag),
                                printable(db.uri()), at.empty() ? std::string() : " as it was at " + at, units_line);
  csv +=
      "first_run,last_run,payload,inserted,status,chi2,ndf,chi2_statistical_errors,sigma_sys_method,sigma_sys_deg,"
      "selected_events,model";
  for (Quantity q : kAllQuantities) csv += fmt::format(",{},{}_error", q, q);
  // The fits' statistical errors (σ_sys left out), where the payloads record them: last, so
  // that the columns before keep their places.
  for (Quantity q : kAllQuantities) csv += fmt::format(",{}_statistical_error", q);
  csv += "\n";
  for (const Iov& iov : snapshot->iovs()) {
    auto p = snapshot->payload(iov);
    if (!p) return p.error();
    auto values = storedValues(**p, iov, tag);
    if (!values) return values.error();
    const IovListing l = iovListing(iov, **p);
    // Free text of a payload (its status, σ_sys method, the model's path) is kept out of the
    // CSV's structure.
    const auto cell = [](const std::string& text) {
      return text.find_first_of(",\"\n\r") == std::string::npos ? text : std::string("?");
    };
    const auto number = [](const auto& v) { return v ? csvNumber(static_cast<double>(*v)) : std::string(); };
    csv += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{}", iov.firstRun, iov.lastRun, iov.payload, iov.inserted,
                       cell(l.status.value_or("")), number(l.chi2), number(l.ndf), number(l.chi2Statistical),
                       cell(l.sigmaSysMethod.value_or("")), number(l.sigmaSysDeg),
                       l.selectedEvents ? std::to_string(*l.selectedEvents) : std::string(), cell(l.model.text()));
    for (const auto& v : *values) csv += fmt::format(",{},{}", csvNumber(v.value), csvNumber(v.error));
    for (const auto& v : *values) {
      csv.push_back(',');
      csv.append(csvNumber(v.statisticalError));
    }
    csv += "\n";
  }
  return csv;
}

}  // namespace emcalign::conddb
