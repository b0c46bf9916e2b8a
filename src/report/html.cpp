#include "emcalign/report/html.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "emcalign/io/json_files.hpp"

namespace emcalign::report::html {

std::string escape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string base64(std::string_view bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) | (static_cast<unsigned char>(bytes[i + 1]) << 8) |
                       static_cast<unsigned char>(bytes[i + 2]);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += kAlphabet[(v >> 6) & 63];
    out += kAlphabet[v & 63];
  }
  if (i + 1 == bytes.size()) {
    const unsigned v = static_cast<unsigned char>(bytes[i]) << 16;
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += "==";
  } else if (i + 2 == bytes.size()) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) | (static_cast<unsigned char>(bytes[i + 1]) << 8);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += kAlphabet[(v >> 6) & 63];
    out += '=';
  }
  return out;
}

Result<std::string> pngDataUri(const std::string& path) {
  auto bytes = io::readTextFile(path);
  if (!bytes) return bytes.error();
  static constexpr std::string_view kSignature = "\x89PNG\r\n\x1a\n";
  if (bytes->size() < kSignature.size() || std::string_view(*bytes).substr(0, kSignature.size()) != kSignature) {
    return Error{fmt::format("{}: not a PNG image", path)};
  }
  return "data:image/png;base64," + base64(*bytes);
}

Result<std::string> figure(const std::string& pngPath, const std::string& caption) {
  auto uri = pngDataUri(pngPath);
  if (!uri) return uri.error();
  return fmt::format("<figure><img src=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>\n", *uri, escape(caption),
                     escape(caption));
}

std::string table(const Table& t) {
  std::string out = "<table>\n";
  if (!t.caption.empty()) out += fmt::format("<caption>{}</caption>\n", escape(t.caption));
  auto numeric = [&](std::size_t c) { return c < t.numeric.size() && t.numeric[c]; };
  out += "<thead><tr>";
  for (std::size_t c = 0; c < t.header.size(); ++c) {
    out += fmt::format("<th{}>{}</th>", numeric(c) ? " class=\"num\"" : "", t.header[c]);
  }
  out += "</tr></thead>\n<tbody>\n";
  for (std::size_t r = 0; r < t.rows.size(); ++r) {
    const std::string cls =
        r < t.rowClass.size() && !t.rowClass[r].empty() ? fmt::format(" class=\"{}\"", t.rowClass[r]) : "";
    out += fmt::format("<tr{}>", cls);
    for (std::size_t c = 0; c < t.rows[r].size(); ++c) {
      out += fmt::format("<td{}>{}</td>", numeric(c) ? " class=\"num\"" : "", t.rows[r][c]);
    }
    out += "</tr>\n";
  }
  return out + "</tbody>\n</table>\n";
}

std::string heatMap(const std::vector<std::string>& labels, const std::vector<std::vector<double>>& matrix,
                    const std::string& caption) {
  std::string out = "<table class=\"heat\">\n";
  if (!caption.empty()) out += fmt::format("<caption>{}</caption>\n", escape(caption));
  out += "<thead><tr><th></th>";
  for (const auto& l : labels) out += fmt::format("<th>{}</th>", escape(l));
  out += "</tr></thead>\n<tbody>\n";
  for (std::size_t i = 0; i < matrix.size(); ++i) {
    out += fmt::format("<tr><th>{}</th>", i < labels.size() ? escape(labels[i]) : std::string());
    for (double v : matrix[i]) {
      if (!std::isfinite(v)) {
        out += "<td>—</td>";
        continue;
      }
      // White at 0, red (+1) or blue (−1) at full strength.
      const double a = std::clamp(std::abs(v), 0.0, 1.0);
      const int fade = static_cast<int>(std::lround(255.0 * (1.0 - a)));
      const std::string colour =
          v >= 0.0 ? fmt::format("rgb(255,{},{})", fade, fade) : fmt::format("rgb({},{},255)", fade, fade);
      // Black text where the colour is pale, white on the strong ones; printed with the colours.
      const std::string value = std::abs(v) < 0.005 ? std::string("0.00") : fmt::format("{:+.2f}", v);
      out += fmt::format("<td style=\"background:{};color:{}\">{}</td>", colour, a > 0.6 ? "#fff" : "#000", value);
    }
    out += "</tr>\n";
  }
  return out + "</tbody>\n</table>\n";
}

