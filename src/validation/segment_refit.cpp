#include "emcalign/validation/segment_refit.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/core/text.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/statistics.hpp"
#include "emcalign/core/units.hpp"

namespace emcalign::validation {

using io::Json;

namespace {

// The value and error of every series (the 12 parameters, then β, ψ, μ, τ, dx_rel) of a fit,
// in file units, in the order of seriesOfTag.
std::vector<std::pair<double, double>> valuesOf(const calib::FitResult& r) {
  std::vector<std::pair<double, double>> out;
  for (Param p : kAllParams) {
    const double unit = geometry::AlignmentParameters::fileUnit(p);
    out.emplace_back(r.parameters[p] / unit, r.errors[p] / unit);
  }
  for (Physical p : kDerivedParams) {
    const double unit = geometry::PhysicalParameters::fileUnit(p);
    out.emplace_back(r.derived[p].value / unit, r.derived[p].error / unit);
  }
  return out;
}

// The statistical errors alone: the fit of the same profile with σ_sys = 0.
Result<std::vector<std::pair<double, double>>> statisticalFit(const calib::ProfileFill& fill,
                                                              const CampaignModel& model, std::int64_t first,
                                                              std::int64_t last) {
  auto r = calib::fitProfiles(fill.profiles.bins(0.0), model.geometry);
  if (!r) return Error{fmt::format("runs {}-{}, statistical errors alone: {}", first, last, r.error().message)};
  return valuesOf(*r);
}

// The statistical errors of a fit: those it records, else (a fit of a saved profile) the fit of
// the same profile with σ_sys = 0.
Result<std::vector<std::pair<double, double>>> statisticalErrorsOf(const calib::FitResult& r,
                                                                   const calib::ProfileFill& fill,
                                                                   const CampaignModel& model, std::int64_t first,
                                                                   std::int64_t last) {
  if (!r.statisticalCovariance) return statisticalFit(fill, model, first, last);
  std::vector<std::pair<double, double>> out;
  for (Param p : kAllParams) {
    const double unit = geometry::AlignmentParameters::fileUnit(p);
    out.emplace_back(r.parameters[p] / unit, r.statisticalErrors[p] / unit);
  }
  for (Physical p : kDerivedParams) {
    const double unit = geometry::PhysicalParameters::fileUnit(p);
    out.emplace_back(r.derived[p].value / unit, r.derived[p].statisticalError / unit);
  }
  return out;
}

std::string number(double v, int digits) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, digits) : std::string("—");
}

std::string ratio(double a, double b) {
  return std::isfinite(a) && std::isfinite(b) && b > 0.0 ? fmt::format("×{:.1f}", a / b) : std::string("—");
}

int digitsOf(Quantity q) { return q.dimension() == Dimension::Length ? 4 : 3; }

double rms(const std::vector<double>& v) {
  double ss = 0.0;
  int n = 0;
  for (double d : v) {
    if (std::isfinite(d)) {
      ss += d * d;
      ++n;
    }
  }
  return n > 0 ? std::sqrt(ss / n) : RefitPrecision::kNaN;
}

