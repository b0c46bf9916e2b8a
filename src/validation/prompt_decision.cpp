#include "emcalign/validation/prompt_decision.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "emcalign/core/sha256.hpp"
#include "emcalign/core/types.hpp"
#include "emcalign/io/strict_json.hpp"

namespace emcalign::validation {

namespace {

using io::Json;
constexpr const char* kKeys[] = {"min_change", "significance", "max_change", "max_error"};

std::string unitOf(Param p) { return std::string(fileUnitName(dimension(p))); }

// q with P(|z| > q) = tail for a standard normal z (bisection of erfc).
double twoSidedQuantile(double tail) {
  double lo = 0.0, hi = 40.0;
  for (int k = 0; k < 200; ++k) {
    const double mid = 0.5 * (lo + hi);
    (std::erfc(mid / std::sqrt(2.0)) > tail ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Three significant digits: a file a person reads and edits.
double rounded(double x) { return std::stod(fmt::format("{:.3g}", x)); }

}  // namespace

Result<Thresholds> parseThresholds(const Json& j, const std::string& source) {
  if (Status s = io::expectFormat(j, kThresholdsFormat, "a thresholds file (emcalign-thresholds/1)", source); !s) {
    return s.error();
  }
  return io::strict::guarded([&]() -> Thresholds {
    const io::strict::StrictObject o(j, "", source);
    o.allowOnly({"format", "parameters"});
    if (o.string("format") != kThresholdsFormat) o.fail("format", fmt::format("expected \"{}\"", kThresholdsFormat));
    const auto listed = o.object("parameters");
    for (const auto& [key, value] : o.at("parameters").items()) {
      if (!paramFromName(key)) {
        listed.fail(listed.pathOf(key), "not one of the 12 parameters of a calibration (alpha, beta1, …, beta_rel)");
      }
    }
    Thresholds t;
    Json canonical = Json::object();
    for (Param p : kAllParams) {
      if (!listed.has(name(p))) continue;
      const auto limits = listed.object(name(p));
      limits.allowOnly({"min_change", "significance", "max_change", "max_error"});
      double v[4];
      for (int k = 0; k < 4; ++k) {
        v[k] = limits.number(kKeys[k]);
        if (!(std::isfinite(v[k]) && v[k] > 0.0)) limits.fail(limits.pathOf(kKeys[k]), "expected a number > 0");
      }
      if (!(v[0] < v[2])) {
        limits.fail(
            limits.pathOf("max_change"),
            fmt::format("expected more than min_change ({:g} {}): a change both updated and vetoed", v[0], unitOf(p)));
      }
      t.parameters.push_back({p, v[0], v[1], v[2], v[3]});
      canonical[std::string(name(p))] = {
          {"min_change", v[0]}, {"significance", v[1]}, {"max_change", v[2]}, {"max_error", v[3]}};
    }
    if (t.parameters.empty()) o.fail("parameters", "lists no parameter: nothing would ever be updated or vetoed");
    t.json = {{"format", kThresholdsFormat}, {"parameters", canonical}};
    t.sha256 = sha256(t.json.dump());
    return t;
  });
}

Result<Thresholds> readThresholds(const std::string& path) {
  auto text = io::readTextFile(path);
  if (!text) return text.error();
  auto j = io::parseJson(*text, path);
  if (!j) return j.error();
  return parseThresholds(*j, path);
}

Result<Thresholds> proposeThresholds(const std::vector<MeasuredSpread>& measured, double falseRate) {
  if (measured.empty()) return Error{"no parameter to propose thresholds for"};
  if (!(falseRate > 0.0 && falseRate < 0.5)) return Error{"the false update rate must lie in (0, 0.5)"};
  const double q = twoSidedQuantile(falseRate / static_cast<double>(measured.size()));
  Json parameters = Json::object();
  for (const MeasuredSpread& m : measured) {
    if (!(std::isfinite(m.spread) && m.spread > 0.0 && std::isfinite(m.quotedError) && m.quotedError > 0.0)) {
      return Error{fmt::format("{}: the validation's spread {} or error {} is not a positive number", name(m.parameter),
                               m.spread, m.quotedError)};
    }
    const double minChange = q * std::sqrt(2.0) * m.spread;
    parameters[std::string(name(m.parameter))] = {{"min_change", rounded(minChange)},
                                                  {"significance", 3.0},
                                                  {"max_change", rounded(10.0 * minChange)},
                                                  {"max_error", rounded(2.0 * m.quotedError)}};
  }
  return parseThresholds(Json{{"format", kThresholdsFormat}, {"parameters", parameters}}, "the proposal");
}

double falseUpdateQuantile(double falseRate, std::size_t parameters) {
  return twoSidedQuantile(falseRate / static_cast<double>(std::max<std::size_t>(parameters, 1)));
}

std::string_view name(Decision d) {
  switch (d) {
    case Decision::Update:
      return "update";
    case Decision::NoUpdate:
      return "no-update";
    case Decision::Veto:
      return "veto";
  }
  return "?";
}

DecisionResult decide(const Thresholds& thresholds, const GroupOutcome& g) {
  DecisionResult out;
  const bool fitted = g.status && usable(*g.status);
  std::vector<std::string> vetoes, updates;
  if (!g.status) {
    vetoes.push_back(fmt::format("no fit: {}", g.fitProblem.empty() ? "no selected event" : g.fitProblem));
  } else if (!usable(*g.status)) {
    vetoes.push_back(fmt::format("the fit is unusable: {}", name(*g.status)));
  }
  if (2 * g.selected < g.minEvents) {
    vetoes.push_back(
        fmt::format("too few events: {} selected, below half of --min-events {}", g.selected, g.minEvents));
  }
  if (g.status && *g.status == FitStatus::PoorFit) {
    out.reasons.push_back(
        fmt::format("a poor fit (p-value {:.2g}): usable, the model describes the profiles badly", g.pValue));
  }
  for (const ParameterThreshold& t : thresholds.parameters) {
    const conddb::StoredValue& f = g.fitted[index(t.parameter)];
    ParameterDecision d{t.parameter, kNaN, kNaN, kNaN, kNaN, kNaN};
    const std::string unit = unitOf(t.parameter);
    const std::string_view p = name(t.parameter);
    if (fitted) {
      d.fitted = f.value;
      d.error = f.error;
      if (!(std::isfinite(f.value) && std::isfinite(f.error) && f.error > 0.0)) {
        vetoes.push_back(fmt::format("{}: the fit gives no value with an error", p));
      } else if (f.error > t.maxError) {
        vetoes.push_back(fmt::format("{}: error {:.4g} {} > max_error {:g}", p, f.error, unit, t.maxError));
      }
    }
    if (g.inForce) d.inForce = (*g.inForce)[index(t.parameter)].value;
    if (fitted && g.inForce) {
      d.change = d.fitted - d.inForce;
      d.significance = std::abs(d.change) / d.error;
      if (!std::isfinite(d.inForce)) {
        vetoes.push_back(fmt::format("{}: the calibration in force has no value", p));
      } else if (std::abs(d.change) > t.maxChange) {
        vetoes.push_back(fmt::format("{}: change {:+.4g} {} beyond max_change {:g}", p, d.change, unit, t.maxChange));
      } else if (std::abs(d.change) > t.minChange && d.significance > t.significance) {
        updates.push_back(fmt::format("{}: change {:+.4g} ± {:.4g} {} ({:.1f} σ) beyond min_change {:g} and {:g} σ", p,
                                      d.change, d.error, unit, d.significance, t.minChange, t.significance));
      }
    }
    out.parameters.push_back(d);
  }
  if (!vetoes.empty()) {
    out.decision = Decision::Veto;
    out.reasons.insert(out.reasons.begin(), vetoes.begin(), vetoes.end());
  } else if (!g.inForce) {
    out.decision = Decision::Update;
    out.reasons.insert(out.reasons.begin(), "the first calibration of the tag");
  } else if (!updates.empty()) {
    out.decision = Decision::Update;
    out.reasons.insert(out.reasons.begin(), updates.begin(), updates.end());
  } else {
    out.decision = Decision::NoUpdate;
    out.reasons.insert(out.reasons.begin(), "no parameter moved beyond both its min_change and its significance");
  }
  return out;
}

}  // namespace emcalign::validation
