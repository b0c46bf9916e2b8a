#include "emcalign/conddb/tag_tables.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/core/utf8.hpp"

namespace emcalign::conddb {

namespace {

using io::Json;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

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

Result<TagDiff> diffTags(Database& db, const std::string& a, const std::string& b) {
  auto sa = TagSnapshot::load(db, a, true);
  if (!sa) return sa.error();
  auto sb = TagSnapshot::load(db, b, true);
  if (!sb) return sb.error();
  TagDiff d{a, b, {}, {}, {}};
  // Runs of one tag the other's IOVs do not cover, as stretches.
  auto uncovered = [](const std::vector<Iov>& mine, TagSnapshot& other) {
    std::vector<std::pair<std::int64_t, std::int64_t>> out;
    for (const Iov& i : mine) {
      std::int64_t run = i.firstRun;
      while (run <= i.lastRun) {
        const Iov* o = other.find(run);
        if (o != nullptr) {
          if (o->lastRun >= i.lastRun) break;
          run = o->lastRun + 1;
          continue;
        }
        // The next IOV of the other tag that starts inside this one, if any.
        std::int64_t next = i.lastRun + 1;
        for (const Iov& x : other.iovs()) {
          if (x.firstRun > run && x.firstRun <= i.lastRun) next = std::min(next, x.firstRun);
        }
        if (!out.empty() && out.back().second + 1 == run) {
          out.back().second = next - 1;
        } else {
          out.emplace_back(run, next - 1);
        }
        run = next;
      }
    }
    return out;
  };
  d.onlyA = uncovered(sa->iovs(), *sb);
  d.onlyB = uncovered(sb->iovs(), *sa);
  for (const Iov& ia : sa->iovs()) {
    for (const Iov& ib : sb->iovs()) {
      const std::int64_t first = std::max(ia.firstRun, ib.firstRun), last = std::min(ia.lastRun, ib.lastRun);
      if (first > last) continue;
      auto pa = sa->payload(ia);
      if (!pa) return pa.error();
      auto pb = sb->payload(ib);
      if (!pb) return pb.error();
      auto va = storedValues(**pa, ia, a);
      if (!va) return va.error();
      auto vb = storedValues(**pb, ib, b);
      if (!vb) return vb.error();
      IovPair pair{first, last, ia, ib, *va, *vb, {}, (*pa)->model(), (*pb)->model()};
      for (std::size_t k = 0; k < kAllQuantities.size(); ++k) {
        const double diff = kAllQuantities[k].difference(pair.valuesA[k].value, pair.valuesB[k].value);
        const double e = std::hypot(pair.valuesA[k].error, pair.valuesB[k].error);
        pair.z.push_back(e > 0.0 ? diff / e : (diff == 0.0 ? 0.0 : kNaN));
      }
      d.pairs.push_back(std::move(pair));
    }
  }
  return d;
}

Json tagDiffJson(const TagDiff& d) {
  Json pairs = Json::array();
  auto iovJson = [](const Iov& i) {
    return Json{{"first_run", i.firstRun}, {"last_run", i.lastRun}, {"payload", i.payload}};
  };
  auto number = [](double v) { return std::isfinite(v) ? Json(v) : Json(); };
  for (const auto& p : d.pairs) {
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
    pairs.push_back({{"first_run", p.firstRun},
                     {"last_run", p.lastRun},
                     {"iov_a", iovJson(p.a)},
                     {"iov_b", iovJson(p.b)},
                     {"same_payload", p.samePayload()},
                     {"model_a", p.modelA},
                     {"model_b", p.modelB},
                     {"parameters", params}});
  }
  auto stretches = [](const auto& v) {
    Json out = Json::array();
    for (const auto& [f, l] : v) out.push_back(Json::array({f, l}));
    return out;
  };
  return {{"tag_a", d.tagA},
          {"tag_b", d.tagB},
          {"pairs", pairs},
          {"only_a", stretches(d.onlyA)},
          {"only_b", stretches(d.onlyB)}};
}

Result<std::string> tagCsv(Database& db, const std::string& tag) {
  auto snapshot = TagSnapshot::load(db, tag, true);
  if (!snapshot) return snapshot.error();
  std::string units_line = "# units:";
  for (Quantity q : kAllQuantities) units_line += fmt::format(" {}={}", q, q.unit());
  // A comment line: a newline in a database's path would start a row (printable() shows it).
  std::string csv =
      fmt::format("# emcalign conditions export: tag {} of {}\n{}\n", printable(tag), printable(db.uri()), units_line);
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
                       l.selectedEvents ? std::to_string(*l.selectedEvents) : std::string(), cell(l.model));
    for (const auto& v : *values) csv += fmt::format(",{},{}", csvNumber(v.value), csvNumber(v.error));
    for (const auto& v : *values) csv += "," + csvNumber(v.statisticalError);
    csv += "\n";
  }
  return csv;
}

}  // namespace emcalign::conddb