// The precision of one series before (the replaced IOVs) and after (the refit). `statBefore`:
// the IOVs' statistical errors, where the series does not weigh them by those already.
RefitPrecision precisionOf(const TrendSeries& series, std::int64_t first, std::int64_t last,
                           std::pair<double, double> after, double statAfter, std::vector<double> statBefore,
                           const PeriodTruth* truth) {
  RefitPrecision p{series.parameter};
  p.value = after.first;
  p.quotedAfter = after.second;
  p.statAfter = statAfter;
  std::vector<double> values, errors, quoted, offTruth;
  for (const TrendPoint& pt : series.points) {
    if (pt.firstRun < first || pt.lastRun > last) continue;
    values.push_back(pt.value);
    errors.push_back(pt.error);
    quoted.push_back(std::isfinite(pt.quotedError) ? pt.quotedError : pt.error);
    if (truth != nullptr)
      offTruth.push_back(p.parameter.difference(pt.value, truth->mean(p.parameter, pt.firstRun, pt.lastRun)));
  }
  p.quotedBefore = median(quoted);
  p.statBefore = series.statistical ? median(errors) : median(std::move(statBefore));
  if (values.size() >= 2) {
    double mean = 0.0, ss = 0.0;
    for (double v : values) mean += v / static_cast<double>(values.size());
    for (double v : values) ss += (v - mean) * (v - mean);
    p.scatter = std::sqrt(ss / static_cast<double>(values.size() - 1));
    double w = 0.0, wy = 0.0;
    for (std::size_t k = 0; k < values.size(); ++k) {
      w += 1.0 / (errors[k] * errors[k]);
      wy += values[k] / (errors[k] * errors[k]);
    }
    p.chi2 = 0.0;
    for (std::size_t k = 0; k < values.size(); ++k) p.chi2 += std::pow((values[k] - wy / w) / errors[k], 2);
    p.ndf = static_cast<int>(values.size()) - 1;
    p.scatterOverError = std::sqrt(p.chi2 / p.ndf);
  }
  if (truth != nullptr) {
    p.truth = truth->mean(p.parameter, first, last);
    p.truthRmsBefore = rms(offTruth);
  }
  return p;
}

// What every period's refit reads: the tag and its series, the events, the campaign's model.
struct RefitInputs {
  const std::vector<TrendSeries>& series;
  conddb::TagSnapshot& tag;
  const CampaignScan& scan;
  const CampaignModel& model;
  std::map<std::string, std::string> digests;  ///< SHA-256 of each file scanned
  const PeriodTruth* truth;                    ///< may be null
  std::size_t periods;                         ///< the trend's, stable or not
};

// Stable period `k` refitted from all its events, beside the IOVs it replaces.
Result<RefittedSegment> refitPeriod(const RefitInputs& in, const TrendSegment& seg, std::size_t k) {
  RefittedSegment rs;
  rs.firstRun = seg.firstRun;
  rs.lastRun = seg.lastRun;
  rs.begin = seg.begin;
  rs.end = seg.end;
  CampaignGroup g;
  g.index = static_cast<int>(k);
  g.iovFirst = seg.firstRun;
  g.iovLast = seg.lastRun;
  // A period spans several beam energies: each run was filled at its own energy's depth, and
  // the period is fitted with the corrections at its events' mean energy (a grid's).
  auto periodModel = in.model.at(in.scan.meanBeamEnergy(seg.firstRun, seg.lastRun));
  if (!periodModel)
    return Error{fmt::format("--refit: runs {}-{}: {}", seg.firstRun, seg.lastRun, periodModel.error().message)};
  calib::ProfileFill fill = in.scan.fillOf(seg.firstRun, seg.lastRun, periodModel->profile, &g.runs);
  if (g.runs.empty()) {
    return Error{fmt::format("--refit: no events of runs {}-{} in the files given", seg.firstRun, seg.lastRun)};
  }
  g.files = in.scan.filesOf(seg.firstRun, seg.lastRun);
  g.beamEnergy = std::numeric_limits<double>::quiet_NaN();  // a period spans several energies
  g.selected = fill.cutFlow.events.back();
  const Json origin = {{"refit",
                        {{"tag", in.tag.tag().name},
                         {"period", k},
                         {"periods", in.periods},
                         {"replaces_iovs", seg.end - seg.begin},
                         {"runs", g.runs}}}};
  auto fit = fitGroup(g, fill, *periodModel, in.digests, origin);
  if (!fit) return Error{fmt::format("--refit: {}", fit.error().message)};
  if (!usable(fit->result.status)) {
    return Error{fmt::format("--refit: runs {}-{}: the fit's status is '{}'", seg.firstRun, seg.lastRun,
                             name(fit->result.status))};
  }
  auto statAfter = statisticalErrorsOf(fit->result, fill, *periodModel, seg.firstRun, seg.lastRun);
  if (!statAfter) return Error{fmt::format("--refit: {}", statAfter.error().message)};
  rs.selected = g.selected;

  // The replaced IOVs: their events and (where the payloads do not record them) statistical errors.
  const bool recorded = std::all_of(in.series.begin(), in.series.end(),
                                    [](const TrendSeries& s) { return s.statistical || s.points.empty(); });
  std::vector<double> selectedBefore;
  std::vector<std::vector<double>> statBefore(in.series.size());
  for (std::size_t i = seg.begin; i < seg.end; ++i) {
    const conddb::Iov& iov = in.tag.iovs()[i];
    const double energy = in.scan.meanBeamEnergy(iov.firstRun, iov.lastRun);
    if (std::isnan(energy)) {  // no selected event
      selectedBefore.push_back(0.0);
      continue;
    }
    auto iovModel = in.model.at(energy);
    if (!iovModel)
      return Error{fmt::format("--refit: runs {}-{}: {}", iov.firstRun, iov.lastRun, iovModel.error().message)};
    const calib::ProfileFill f = in.scan.fillOf(iov.firstRun, iov.lastRun, iovModel->profile);
    selectedBefore.push_back(static_cast<double>(f.cutFlow.events.back()));
    if (recorded) continue;
    auto st = statisticalFit(f, *iovModel, iov.firstRun, iov.lastRun);
    if (!st) continue;  // a group too poor for a fit without σ_sys counts as missing
    for (std::size_t s = 0; s < in.series.size() && s < st->size(); ++s) statBefore[s].push_back((*st)[s].second);
  }
  rs.medianSelectedBefore = static_cast<std::int64_t>(std::llround(median(selectedBefore)));
  const auto after = valuesOf(fit->result);
  for (std::size_t s = 0; s < in.series.size(); ++s) {
    const auto value = s < after.size() ? after[s] : std::pair{RefitPrecision::kNaN, RefitPrecision::kNaN};
    const double stat = s < statAfter->size() ? (*statAfter)[s].second : RefitPrecision::kNaN;
    rs.precision.push_back(precisionOf(in.series[s], seg.firstRun, seg.lastRun, value, stat, statBefore[s], in.truth));
  }
  rs.fit = std::move(*fit);
  return rs;
}

}  // namespace

