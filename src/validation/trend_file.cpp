#include <cmath>

#include <fmt/format.h>

#include "emcalign/io/strict_json.hpp"
#include "emcalign/validation/trend.hpp"

// trend.json: the one writer (trendJson) and the one reader (parseTrend) of the file.

namespace emcalign::validation {

using io::Json;

namespace {

Json tellApartJson(const TellApart& a) {
  return {{"min_events", a.minEvents ? Json(*a.minEvents) : Json()},
          {"expected_chi2", a.expectedChi2},
          {"expected_chi2_now", a.expectedNow},
          {"events_in_runs", a.eventsInRuns},
          {"events_factor", io::numberOrNull(a.eventsFactor)}};
}

Json stepJson(const TrendStep& s) {
  return {{"parameter", s.parameter},
          {"known_boundary", s.known},
          {"first_run_after", s.firstRunAfter},
          {"size", s.size},
          {"error", s.error},
          {"z", s.z()},
          {"unit", s.parameter.unit()},
          {"within_iov", s.withinIov ? Json::array({s.withinIov->first, s.withinIov->second}) : Json()},
          {"instead_of_drift",
           s.insteadOfDrift ? Json{{"chi2_step", s.insteadOfDrift->first}, {"chi2_drift", s.insteadOfDrift->second}}
                            : Json()},
          {"or_drift", s.orDrift ? Json{{"first_run", s.orDrift->firstRun},
                                        {"last_run", s.orDrift->lastRun},
                                        {"start_run", s.orDrift->startRun},
                                        {"end_run", s.orDrift->endRun},
                                        {"change", s.orDrift->change},
                                        {"change_error", s.orDrift->changeError},
                                        {"chi2_drift", s.orDrift->chi2Drift},
                                        {"chi2_step", s.orDrift->chi2Step},
                                        {"tell_apart", tellApartJson(s.orDrift->tellApart)},
                                        {"text", driftAlternativeText(s)}}
                                 : Json()}};
}

Json driftJson(const Trend& t, const TrendDrift& d) {
  return {{"parameter", d.parameter},
          {"first_run", d.firstRun},
          {"last_run", d.lastRun},
          {"start_run", d.startRun ? Json(*d.startRun) : Json()},
          {"end_run", d.endRun ? Json(*d.endRun) : Json()},
          {"start_range", Json::array({d.startRange.first, d.startRange.second})},
          {"end_range", Json::array({d.endRange.first, d.endRange.second})},
          {"change", d.change},
          {"change_error", d.changeError},
          {"slope_per_run", d.slopePerRun},
          {"error", d.error},
          {"z", d.z},
          {"p_value", d.pValue},
          {"unit", std::string(d.parameter.unit()) + "/run"},
          {"step_untried_before", d.stepUntriedBefore ? Json(*d.stepUntriedBefore) : Json()},
          {"step_untried_from", d.stepUntriedFrom ? Json(*d.stepUntriedFrom) : Json()},
          {"or_step", d.orStep ? Json{{"first_run_after", d.orStep->firstRunAfter},
                                      {"within_iov", d.orStep->withinIov ? Json::array({d.orStep->withinIov->first,
                                                                                        d.orStep->withinIov->second})
                                                                         : Json()},
                                      {"size", d.orStep->size},
                                      {"error", d.orStep->error},
                                      {"chi2_step", d.orStep->chi2Step},
                                      {"chi2_drift", d.orStep->chi2Line},
                                      {"text", stepAlternativeText(t, d)},
                                      {"tell_apart", d.tellApart ? tellApartJson(*d.tellApart) : Json()}}
                               : Json()}};
}

Json arrayOfScatter(const std::vector<PeriodScatter>& list) {
  Json out = Json::array();
  for (const auto& sc : list) {
    out.push_back({{"parameter", sc.parameter},
                   {"chi2", sc.chi2},
                   {"ndf", sc.ndf},
                   {"p_value", sc.pValue},
                   {"scatter_over_error", sc.ratio()},
                   {"errors", sc.statistical ? "statistical" : "quoted, scaled to their scatter"}});
  }
  return out;
}

Json segmentJson(const TrendSegment& s) {
  return {{"first_run", s.firstRun},
          {"last_run", s.lastRun},
          {"iovs", s.end - s.begin},
          {"transition", s.transition},
          {"after_known_boundary", s.afterKnownBoundary},
          {"steps_at_start", s.stepsAtStart},
          {"drifting", s.drifting},
          {"inconsistent", s.inconsistent},
          {"undecided", s.undecided},
          {"scattering", arrayOfScatter(s.scattering)},
          {"departing", s.departing},
          {"stable", s.stable()}};
}

Json edgeJson(const TrendEdge& e) {
  return {{"parameter", e.parameter},
          {"unit", e.parameter.unit()},
          {"first_run", e.firstRun},
          {"last_run", e.lastRun},
          {"at", e.atEnd ? "end" : "start"},
          {"departure", e.departure},
          {"error", e.error},
          {"z", e.z()}};
}

Json inconsistencyJson(const TrendInconsistency& i) {
  return {{"parameter", i.parameter}, {"unit", i.parameter.unit()},
          {"first_run", i.firstRun},  {"last_run", i.lastRun},
          {"iovs", i.iovs},           {"model", i.line ? "drift" : "constant"},
          {"chi2", i.chi2},           {"ndf", i.ndf},
          {"p_value", i.pValue},      {"too_few_iovs", i.unsplittable}};
}

Json boundaryJson(const KnownBoundary& b) {
  return {{"run", b.run},
          {"within_iov", b.withinIov ? Json::array({b.withinIov->first, b.withinIov->second}) : Json()},
          {"measurable", b.measurable},
          {"changed", b.changed},
          {"largest_change", b.largest ? Json(*b.largest) : Json()},
          {"largest_z", b.largestZ}};
}

// A series' analysis `a` of the points `s`: its segments, stretches and the IOVs left out as
// transitions.
Json seriesJson(const SeriesAnalysis& a, const TrendSeries& s) {
  const auto& pts = s.points;
  Json segs = Json::array();
  for (const auto& g : a.segments) {
    segs.push_back({{"first_run", pts[g.begin].firstRun},
                    {"last_run", pts[g.end - 1].lastRun},
                    {"iovs", g.end - g.begin},
                    {"mean", g.constant.a},
                    {"mean_error", std::sqrt(g.constant.varA)},
                    {"chi2", g.constant.chi2},
                    {"slope_per_run", g.line.b},
                    {"slope_error", std::sqrt(g.line.varB)},
                    {"slope_z", g.slopeZ}});
  }
  Json stretches = Json::array();
  for (const auto& m : a.stretches) {
    const RampFit& r = m.model;
    stretches.push_back({{"first_run", pts[m.points.front()].firstRun},
                         {"last_run", pts[m.points.back()].lastRun},
                         {"iovs", m.points.size()},
                         {"model", r.flat ? "flat" : "drift"},
                         {"level", r.level},
                         {"slope_per_run", r.slope},
                         {"start", r.flat || r.openStart ? Json() : Json(r.start)},
                         {"end", r.flat || r.openEnd ? Json() : Json(r.end)},
                         {"chi2", r.chi2},
                         {"ndf", m.ndf()}});
  }
  Json transitions = Json::array();
  for (const Change& c : a.changes) {
    if (c.transition) {
      const auto& p = s.points[c.start - 1];
      transitions.push_back(Json::array({p.firstRun, p.lastRun}));
    }
  }
  return {{"parameter", a.parameter},    {"unit", a.parameter.unit()},
          {"iovs", s.points.size()},     {"errors", s.statistical ? "statistical" : "quoted"},
          {"error_scale", a.errorScale}, {"segments", segs},
          {"stretches", stretches},      {"transition_iovs", transitions}};
}

// How the trend was analysed: the rules in words and their settings.
Json methodJson(const Trend& t) {
  return {
      {"changes", "optimal partitioning, Gaussian known-variance cost, a straight line per segment"},
      {"penalty", t.penalty},
      {"penalty_rule", "(k + 2) ln n, k = 2 (MBIC with a slope)"},
      {"errors", "the fits' statistical errors where every IOV records one, else the quoted ones"},
      {"error_scale_rule", "IOV-to-IOV scatter / error (median |dy|/0.6745), x(1 + 2.3/sqrt(m)), up or down"},
      {"step_test", "jump between the segments' models >= 3 sigma, and no continuous broken line within chi2 9"},
      {"transition_penalty", t.transitionPenalty},
      {"transition_rule", "ln n more for an IOV left out between two segments (straddling a step)"},
      {"step_z", t.options.stepZ},
      {"min_segment", t.options.minSegment},
      {"min_line_points", kMinLinePoints},
      {"knee_test", t.options.kneeTest},
      {"drift_test",
       "each stretch between steps flat, or one slope between two knees (a knee at the stretch's edge: the drift "
       "runs into it); the drift chosen when its chi2 + slope_penalty + knee_penalty per knee inside is lower"},
      {"drift_alpha", t.options.driftAlpha},
      {"drift_tests", t.tests},
      {"slope_penalty", t.slopePenalty},
      {"knee_penalty", t.kneePenalty},
      {"drift_or_step", "the best single step within chi2 9 of the drift: cannot tell"},
      {"consistency_test",
       "chi2 of each stretch's model (flat, or its drift), Bonferroni over all stretches tested, family-wise rate "
       "drift_alpha"},
      {"consistency_tests", t.consistencyTests},
      {"stability_test",
       "chi2 of each period's IOVs about their mean with their statistical errors (quoted ones scaled to their "
       "scatter where none are recorded), Bonferroni over periods x series, family-wise rate drift_alpha"},
      {"stability_tests", t.scatterTests},
      {"edge_test",
       "the first and the last IOV against the rest of their segment: left out when the chi2 drops by more than the "
       "penalty and p-value x 2 x series < drift_alpha"},
      {"known_boundaries", t.options.boundaries}};
}

// Each element of `items` as `json` makes it.
template <class Items, class ToJson>
Json arrayOf(const Items& items, ToJson json) {
  Json out = Json::array();
  for (const auto& item : items) out.push_back(json(item));
  return out;
}

}  // namespace

Json trendJson(const Trend& t, const std::vector<TrendSeries>& series, const PeriodTruth* truth) {
  Json list = Json::array();
  for (std::size_t k = 0; k < t.series.size(); ++k) list.push_back(seriesJson(t.series[k], series[k]));
  Json setAside = Json::array();
  for (const auto& a : t.setAside) {
    setAside.push_back({{"parameter", a.parameter}, {"first_run", a.firstRun}, {"last_run", a.lastRun}});
  }
  return {{"format", kTrendFormat},
          {"method", methodJson(t)},
          {"iovs", t.iovs},
          {"resolvable", t.resolvable()},
          {"verdict", trendVerdict(t)},
          {"steps", arrayOf(t.steps,
                            [&](const TrendStep& s) {
                              Json j = stepJson(s);
                              if (truth) j["true_size"] = io::numberOrNull(trueStepSize(s, series, *truth));
                              return j;
                            })},
          {"inconsistent", arrayOf(t.inconsistencies, inconsistencyJson)},
          {"known_boundaries", arrayOf(t.boundaries, boundaryJson)},
          {"set_aside", setAside},
          {"edges", arrayOf(t.edges, edgeJson)},
          {"drifts", arrayOf(t.drifts,
                             [&](const TrendDrift& d) {
                               Json j = driftJson(t, d);
                               if (truth) j["true_change"] = io::numberOrNull(trueDriftChange(d, *truth));
                               return j;
                             })},
          {"truth", truth != nullptr},
          {"segments", arrayOf(t.segments, segmentJson)},
          {"series", list}};
}

Json trendJson(const Trend& t, const std::vector<TrendSeries>& series, const TrendOrigin& origin,
               const PeriodTruth* truth) {
  Json out = trendJson(t, series, truth);
  out["conditions"] = origin.conditions;
  out["tag"] = origin.tag;
  Json models = Json::array();
  for (const auto& m : origin.models) models.push_back(m.text());
  out["models"] = models;
  if (origin.refit) out["refit"] = *origin.refit;
  return out;
}

// ---------------------------------------------------------------- reading trend.json back

namespace {

using io::strict::StrictObject;

Quantity quantityAt(const StrictObject& o, std::string_view key) {
  const std::string n = o.string(key);
  const auto q = quantityFromName(n);
  if (!q) o.fail(o.pathOf(key), fmt::format("unknown parameter '{}'", n));
  return *q;
}

std::vector<Quantity> quantitiesAt(const StrictObject& o, std::string_view key) {
  std::vector<Quantity> out;
  if (!o.has(key)) return out;
  const std::vector<std::string> names = o.strings(key);
  for (std::size_t k = 0; k < names.size(); ++k) {
    const auto q = quantityFromName(names[k]);
    if (!q) o.fail(fmt::format("{}[{}]", o.pathOf(key), k), fmt::format("unknown parameter '{}'", names[k]));
    out.push_back(*q);
  }
  return out;
}

// An IOV's runs [first, last], or none (null or absent).
std::optional<std::pair<std::int64_t, std::int64_t>> iovAt(const StrictObject& o, std::string_view key) {
  if (!o.has(key) || o.at(key).is_null()) return std::nullopt;
  const Json& runs = o.array(key);
  if (runs.size() != 2 || !runs[0].is_number_integer() || !runs[1].is_number_integer()) {
    o.fail(o.pathOf(key), "expected [first run, last run]");
  }
  return std::pair{runs[0].get<std::int64_t>(), runs[1].get<std::int64_t>()};
}

// Each element of the array at `key` (none when absent) as `read` makes it.
template <class Read>
auto listAt(const StrictObject& top, std::string_view key, Read read) {
  std::vector<decltype(read(top))> out;
  if (!top.has(key)) return out;
  const Json& list = top.array(key);
  for (std::size_t k = 0; k < list.size(); ++k) {
    out.push_back(read(top.nested(list[k], fmt::format("{}[{}]", top.pathOf(key), k))));
  }
  return out;
}

RecordedStep readStep(const StrictObject& s) {
  TrendStep step{.parameter = quantityAt(s, "parameter"),
                 .known = s.has("known_boundary") && s.boolean("known_boundary"),
                 .firstRunAfter = s.integer("first_run_after"),
                 .size = s.numberOrNull("size"),
                 .error = s.numberOrNull("error"),
                 .withinIov = iovAt(s, "within_iov")};
  RecordedStep out{.step = step};
  if (s.has("true_size")) out.trueSize = s.numberOrNull("true_size");
  if (s.has("or_drift") && !s.at("or_drift").is_null()) {
    const StrictObject d = s.object("or_drift");
    if (d.has("text")) out.orDriftText = d.string("text");
    step.orDrift = DriftAlternative{.firstRun = d.integer("first_run"),
                                    .lastRun = d.integer("last_run"),
                                    .startRun = d.integer("start_run"),
                                    .endRun = d.integer("end_run"),
                                    .change = d.numberOrNull("change"),
                                    .changeError = d.numberOrNull("change_error"),
                                    .chi2Drift = d.numberOrNull("chi2_drift"),
                                    .chi2Step = d.numberOrNull("chi2_step")};
  }
  if (s.has("instead_of_drift") && !s.at("instead_of_drift").is_null()) {
    const StrictObject d = s.object("instead_of_drift");
    step.insteadOfDrift = std::pair{d.number("chi2_step"), d.number("chi2_drift")};
  }
  out.step = std::move(step);
  return out;
}

TrendInconsistency readInconsistency(const StrictObject& i) {
  const std::string model = i.string("model");
  // (an older trend.json calls a drift's model a line)
  if (model != "drift" && model != "line" && model != "constant") {
    i.fail(i.pathOf("model"), "expected \"drift\" or \"constant\"");
  }
  return {.parameter = quantityAt(i, "parameter"),
          .firstRun = i.integer("first_run"),
          .lastRun = i.integer("last_run"),
          .iovs = static_cast<std::size_t>(i.integer("iovs")),
          .chi2 = i.numberOrNull("chi2"),
          .ndf = static_cast<int>(i.integer("ndf")),
          .pValue = i.numberOrNull("p_value"),
          .line = model != "constant",
          .unsplittable = i.has("too_few_iovs") && i.boolean("too_few_iovs")};
}

RecordedDrift readDrift(const StrictObject& d) {
  RecordedDrift out{.drift = {.parameter = quantityAt(d, "parameter"),
                              .firstRun = d.integer("first_run"),
                              .lastRun = d.integer("last_run"),
                              .slopePerRun = d.numberOrNull("slope_per_run"),
                              .error = d.numberOrNull("error"),
                              .z = d.numberOrNull("z"),
                              .pValue = d.numberOrNullIfGiven("p_value")}};
  if (d.has("start_run") && !d.at("start_run").is_null()) out.drift.startRun = d.integer("start_run");
  if (d.has("end_run") && !d.at("end_run").is_null()) out.drift.endRun = d.integer("end_run");
  if (auto r = iovAt(d, "start_range")) out.drift.startRange = *r;
  if (auto r = iovAt(d, "end_range")) out.drift.endRange = *r;
  if (d.has("step_untried_before") && !d.at("step_untried_before").is_null()) {
    out.drift.stepUntriedBefore = d.integer("step_untried_before");
  }
  if (d.has("step_untried_from") && !d.at("step_untried_from").is_null()) {
    out.drift.stepUntriedFrom = d.integer("step_untried_from");
  }
  if (d.has("change")) out.drift.change = d.numberOrNull("change");
  if (d.has("change_error")) out.drift.changeError = d.numberOrNull("change_error");
  if (d.has("or_step") && !d.at("or_step").is_null()) {
    const StrictObject s = d.object("or_step");
    out.drift.orStep = StepAlternative{.firstRunAfter = s.integer("first_run_after"),
                                       .withinIov = iovAt(s, "within_iov"),
                                       .size = s.numberOrNull("size"),
                                       .error = s.numberOrNull("error"),
                                       .chi2Step = s.number("chi2_step"),
                                       .chi2Line = s.number("chi2_drift")};
    out.orStepText = s.string("text");
  }
  if (d.has("true_change")) out.trueChange = d.numberOrNull("true_change");
  return out;
}

RecordedRefitPeriod readRefitPeriod(const StrictObject& s) {
  RecordedRefitPeriod p{.firstRun = s.integer("first_run"),
                        .lastRun = s.integer("last_run"),
                        .replacesIovs = s.integer("replaces_iovs"),
                        .kept = s.has("kept") && s.boolean("kept")};
  if (s.has("why")) p.keptBecause = s.string("why");
  if (s.has("selected_events")) p.selectedEvents = s.integer("selected_events");
  if (s.has("precision")) {
    const StrictObject precision = s.object("precision");
    for (const auto& [key, entry] : s.at("precision").items()) {
      const auto q = quantityFromName(key);
      if (!q) precision.fail(precision.pathOf(key), fmt::format("unknown parameter '{}'", key));
      const StrictObject e = precision.object(key);
      const auto given = [&](std::string_view k) { return e.has(k) ? e.numberOrNull(k) : std::nan(""); };
      p.precision.push_back({.parameter = *q,
                             .value = given("value"),
                             .truth = given("truth"),
                             .statisticalBefore = given("statistical_error_before"),
                             .statisticalAfter = given("statistical_error_after"),
                             .scatterOverError = given("scatter_over_error_before"),
                             .rmsBeforeMinusTruth = given("rms_before_minus_truth")});
    }
  }
  return p;
}

RecordedRefit readRefit(const StrictObject& r) {
  RecordedRefit out{.tagOut = r.has("tag_out") ? r.string("tag_out") : std::string(),
                    .iovs = r.integer("iovs"),
                    .iovsBefore = r.integer("iovs_before")};
  out.periods = listAt(r, "segments", readRefitPeriod);
  return out;
}

PeriodScatter readScatter(const StrictObject& s) {
  return {.parameter = quantityAt(s, "parameter"),
          .chi2 = s.numberOrNull("chi2"),
          .ndf = static_cast<int>(s.integer("ndf")),
          .pValue = s.numberOrNull("p_value"),
          .statistical = !s.has("errors") || s.string("errors") == "statistical"};
}

TrendSegment readSegment(const StrictObject& s, bool resolvable) {
  return {.begin = 0,
          .end = static_cast<std::size_t>(s.integer("iovs")),
          .firstRun = s.integer("first_run"),
          .lastRun = s.integer("last_run"),
          .transition = s.has("transition") && s.boolean("transition"),
          .afterKnownBoundary = s.has("after_known_boundary") && s.boolean("after_known_boundary"),
          .stepsAtStart = quantitiesAt(s, "steps_at_start"),
          .drifting = quantitiesAt(s, "drifting"),
          .inconsistent = quantitiesAt(s, "inconsistent"),
          .undecided = quantitiesAt(s, "undecided"),
          .scattering = listAt(s, "scattering", readScatter),
          .departing = quantitiesAt(s, "departing"),
          .resolvable = resolvable};
}

}  // namespace

Result<TrendRecord> parseTrend(const Json& j, std::string_view source) {
  return io::strict::guarded([&] {
    const StrictObject top(j, "", source);
    if (top.string("format") != kTrendFormat) top.fail("format", fmt::format("expected \"{}\"", kTrendFormat));
    TrendRecord r;
    if (top.has("tag")) r.tag = top.string("tag");
    if (top.has("conditions")) r.conditions = top.string("conditions");
    if (top.has("models")) r.models = top.strings("models");
    r.iovs = static_cast<std::size_t>(top.integer("iovs"));
    if (top.has("verdict")) r.verdict = top.string("verdict");
    if (top.has("method") && top.object("method").has("drift_tests")) {
      r.driftTests = static_cast<int>(top.object("method").integer("drift_tests"));
    }
    const bool resolvable = !top.has("resolvable") || top.boolean("resolvable");
    r.steps = listAt(top, "steps", readStep);
    r.inconsistencies = listAt(top, "inconsistent", readInconsistency);
    r.drifts = listAt(top, "drifts", readDrift);
    r.segments = listAt(top, "segments", [&](const StrictObject& s) { return readSegment(s, resolvable); });
    r.withTruth = top.has("truth") && top.boolean("truth");
    if (top.has("refit")) r.refit = readRefit(top.object("refit"));
    return r;
  });
}

}  // namespace emcalign::validation
