// `conditions list` and `diff` in words, a run range, a copy between databases
// (conddb/tag_text.hpp).

#include "emcalign/conddb/tag_text.hpp"

#include <charconv>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/conddb/address.hpp"
#include "emcalign/conddb/database_to_write.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/utf8.hpp"

namespace emcalign::conddb {

namespace {

constexpr const char* kTagsRow = "{:<24} {:<9} {:>6} {:>17}  {:<28} {:<22} {}\n";
constexpr const char* kIovsRow = "{:>10} {:>10} {:>9} {:>12} {:>12} {:<12} {:<12} {}\n";

std::string iovRow(const IovListing& i) {
  const auto ratio = [&](const std::optional<double>& chi2) {
    return chi2 && std::isfinite(*chi2) && i.ndf ? fmt::format("{:.1f}/{}", *chi2, *i.ndf) : std::string("-");
  };
  // sigma_sys auto makes chi2/ndf 1: the chi2 with the statistical errors alone beside it.
  const std::string events = i.selectedEvents ? std::to_string(*i.selectedEvents) : "-";
  const std::string status = i.status ? printable(*i.status) : "-";
  return fmt::format(fmt::runtime(kIovsRow), i.iov.firstRun, i.iov.lastRun, events, ratio(i.chi2),
                     ratio(i.chi2Statistical), status, i.iov.payload.substr(0, 12), i.iov.inserted);
}

// The models the two tags were fitted with: differences that are the models', not the detector's.
std::string modelsOfDiff(const TagDiff& d) {
  const ModelComparison models = compareModels(d);
  // σ_sys sets the errors the pulls are in units of: said beside the models.
  const std::string sigmaA = sigmaSysSummary(d.listingA), sigmaB = sigmaSysSummary(d.listingB);
  std::string out = fmt::format("models: tag {}: {}, sigma_sys {}; tag {}: {}, sigma_sys {}\n", d.tagA,
                                printable(models.a), sigmaA, d.tagB, printable(models.b), sigmaB);
  if (!models.same) {
    out += fmt::format("  the models differ: {}\n",
                       models.paperOnOneSide
                           ? "differences common to every IOV (the gaps dp1-dp3, dx_rel, the shifts' scale) are the "
                             "paper's model's against the corrections' (docs/validation.md), not the detector's"
                           : "differences common to every IOV are the models', not the detector's");
  }
  if (sigmaA != sigmaB) {
    out += "  sigma_sys differs: the errors, and the pulls in their units, are not alike in the two tags\n";
  }
  return out;
}

}  // namespace

std::string tagsText(const std::vector<TagListing>& tags, const std::string& uri, const std::string& at) {
  std::string out = at.empty() ? std::string() : fmt::format("{}: as it was at {}\n", uri, at);
  out += fmt::format(fmt::runtime(kTagsRow), "tag", "state", "IOVs", "runs", "model", "sigma_sys", "description");
  for (const auto& t : tags) {
    const auto& iovs = t.iovs;
    const std::string runs =
        iovs.empty() ? "-" : fmt::format("{}-{}", iovs.front().iov.firstRun, iovs.back().iov.lastRun);
    out += fmt::format(fmt::runtime(kTagsRow), t.tag.name, name(t.tag.state), iovs.size(), runs, modelSummary(iovs),
                       sigmaSysSummary(iovs), t.tag.description);
  }
  return out;
}

std::string tagText(const TagListing& t, const std::string& at) {
  std::string out = fmt::format("tag {} ({}), created {}{}{}\n", t.tag.name, name(t.tag.state), t.tag.created,
                                t.tag.description.empty() ? "" : ": " + t.tag.description,
                                at.empty() ? std::string() : ", as it was at " + at);
  if (!t.tag.stateChanged.empty()) {
    out += fmt::format("{} since {}{}\n", name(t.tag.state), t.tag.stateChanged,
                       t.tag.reason.empty() ? std::string() : ": " + t.tag.reason);
  }
  out += fmt::format("model: {}; sigma_sys: {}\n", modelSummary(t.iovs, false), sigmaSysSummary(t.iovs));
  out += fmt::format(fmt::runtime(kIovsRow), "first_run", "last_run", "events", "chi2/ndf", "stat. only", "status",
                     "payload", "inserted");
  for (const auto& i : t.iovs) out += iovRow(i);
  return out;
}

std::string tagDiffText(const TagDiff& d, const std::string& uri, const std::string& at) {
  std::string out =
      fmt::format("{}: tag {} against tag {}{}, (a - b) / sqrt(error_a^2 + error_b^2) of each parameter\n", uri, d.tagA,
                  d.tagB, at.empty() ? std::string() : " as they were at " + at);
  if (!d.pairs.empty()) out += modelsOfDiff(d);
  out += fmt::format("{:>17}", "runs");
  for (Quantity q : kAllQuantities) out += fmt::format(" {:>8} ", q);  // the last column of a cell: its mark
  out += "\n";
  int beyond3 = 0;
  for (const auto& p : d.pairs) {
    out += fmt::format("{:>17}", fmt::format("{}-{}", p.firstRun, p.lastRun));
    if (p.samePayload()) {
      out += "  the same payload\n";
      continue;
    }
    for (double z : p.z) {
      // Two decimals cut toward zero, so that a cell reads 3.00 or more exactly when it is
      // counted (rounded, -2.996 would read -3.00); the counted cells are marked too.
      const bool counted3 = std::isfinite(z) && std::abs(z) >= 3.0;
      out +=
          fmt::format(" {:>8}{}", std::isfinite(z) ? fixed(std::trunc(z * 100.0) / 100.0, 2, true) : std::string("-"),
                      counted3 ? "*" : " ");
      beyond3 += counted3 ? 1 : 0;
    }
    out += "\n";
  }
  for (const auto& [f, l] : d.onlyA) out += fmt::format("runs {}-{}: only in tag {}\n", f, l, d.tagA);
  for (const auto& [f, l] : d.onlyB) out += fmt::format("runs {}-{}: only in tag {}\n", f, l, d.tagB);
  out += fmt::format(
      "{}, {} of 3 sigma or more (marked *; the errors of one fit each, not independent when the tags fitted the "
      "same events)\n",
      counted(d.pairs.size(), "IOV pair"), counted(beyond3, "difference"));
  return out;
}

Result<std::pair<std::int64_t, std::int64_t>> parseRunRange(const std::string& text) {
  const auto number = [](std::string_view s, std::int64_t& out) {
    if (s.empty()) return false;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
    return ec == std::errc() && p == s.data() + s.size() && out >= 0;
  };
  std::int64_t first = 0, last = 0;
  const auto dash = text.find('-');
  const bool ok = dash == std::string::npos ? number(text, first) && (last = first, true)
                                            : number(std::string_view(text).substr(0, dash), first) &&
                                                  number(std::string_view(text).substr(dash + 1), last);
  if (!ok) return Error{fmt::format("--runs '{}': expected FIRST-LAST (runs are integers >= 0), e.g. 1-40", text)};
  if (first > last) return Error{fmt::format("--runs '{}': the first run is after the last", text)};
  return std::pair{first, last};
}

namespace {

bool sameSqliteFile(const std::string& a, const std::string& b) {
  auto x = DatabaseAddress::parse(a);
  auto y = DatabaseAddress::parse(b);
  if (!x || !y || x->kind != DatabaseAddress::Kind::Sqlite || y->kind != DatabaseAddress::Kind::Sqlite) return false;
  std::error_code ec;
  return std::filesystem::equivalent(x->file, y->file, ec) && !ec;
}

}  // namespace

Result<TagCopy> copyTagBetween(const std::string& fromUri, const std::string& tag, const std::string& toUri,
                               const std::string& as, const std::string& at) {
  auto from = Database::open(fromUri);
  if (!from) return from.error();
  if (auto t = TagSnapshot::load(**from, tag, false, at); !t) return t.error();
  DatabaseToWrite target(sameSqliteFile(fromUri, toUri) ? fromUri : toUri);
  if (Status s = target.prepare(); !s) return s.error();
  auto to = target.create();
  if (!to) return to.error();
  auto copied = copyTag(**from, tag, **to, as.empty() ? tag : as, at);
  if (!copied) return copied.error();
  return TagCopy{*copied, (*from)->uri(), (*to)->uri()};
}

}  // namespace emcalign::conddb