std::string paragraph(std::string_view text) { return fmt::format("<p>{}</p>\n", escape(text)); }

std::string list(const std::vector<std::string>& items, std::string_view cssClass) {
  std::string out = cssClass.empty() ? "<ul>\n" : fmt::format("<ul class=\"{}\">\n", cssClass);
  for (const auto& i : items) out += fmt::format("<li>{}</li>\n", escape(i));
  return out + "</ul>\n";
}

namespace {

constexpr const char* kStyle = R"(
body { font-family: "DejaVu Sans", "Helvetica", "Arial", sans-serif; font-size: 14px; line-height: 1.45;
       color: #1a1a1a; max-width: 1180px; margin: 0 auto; padding: 1.5em 2em; }
h1 { font-size: 1.7em; margin-bottom: 0.1em; }
h2 { font-size: 1.3em; border-bottom: 2px solid #3a6ea5; padding-bottom: 0.15em; margin-top: 2em; }
h3 { font-size: 1.08em; margin-top: 1.4em; }
.subtitle { color: #555; margin-top: 0; }
nav ol { columns: 2; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.92em; }
caption { text-align: left; font-weight: bold; padding-bottom: 0.3em; white-space: nowrap; }
.side { display: flex; flex-wrap: wrap; gap: 0 2.5em; align-items: flex-start; }
th, td { border: 1px solid #c8c8c8; padding: 0.22em 0.55em; }
thead th { background: #eef2f7; }
td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; }
tr.sub td { color: #555; }
tr.warn td, ul.warn li { color: #8a3b00; }
ul.warn { background: #fff6e8; border-left: 4px solid #e09000; padding: 0.5em 1.5em; }
table.heat td { text-align: center; min-width: 3.2em; font-variant-numeric: tabular-nums;
                print-color-adjust: exact; -webkit-print-color-adjust: exact; }
table.heat th { font-weight: normal; background: #f4f4f4; }
figure { margin: 1em 0; page-break-inside: avoid; break-inside: avoid; }
figure img { max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { color: #444; font-size: 0.92em; margin-top: 0.3em; }
.good { color: #1d6b2a; font-weight: bold; }
.bad { color: #a01c1c; font-weight: bold; }
code { font-size: 0.95em; background: #f4f4f4; padding: 0 0.2em; }
footer { margin-top: 3em; color: #666; font-size: 0.85em; border-top: 1px solid #ccc; padding-top: 0.5em; }
@media print {
  body { max-width: none; padding: 0; font-size: 11px; }
  nav { display: none; }
  h2 { page-break-before: always; break-before: page; }
  section:first-of-type h2 { page-break-before: avoid; break-before: avoid; }
  table { page-break-inside: avoid; break-inside: avoid; }
  h3, caption { page-break-after: avoid; break-after: avoid; }
  figure img { max-height: 235mm; width: auto; }  /* a tall figure shrinks onto one page */
}
@page { size: A4; margin: 14mm; }
)";

}  // namespace

std::string page(const std::string& title, const std::string& subtitle, const std::vector<Section>& sections,
                 const std::string& footer) {
  std::string out = fmt::format(
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>{}</title>\n<style>{}</style>\n"
      "</head>\n<body>\n<header><h1>{}</h1>\n<p class=\"subtitle\">{}</p></header>\n",
      escape(title), kStyle, escape(title), escape(subtitle));
  if (sections.size() > 1) {
    out += "<nav><h2>Contents</h2>\n<ol>\n";
    for (const auto& s : sections)
      out += fmt::format("<li><a href=\"#{}\">{}</a></li>\n", escape(s.id), escape(s.title));
    out += "</ol>\n</nav>\n";
  }
  for (const auto& s : sections) {
    out += fmt::format("<section id=\"{}\">\n<h2>{}</h2>\n{}</section>\n", escape(s.id), escape(s.title), s.body);
  }
  if (!footer.empty()) out += fmt::format("<footer>{}</footer>\n", escape(footer));
  return out + "</body>\n</html>\n";
}

}  // namespace emcalign::report::html