Result<std::optional<std::string>> recordedCorrections(conddb::TagSnapshot& tag) {
  std::optional<std::pair<std::string, std::string>> named;  // (file, SHA-256)
  for (const conddb::Iov& iov : tag.iovs()) {
    auto p = tag.payload(iov);
    if (!p) return p.error();
    const std::pair<std::string, std::string> these{(*p)->correctionsFile(), (*p)->correctionsSha256()};
    if (!named) {
      named = these;
    } else if (these != *named) {
      return Error{fmt::format(
          "tag {}: its IOVs were fitted with different corrections ({} and, from runs {}-{}, {}): give --corrections",
          tag.tag().name, named->first.empty() ? "none" : named->first, iov.firstRun, iov.lastRun,
          these.first.empty() ? "none" : these.first)};
    }
  }
  if (!named || named->first.empty()) return std::optional<std::string>{};
  const auto& [file, sha] = *named;
  auto grid = calib::CorrectionsGrid::read(file);
  if (!grid) {
    return Error{
        fmt::format("tag {} was fitted with the corrections {}, which cannot be read now ({}): give --corrections, the "
                    "campaign's own",
                    tag.tag().name, file, grid.error().message)};
  }
  if (!sha.empty() && grid->sha256() != sha) {
    return Error{
        fmt::format("tag {} was fitted with the corrections {} (SHA-256 {}…), which have changed since (now {}…): give "
                    "--corrections, the campaign's own",
                    tag.tag().name, file, sha.substr(0, 12), grid->sha256().substr(0, 12))};
  }
  return std::optional<std::string>{file};
}

