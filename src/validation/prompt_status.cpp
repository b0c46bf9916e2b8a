// STATE_DIR/status.html of the prompt loop (validation/prompt.hpp): one self-contained page —
// the parameters against run with their IOVs, each decision marked, the thresholds as bands
// around the calibration in force, the last decisions, the alerts and the quarantined files.
// The figures are inline SVG (drawn here: a page rewritten after every decision must not wait
// for a plotting program).

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "emcalign/report/html.hpp"
#include "prompt_internal.hpp"

namespace emcalign::validation::prompt {

namespace {

using io::Json;
namespace html = report::html;

struct Point {
  double first = 0, last = 0;  // the group's runs
  double iovFirst = 0, iovLast = 0;
  bool hasIov = false;
  double fitted = NAN, error = NAN, inForce = NAN, payloadValue = NAN;
  std::string decision;
};

const char* colourOf(const std::string& decision) {
  return decision == "update" ? "#1a7f37" : decision == "veto" ? "#cf222e" : "#6e7781";
}

// A panel's size and margins (px).
constexpr double kW = 760, kH = 220, kLeft = 70, kRight = 12, kTop = 22, kBottom = 30;

// A panel's ranges: the runs of its groups, and the values of their fits, errors, IOVs and the
// min_change bands (with a margin); X and Y place a run and a value.
struct Frame {
  double xMin = std::numeric_limits<double>::max(), xMax = std::numeric_limits<double>::lowest();
  double yMin = xMin, yMax = xMax;
  [[nodiscard]] double X(double run) const { return kLeft + (run - xMin) / (xMax - xMin) * (kW - kLeft - kRight); }
  [[nodiscard]] double Y(double v) const { return kTop + (yMax - v) / (yMax - yMin) * (kH - kTop - kBottom); }
};

Frame frameOf(const std::vector<Point>& points, double minChange) {
  Frame f;
  const auto grow = [&](double y) {
    if (std::isfinite(y)) {
      f.yMin = std::min(f.yMin, y);
      f.yMax = std::max(f.yMax, y);
    }
  };
  for (const Point& p : points) {
    f.xMin = std::min(f.xMin, p.hasIov ? p.iovFirst : p.first);
    f.xMax = std::max(f.xMax, p.last + 1);
    grow(p.fitted - p.error);
    grow(p.fitted + p.error);
    grow(p.payloadValue);
    grow(p.inForce - minChange);
    grow(p.inForce + minChange);
  }
  if (!(f.xMin < f.xMax)) f.xMax = f.xMin + 1;
  if (!(f.yMin < f.yMax)) {
    f.yMin = std::isfinite(f.yMin) ? f.yMin - 1 : -1;
    f.yMax = f.yMin + 2;
  }
  const double pad = 0.08 * (f.yMax - f.yMin);
  f.yMin -= pad;
  f.yMax += pad;
  return f;
}

// The panel's frame, title and axes' labels (the SVG element left open).
std::string axes(const std::string& name, const std::string& unit, const Frame& f) {
  std::string svg = fmt::format(
      R"(<svg xmlns="http://www.w3.org/2000/svg" width="{0}" height="{1}" viewBox="0 0 {0} {1}" role="img" )"
      R"(aria-label="{2} against run"><rect x="{3}" y="{4}" width="{5}" height="{6}" fill="#fff" stroke="#999"/>)"
      R"(<text x="{3}" y="14" font-size="12" font-family="sans-serif">{2} ({7})</text>)",
      kW, kH, html::escape(name), kLeft, kTop, kW - kLeft - kRight, kH - kTop - kBottom, html::escape(unit));
  for (int k = 0; k <= 4; ++k) {  // the value axis
    const double v = f.yMin + (f.yMax - f.yMin) * k / 4.0;
    svg += fmt::format(
        R"(<text x="{}" y="{:.1f}" font-size="10" text-anchor="end" font-family="sans-serif">{:.4g}</text>)", kLeft - 4,
        f.Y(v) + 3, v);
  }
  svg += fmt::format(R"(<text x="{}" y="{}" font-size="10" font-family="sans-serif">run {:.0f}</text>)", kLeft, kH - 8,
                     f.xMin);
  svg +=
      fmt::format(R"(<text x="{}" y="{}" font-size="10" text-anchor="end" font-family="sans-serif">run {:.0f}</text>)",
                  kW - kRight, kH - 8, f.xMax - 1);
  return svg;
}

// One group on the panel: the thresholds around what was in force, what its IOV serves, its fit
// (or a mark at the axis without one).
std::string groupMarks(const Point& p, const Frame& f, double minChange, double maxChange) {
  std::string svg;
  if (std::isfinite(p.inForce)) {  // the thresholds around what was in force
    const double x0 = f.X(p.hasIov ? p.iovFirst : p.first), x1 = f.X(p.last + 1);
    svg += fmt::format(R"(<rect x="{:.1f}" y="{:.1f}" width="{:.1f}" height="{:.1f}" fill="#d0d7de" opacity="0.6"/>)",
                       x0, f.Y(p.inForce + minChange), std::max(0.5, x1 - x0),
                       std::max(0.5, f.Y(p.inForce - minChange) - f.Y(p.inForce + minChange)));
    for (double edge : {p.inForce + maxChange, p.inForce - maxChange}) {
      if (edge > f.yMin && edge < f.yMax) {
        svg += fmt::format(
            R"(<line x1="{:.1f}" x2="{:.1f}" y1="{:.1f}" y2="{:.1f}" stroke="#cf222e" stroke-dasharray="3,2"/>)", x0,
            x1, f.Y(edge), f.Y(edge));
      }
    }
  }
  if (p.hasIov && std::isfinite(p.payloadValue)) {  // what the IOV serves
    svg += fmt::format(R"(<line x1="{:.1f}" x2="{:.1f}" y1="{:.1f}" y2="{:.1f}" stroke="#0969da" stroke-width="2"/>)",
                       f.X(p.iovFirst), f.X(p.iovLast + 1), f.Y(p.payloadValue), f.Y(p.payloadValue));
  }
  if (std::isfinite(p.fitted)) {  // the group's fit
    const double x = f.X(0.5 * (p.first + p.last + 1));
    const char* c = colourOf(p.decision);
    if (std::isfinite(p.error)) {
      svg += fmt::format(R"(<line x1="{0:.1f}" x2="{0:.1f}" y1="{1:.1f}" y2="{2:.1f}" stroke="{3}"/>)", x,
                         f.Y(p.fitted - p.error), f.Y(p.fitted + p.error), c);
    }
    svg +=
        fmt::format(R"(<circle cx="{:.1f}" cy="{:.1f}" r="3" fill="{}"><title>runs {:.0f}-{:.0f}: {}</title></circle>)",
                    x, f.Y(p.fitted), c, p.first, p.last, html::escape(p.decision));
  } else {  // no fit: a mark at the axis
    svg += fmt::format(R"(<text x="{:.1f}" y="{:.1f}" font-size="11" fill="{}" text-anchor="middle">×</text>)",
                       f.X(0.5 * (p.first + p.last + 1)), kH - kBottom - 2, colourOf(p.decision));
  }
  return svg;
}

// One parameter against run: a step line of the value each IOV serves, the fitted value of each
// group with its error, coloured by its decision, and the bands of min_change (grey) and
// max_change (red lines) around the calibration in force.
std::string panel(const std::string& name, const std::string& unit, const std::vector<Point>& points,
                  const Json& limits) {
  const double minChange = limits.value("min_change", 0.0), maxChange = limits.value("max_change", 0.0);
  const Frame f = frameOf(points, minChange);
  std::string svg = axes(name, unit, f);
  for (const Point& p : points) svg += groupMarks(p, f, minChange, maxChange);
  return svg + "</svg>";
}

std::string number(const Json& v, int digits = 4) {
  return v.is_number() ? fmt::format("{:.{}g}", v.get<double>(), digits) : std::string("–");
}

// The summary: the decisions counted, the open group, the thresholds.
html::Section summarySection(const StatusInput& in, const std::vector<Json>& decisions, const Json& listed) {
  int updates = 0, vetoes = 0, none = 0;
  for (const Json& d : decisions) {
    const std::string what = d.value("decision", std::string());
    (what == "update" ? updates : what == "veto" ? vetoes : none)++;
  }
  std::int64_t openSelected = 0;
  for (const TakenRun& r : in.state.open) openSelected += r.selected;
  std::string summary = html::paragraph(fmt::format(
      "Tag {} (running) in {}: {} groups decided — {} updates, {} no-updates, {} vetoes. Open group: {} runs, {} of "
      "{} selected events. Thresholds {}… (min_events {}).",
      in.tag, in.conditions, decisions.size(), updates, none, vetoes, in.state.open.size(), openSelected, in.minEvents,
      in.thresholds.value("sha256", std::string()).substr(0, 12), in.minEvents));
  html::Table limits{"The thresholds (emcalign-thresholds/1)",
                     {"parameter", "min_change", "significance", "max_change", "max_error"},
                     {},
                     {false, true, true, true, true}};
  for (const auto& [name, l] : listed.items()) {
    limits.rows.push_back({html::escape(name), number(l["min_change"]), number(l["significance"]),
                           number(l["max_change"]), number(l["max_error"])});
  }
  return {"summary", "Summary", summary + html::table(limits)};
}

// Parameter `name` of every decision, as its panel shows it.
std::vector<Point> pointsOf(const std::vector<Json>& decisions, const std::string& name) {
  std::vector<Point> points;
  for (const Json& d : decisions) {
    Point p;
    p.first = d["runs"][0].get<double>();
    p.last = d["runs"][1].get<double>();
    p.decision = d.value("decision", std::string());
    if (d.contains("iov") && d["iov"].is_array()) {
      p.hasIov = true;
      p.iovFirst = d["iov"][0].get<double>();
      p.iovLast = d["iov"][1].get<double>();
    }
    const Json& v = d["parameters"].contains(name) ? d["parameters"][name] : Json::object();
    const auto num = [&](const char* key) {
      return v.contains(key) && v[key].is_number() ? v[key].get<double>() : NAN;
    };
    p.fitted = num("fitted");
    p.error = num("error");
    p.inForce = num("in_force");
    p.payloadValue = p.decision == "update" ? p.fitted : p.inForce;
    points.push_back(p);
  }
  return points;
}

// Every parameter with thresholds against run.
html::Section parametersSection(const std::vector<Json>& decisions, const Json& listed) {
  std::string figures;
  for (const auto& [name, l] : listed.items()) {
    const bool angle = name == "alpha" || name == "beta1" || name == "beta2" || name == "beta_rel";
    figures += "<figure>" + panel(name, angle ? "deg" : "cm", pointsOf(decisions, name), l) + "</figure>";
  }
  return {"parameters", "Parameters against run",
          html::paragraph("Each group's fit with its error (green: update, grey: no-update, red: veto; × a group "
                          "without a fit); blue: the value each IOV serves; grey band: the calibration in force ± "
                          "min_change; red dashes: ± max_change.") +
              figures};
}

// The last 30 decisions, newest first.
html::Section decisionsSection(const std::vector<Json>& decisions) {
  html::Table last{"The last decisions (newest first)",
                   {"group", "runs", "beam energy (MeV)", "selected", "decision", "reasons"},
                   {},
                   {true, false, true, true, false, false}};
  for (auto it = decisions.rbegin(); it != decisions.rend() && last.rows.size() < 30; ++it) {
    const Json& d = *it;
    std::vector<std::string> reasons = d.value("reasons", std::vector<std::string>());
    std::string text;
    for (const auto& r : reasons) text += (text.empty() ? "" : "; ") + r;
    last.rows.push_back({fmt::format("{}", d.value("group", 0)),
                         fmt::format("{}-{}", d["runs"][0].get<std::int64_t>(), d["runs"][1].get<std::int64_t>()),
                         number(d["beam_energy_mev"], 6), fmt::format("{}", d.value("selected_events", 0)),
                         html::escape(d.value("decision", std::string())), html::escape(text)});
    last.rowClass.push_back(d.value("decision", std::string()) == "veto" ? "warn" : "");
  }
  return {"decisions", "Decisions", html::table(last)};
}

// The vetoes and the quarantined files.
html::Section alertsSection(const StatusInput& in, const std::vector<Json>& decisions) {
  std::vector<std::string> alerts;
  for (const Json& d : decisions) {
    if (d.value("decision", std::string()) == "veto") {
      alerts.push_back(fmt::format("veto of group {} (runs {}-{})", d.value("group", 0),
                                   d["runs"][0].get<std::int64_t>(), d["runs"][1].get<std::int64_t>()));
    }
  }
  html::Table quarantined{"Quarantined files (never taken again unless they change)", {"file", "reason"}, {}, {}};
  for (const auto& [name, f] : in.state.files) {
    if (f.status == "quarantined") {
      quarantined.rows.push_back({html::escape(name), html::escape(f.reason)});
      alerts.push_back("quarantined: " + name);
    }
  }
  return {"alerts", "Alerts",
          (alerts.empty() ? html::paragraph("None.") : html::list(alerts, "warn")) +
              (quarantined.rows.empty() ? std::string() : html::table(quarantined))};
}

}  // namespace

std::vector<report::html::Section> statusSections(const StatusInput& in) {
  std::vector<Json> decisions;
  for (const std::string& r : in.records) {
    Json j = Json::parse(r, nullptr, false);
    if (j.is_object()) decisions.push_back(std::move(j));
  }
  const Json& listed = in.thresholds.contains("json") ? in.thresholds["json"]["parameters"] : Json::object();
  return {summarySection(in, decisions, listed), parametersSection(decisions, listed), decisionsSection(decisions),
          alertsSection(in, decisions)};
}

std::string statusPage(const StatusInput& in) {
  return html::page(fmt::format("Prompt calibration: {}", in.tag), fmt::format("watching {}", in.state.watchDir),
                    statusSections(in), fmt::format("emcalign prompt, written {}", in.written));
}

}  // namespace emcalign::validation::prompt