Status adoptTagSettings(conddb::TagSnapshot& tag, CampaignModel& model) {
  const std::string& name = tag.tag().name;
  std::optional<calib::SigmaSysChoice> sigmaSys;
  for (const conddb::Iov& iov : tag.iovs()) {
    auto p = tag.payload(iov);
    if (!p) return p.error();
    auto choice = (*p)->sigmaSysChoice();
    if (!choice) {
      return Error{fmt::format("tag {}: the calibration of runs {}-{} has {}", name, iov.firstRun, iov.lastRun,
                               choice.error().message)};
    }
    if (!sigmaSys) {
      sigmaSys = *choice;
      model.setSigmaSys(*choice);
    } else if (!calib::sameChoice(*sigmaSys, *choice)) {
      return Error{
          fmt::format("tag {}: its IOVs were fitted with different sigma_sys ({} and {}): no "
                      "refit comparable with all of them",
                      name, calib::sigmaSysChoiceJson(*sigmaSys).dump(), calib::sigmaSysChoiceJson(*choice).dump())};
    }
    const std::string used = (*p)->correctionsFile(), usedSha = (*p)->correctionsSha256();
    const bool same = usedSha.empty() ? used == model.corrections : usedSha == model.correctionsSha256;
    if (!same && used == model.corrections && !usedSha.empty()) {  // the same path, other contents
      return Error{fmt::format(
          "--refit with {}: the calibration of runs {}-{} in tag {} was made with the corrections at this path as "
          "they were then (SHA-256 {}…); they have changed since (now {}…): give the corrections the campaign used",
          model.corrections, iov.firstRun, iov.lastRun, name, usedSha.substr(0, 12),
          model.correctionsSha256.substr(0, 12))};
    }
    if (!same) {
      auto what = [](const std::string& c) { return c.empty() ? std::string("without corrections") : "with " + c; };
      return Error{
          fmt::format("--refit {}: the calibration of runs {}-{} in tag {} was made {} (give the "
                      "same --corrections, for a refit comparable with them)",
                      what(model.corrections), iov.firstRun, iov.lastRun, name, what(used))};
    }
  }
  return {};
}

Result<std::vector<std::string>> checkRefitData(conddb::TagSnapshot& tag, const CampaignScan& scan) {
  std::vector<std::string> warnings;
  std::map<std::string, std::string> recorded;  // SHA-256 → the file's name and IOV when recorded
  for (const conddb::Iov& iov : tag.iovs()) {
    auto p = tag.payload(iov);
    if (!p) return p.error();
    const auto digests = (*p)->inputDigests();
    if (digests.empty()) {
      warnings.push_back(
          fmt::format("tag {}: the calibration of runs {}-{} records no digests of its data: the refit "
                      "cannot check it reads the same events",
                      tag.tag().name, iov.firstRun, iov.lastRun));
      continue;
    }
    for (const auto& [file, sha] : digests) {
      recorded.emplace(sha, fmt::format("{} (runs {}-{})", file, iov.firstRun, iov.lastRun));
    }
  }
  if (recorded.empty()) return warnings;
  std::set<std::string> given;
  for (std::size_t k = 0; k < scan.files.size() && k < scan.digests.size(); ++k) {
    given.insert(scan.digests[k]);
    if (!recorded.contains(scan.digests[k])) {
      return Error{
          fmt::format("--refit: {} is not one of the files tag {} was made from (another period's file, or "
                      "a file changed since?): a refit reads the tag's own data",
                      scan.files[k], tag.tag().name)};
    }
  }
  for (const auto& [sha, where] : recorded) {
    if (!given.contains(sha)) {
      return Error{
          fmt::format("--refit: the data lack {} (SHA-256 {}…), which tag {} was made from: a refit reads "
                      "all of the tag's data",
                      where, sha.substr(0, 12), tag.tag().name)};
    }
  }
  return warnings;
}

Result<SegmentRefit> refitSegments(const Trend& trend, const std::vector<TrendSeries>& series, conddb::TagSnapshot& tag,
                                   const CampaignScan& scan, const CampaignModel& model, const PeriodTruth* truth) {
  RefitInputs in{.series = series,
                 .tag = tag,
                 .scan = scan,
                 .model = model,
                 .digests = {},
                 .truth = truth,
                 .periods = trend.segments.size()};
  for (std::size_t k = 0; k < scan.files.size() && k < scan.digests.size(); ++k)
    in.digests[scan.files[k]] = scan.digests[k];
  SegmentRefit out;
  for (std::size_t k = 0; k < trend.segments.size(); ++k) {
    const TrendSegment& seg = trend.segments[k];
    if (!seg.refittable()) {
      // Kept as they were.
      RefittedSegment rs;
      rs.firstRun = seg.firstRun;
      rs.lastRun = seg.lastRun;
      rs.begin = seg.begin;
      rs.end = seg.end;
      rs.kept = true;
      rs.drifting = seg.drifting;
      rs.undecided = seg.undecided;
      rs.inconsistent = seg.inconsistent;
      rs.scattering = seg.scattering;
      rs.transition = seg.transition;
      for (std::size_t i = seg.begin; i < seg.end; ++i) {
        auto p = tag.payload(tag.iovs()[i]);
        if (!p) return p.error();
        out.iovs.push_back({tag.iovs()[i].firstRun, tag.iovs()[i].lastRun, **p});
      }
      out.segments.push_back(std::move(rs));
      continue;
    }
    auto rs = refitPeriod(in, seg, k);
    if (!rs) return rs.error();
    out.iovs.push_back({seg.firstRun, seg.lastRun, rs->fit->payload});
    out.segments.push_back(std::move(*rs));
  }
  return out;
}

std::string keptBecause(const RefittedSegment& s) {
  std::vector<std::string> why;
  if (s.transition) why.emplace_back("it straddles a step");
  if (!s.drifting.empty()) why.push_back(fmt::format("drifting: {}", fmt::join(s.drifting, ", ")));
  if (!s.undecided.empty()) why.push_back(fmt::format("a step or a drift: {}", fmt::join(s.undecided, ", ")));
  if (!s.inconsistent.empty()) why.push_back(fmt::format("inconsistent: {}", fmt::join(s.inconsistent, ", ")));
  for (const auto& sc : s.scattering) {
    why.push_back(fmt::format("{} scatters {:.1f} times its {} errors", sc.parameter, sc.ratio(),
                              sc.statistical ? "statistical" : "measured"));
  }
  return fmt::format("{}", fmt::join(why, "; "));
}

Json refitJson(const SegmentRefit& r, std::size_t iovsBefore) {
  Json segments = Json::array();
  for (const RefittedSegment& s : r.segments) {
    Json j = {{"first_run", s.firstRun}, {"last_run", s.lastRun}, {"replaces_iovs", s.end - s.begin}};
    if (s.kept) {
      j["kept"] = true;
      j["drifting"] = s.drifting;
      j["undecided"] = s.undecided;
      j["inconsistent"] = s.inconsistent;
      Json scattering = Json::array();
      for (const auto& sc : s.scattering) scattering.push_back(sc.parameter);
      j["scattering"] = scattering;
      j["transition"] = s.transition;
      j["why"] = keptBecause(s);
      segments.push_back(j);
      continue;
    }
    j["kept"] = false;
    j["selected_events"] = s.selected;
    j["median_selected_events_before"] = s.medianSelectedBefore;
    j["parameters"] = s.fit->resultJson["parameters"];
    j["errors"] = s.fit->resultJson["errors"];
    if (s.fit->resultJson.contains("systematic_errors"))
      j["systematic_errors"] = s.fit->resultJson["systematic_errors"];
    j["status"] = s.fit->resultJson["status"];
    Json precision = Json::object();
    for (const RefitPrecision& p : s.precision) {
      Json q = {{"value", io::numberOrNull(p.value)},
                {"unit", p.parameter.unit()},
                {"quoted_error_before", io::numberOrNull(p.quotedBefore)},
                {"quoted_error_after", io::numberOrNull(p.quotedAfter)},
                {"statistical_error_before", io::numberOrNull(p.statBefore)},
                {"statistical_error_after", io::numberOrNull(p.statAfter)},
                {"scatter_before", io::numberOrNull(p.scatter)},
                {"scatter_over_error_before", io::numberOrNull(p.scatterOverError)}};
      if (std::isfinite(p.truth)) {
        q["truth"] = p.truth;
        q["refit_minus_truth"] = io::numberOrNull(p.parameter.difference(p.value, p.truth));
        q["rms_before_minus_truth"] = io::numberOrNull(p.truthRmsBefore);
      }
      precision[std::string(p.parameter.name())] = q;
    }
    j["precision"] = precision;
    segments.push_back(j);
  }
  return {{"iovs", r.iovs.size()}, {"iovs_before", iovsBefore}, {"segments", segments}};
}

std::string refitMarkdown(const SegmentRefit& r, std::size_t iovsBefore, const std::string& tagOut) {
  std::string md = fmt::format(
      "\n## Refit: one calibration per stable period\n\n"
      "Tag {}: {} instead of {}. Each stable period is fitted from all its events; a period whose IOVs do not "
      "agree within their errors keeps them (a drift, a step or drift its IOVs cannot tell apart, a stretch its "
      "model does not fit, IOVs scattering beyond their statistical errors), and so does an IOV straddling a "
      "step.\n\n"
      "The precision gained, three ways. *Quoted*: the fit's errors, which carry σ_sys = 0.2° per profile bin "
      "(docs/fit.md); σ_sys does not shrink with events and already dominates a group of ~50 000, so the quoted "
      "error barely moves. *Statistical*: the part the events make, which shrinks as 1/√N (the fits' own "
      "statistical errors; the same fits with σ_sys = 0 for payloads that do not record them). *Observed*: the "
      "RMS of the replaced IOVs about their mean, what they really scatter by, and that scatter over their "
      "statistical errors (√(χ²/ndf) about their weighted mean: about 1 where one value describes them)",
      tagOut, counted(r.iovs.size(), "IOV"), iovsBefore);
  bool withTruth = false;
  for (const auto& s : r.segments) {
    for (const auto& p : s.precision) withTruth = withTruth || std::isfinite(p.truth);
  }
  md += withTruth
            ? "; and, against the simulation's truth, the RMS of (IOV − truth) before and |refit − truth| after.\n"
            : ".\n";
  for (const RefittedSegment& s : r.segments) {
    if (s.transition) {
      md += fmt::format(
          "\n### Runs {}-{}: kept, straddling a step (to be calibrated again, split where the detector "
          "changed)\n",
          s.firstRun, s.lastRun);
      continue;
    }
    if (s.kept) {
      md += fmt::format("\n### Runs {}-{}: {} kept ({})\n", s.firstRun, s.lastRun, counted(s.end - s.begin, "IOV"),
                        keptBecause(s));
      continue;
    }
    md += fmt::format("\n### Runs {}-{}: {} → 1; {} (median {} per IOV before)\n\n", s.firstRun, s.lastRun,
                      counted(s.end - s.begin, "IOV"), counted(s.selected, "selected event"), s.medianSelectedBefore);
    md += withTruth ? "| parameter | refit | truth | quoted error before → after | statistical error before → after | "
                      "gain | observed scatter before | scatter / statistical error | RMS(IOV − truth) → refit − truth "
                      "|\n|---|---|---|---|---|---|---|---|---|\n"
                    : "| parameter | refit | quoted error before → after | statistical error before → after | gain | "
                      "observed scatter before | scatter / statistical error |\n|---|---|---|---|---|---|---|\n";
    for (const RefitPrecision& p : s.precision) {
      const int d = digitsOf(p.parameter);
      const std::string u = p.parameter.dimension() == Dimension::Angle ? "°" : " cm";
      std::string row = fmt::format("| {} | {}{} |", p.parameter, number(p.value, d), u);
      if (withTruth) row += fmt::format(" {} |", number(p.truth, d));
      row += fmt::format(" {} → {} | {} → {} | {} | {} | {} |", number(p.quotedBefore, d), number(p.quotedAfter, d),
                         number(p.statBefore, d), number(p.statAfter, d), ratio(p.statBefore, p.statAfter),
                         number(p.scatter, d), number(p.scatterOverError, 2));
      if (withTruth) {
        row +=
            fmt::format(" {} → {} |", number(p.truthRmsBefore, d), number(p.parameter.difference(p.value, p.truth), d));
      }
      md += row + "\n";
    }
  }
  return md;
}

}  // namespace emcalign::validation
